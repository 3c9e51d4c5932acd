"""The paper's Fig. 9: growth rates of the three roots against k*."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure

from ._figure import new_figure, pt

if TYPE_CHECKING:
    from ..stability import StabilityResult

STYLES = ("-", "-.", "--")


def plot_growth_rates(res: StabilityResult, *, zoom_k_max: float = 0.8) -> Figure:
    """(a) the three growth rates over the whole range, (b) over ``0 <= k* <= zoom_k_max``."""
    from ..stability import analyze_stability

    fig, axes = new_figure(2, 1, figsize=(7, 7.5), constrained_layout=True)
    zoom = analyze_stability(res.params, np.linspace(max(res.k[0], 1e-4), zoom_k_max, 1600))
    for ax, r, label in ((axes[0], res, "(a)"), (axes[1], zoom, "(b)")):
        for j in range(3):
            ax.plot(r.k, r.omega[:, j].imag, STYLES[j], color="k", lw=1.2, label=f"root {j + 1}")
        ax.axhline(0, color="0.6", lw=0.7)
        m = r.most_unstable
        if m is not None:
            what = "most unstable" if m.at_range_edge is None else f"largest at {m.at_range_edge} (no maximum inside)"
            ax.plot([m.k], [m.growth_rate], "o", color="tab:red",
                    label=f"{what} k* = {m.k:.3f} (λ/D = {m.wavelength_over_diameter:.1f})")
        for kc in r.cutoff_k:
            ax.axvline(kc, color="tab:blue", ls=":", lw=1,
                       label=f"cut-off k* = {kc:.3f} (λ/D = {2 * np.pi / kc:.1f})")
        ax.set_xlabel("k* = kD")
        ax.set_ylabel("growth rate ω_i*")
        ax.set_title(label, loc="left")
        ax.legend(fontsize=pt(7), loc="lower left")
    g = zoom.omega.imag
    lo = max(np.percentile(g, 5), -1.0)
    hi = max(float(g.max()), 0.05)
    axes[1].set_ylim(lo - 0.05 * (hi - lo), hi + 0.1 * (hi - lo))
    axes[1].set_xlim(0, zoom_k_max)
    p = res.params
    m = res.most_unstable
    verdict = ("no unstable mode" if m is None else
               f"growth largest at {m.at_range_edge}" if m.at_range_edge else
               f"most unstable λ/D = {m.wavelength_over_diameter:.1f}")
    P0 = p.base_pressure_abs_pa
    pressure = f"{P0:.0f}" if P0 >= 1000 else f"{P0:.3g}"
    fig.suptitle(f"friction {p.law}, air at {pressure} Pa (B* = {p.B_star:.4g}): {verdict}\n"
                 f"B1* = {p.B1_star:.3f}, c0 = {p.c0}, κ = {p.kappa}, μs = {p.mu_s:.4f}, θ = {p.theta_deg}°",
                 fontsize=pt(9))
    return fig
