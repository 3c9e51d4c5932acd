"""Celerity and plug length against mass flow rate, in the manner of the paper's figures."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure

from ._figure import new_figure, pt
from .palette import GROUPS

if TYPE_CHECKING:
    from ..campaigns.fits import LinearFit

MARKERS = ("o", "^", "D", "v", "s", "P", "X")
LINES = ("-", "--", "-.", ":")


def plot_vs_mass_flow(groups: Mapping[str, tuple[np.ndarray, np.ndarray]],
                      fits: Mapping[str, LinearFit | None], *, ylabel: str, title: str,
                      hline: float | None = None,
                      hline_label: str = "",
                      errors: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None) -> Figure:
    """Scatter of each group, each run's 95 % interval as an error bar, the fitted line and its 95 % band.

    Parameters
    ----------
    groups : mapping
        ``name -> (mass_flow_g_s, y)``.
    fits : mapping
        ``name -> LinearFit`` (fitted on the signed values).
    hline : float, optional
        A reference level (e.g. 10 D).
    errors : mapping, optional
        ``name -> (low, high)``: each run's 95 % interval (same order as ``groups``).
    """
    fig, ax = new_figure(figsize=(6.4, 4.6), constrained_layout=True)
    for i, (name, (x, y)) in enumerate(groups.items()):
        x = np.asarray(x, float)
        y = np.asarray(y, float)
        col = GROUPS[i % len(GROUPS)]
        ax.plot(x, y, MARKERS[i % len(MARKERS)], mfc="none", mec=col, ms=7, label=name)
        if errors and name in errors:
            lo_e, hi_e = (np.asarray(a, float) for a in errors[name])
            ok = np.isfinite(lo_e) & np.isfinite(hi_e) & np.isfinite(y)
            if ok.any():
                lo_b, hi_b = np.minimum(lo_e[ok], hi_e[ok]), np.maximum(lo_e[ok], hi_e[ok])
                ax.errorbar(x[ok], y[ok], yerr=[y[ok] - lo_b, hi_b - y[ok]], fmt="none",
                            ecolor=col, elinewidth=0.8, capsize=2)
        fit = fits.get(name)
        if fit is not None:
            xx = np.linspace(fit.x_min, fit.x_max, 100)
            lo, hi = fit.band(xx)
            yy = fit.predict(xx)
            if fit.n < 3:  # a line through two points: no R² or band to speak of
                ax.plot(xx, yy, LINES[i % len(LINES)], color=col, lw=1.3,
                        label=f"line through {fit.n} runs: slope {fit.slope:+.4g} (no band: too few runs)")
                continue
            ax.plot(xx, yy, LINES[i % len(LINES)], color=col, lw=1.3,
                    label=f"fit: slope {fit.slope:+.4g}, R² = {fit.r2:.3f}")
            ax.fill_between(xx, lo, hi, color=col, alpha=0.15, lw=0, label="95 % band of the fit")
    if hline is not None:
        ax.axhline(hline, color="0.4", ls=":", lw=1, label=hline_label)
    ax.set_xlabel("mass flow rate ṁ (g s⁻¹)")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=pt(10))
    ax.legend(fontsize=pt(7))
    return fig
