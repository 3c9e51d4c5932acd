"""Figures of a simulation: the compactness diagram and the wave count."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from matplotlib.ticker import MaxNLocator

from ._figure import new_figure, pt

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ..simulation.state import SimulationResult


def plot_simulation(res: SimulationResult, counts: np.ndarray, *, close_packing: float, min_range_c: float,
                    max_rows: int = 1500) -> Figure:
    """(a) compactness over position and time (flow downward), (b) dense segments and peak compactness.

    Parameters
    ----------
    res : SimulationResult
        The run.
    counts : ndarray
        The number of dense segments at each output time
        (:func:`grainplug.simulation.waves.segment_counts`).
    close_packing : float
        The compactness drawn as a dotted line (random close packing).
    min_range_c : float
        A compactness range narrower than this is drawn over this range (a uniform flow's round-off ripples are
        not stretched over the colour scale).
    max_rows : int
        At most this many output times are drawn in (a).
    """
    p = res.model
    fig, axes = new_figure(1, 2, figsize=(9, 5.5), constrained_layout=True,
                           gridspec_kw={"width_ratios": [3, 1.2]})
    ax = axes[0]
    step = max(1, len(res.time) // max_rows)
    t_s = res.time[::step] * p.t_c_s
    z_mm = res.z * p.diameter_mm
    lo, hi = float(res.c.min()), float(res.c.max())
    if hi - lo < min_range_c:  # a uniform flow: its round-off ripples are not stretched over the colour scale
        mid = 0.5 * (lo + hi)
        lo, hi = mid - 0.5 * min_range_c, mid + 0.5 * min_range_c
    im = ax.pcolormesh(t_s, z_mm, res.c[::step].T, shading="nearest", cmap="cividis_r", rasterized=True,
                       vmin=lo, vmax=hi)
    ax.set_ylim(z_mm[-1], z_mm[0])  # positions from the top, increasing with the flow (downward)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("position from the top (mm)")
    ax.set_title("(a) compactness c", loc="left", fontsize=pt(10))
    cbar = fig.colorbar(im, ax=ax, label="compactness c", shrink=0.85)
    cbar.formatter.set_useOffset(False)  # compactness read as it is, not as an offset plus 1e-9s
    ax2 = axes[1]
    t_all = res.time * p.t_c_s
    ax2.plot(t_all, counts, color="k", lw=1.2, label="dense segments")
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("number of dense segments")
    ax2.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax2.set_ylim(-0.5, max(1.5, float(counts.max()) + 0.5))  # whole numbers of segments, 0 and 1 at least
    ax3 = ax2.twinx()
    ax3.plot(t_all, res.c.max(axis=1), color="#d55e00", lw=1.0, label="max c")
    ax3.axhline(close_packing, color="#d55e00", ls=":", lw=0.8)
    ax3.set_ylabel("max c (dotted: random close packing)", color="#d55e00")
    ax2.set_title("(b) waves", loc="left", fontsize=pt(10))
    law = p.law
    fig.suptitle(f"{res.params.boundary} {res.params.length_D:g} D ({res.params.length_D * p.diameter_mm:g} mm), "
                 f"{res.params.n_cells} cells — friction {law}, P0 = {p.base_pressure_abs_pa:.3g} Pa"
                 + (", jamming" if p.jamming else ""), fontsize=pt(9))
    return fig
