"""Celerity and plug length against mass flow rate, in the manner of the paper's figures."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from matplotlib.figure import Figure

from ..campaigns.fits import LinearFit
from ._figure import new_figure

MARKERS = ("o", "^", "D", "v", "s", "P", "X")
LINES = ("-", "--", "-.", ":")


def plot_vs_mass_flow(groups: Mapping[str, tuple[np.ndarray, np.ndarray]],
                      fits: Mapping[str, LinearFit | None], *, ylabel: str, title: str,
                      absolute: bool = False, hline: float | None = None,
                      hline_label: str = "") -> Figure:
    """Scatter of each group with its fitted line and 95% band.

    Parameters
    ----------
    groups : mapping
        ``name -> (mass_flow_g_s, y)``.
    fits : mapping
        ``name -> LinearFit`` (fitted on the signed values).
    absolute : bool
        Plot ``|y|`` (the paper plots the absolute celerity of climbing plugs).
    hline : float, optional
        A reference level (e.g. 10 D).
    """
    fig, ax = new_figure(figsize=(6.4, 4.6), constrained_layout=True)
    for i, (name, (x, y)) in enumerate(groups.items()):
        x = np.asarray(x, float)
        y = np.asarray(y, float)
        sign = np.sign(np.nanmean(y)) if absolute and np.any(np.isfinite(y)) else 1.0
        ax.plot(x, sign * y, MARKERS[i % len(MARKERS)], mfc="none", mec=f"C{i}", ms=7, label=name)
        fit = fits.get(name)
        if fit is not None:
            xx = np.linspace(fit.x_min, fit.x_max, 100)
            lo, hi = fit.band(xx)
            yy = fit.predict(xx)
            if sign < 0:
                lo, hi = -hi, -lo
            ax.plot(xx, sign * yy, LINES[i % len(LINES)], color=f"C{i}", lw=1.3,
                    label=f"fit: slope {sign * fit.slope:+.4g}, R² = {fit.r2:.3f}")
            ax.fill_between(xx, lo, hi, color=f"C{i}", alpha=0.15, lw=0)
    if hline is not None:
        ax.axhline(hline, color="0.4", ls=":", lw=1, label=hline_label)
    ax.set_xlabel("mass flow rate ṁ (g/s)")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=7)
    return fig
