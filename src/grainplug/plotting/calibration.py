"""The figure of a calibration: the image with the points found and where the scale was taken."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ._figure import new_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ..calibration.pattern import Calibration


def plot_calibration(image: np.ndarray, cal: Calibration) -> Figure:
    """The calibration image in grey with the points found (red crosses), the point the scale is taken at
    (cyan) and the scale, tilt and variation in the title."""
    img = np.asarray(image, dtype=np.float64)
    if img.ndim == 3:
        img = img[..., :3].mean(axis=2)
    h, w = img.shape
    fig, ax = new_figure(figsize=(8.0, 8.0 * h / w + 0.6))
    ax.imshow(img, cmap="gray", interpolation="nearest")
    if cal.points_px:
        pts = np.asarray(cal.points_px)
        what = {"graph": "line crossings", "ruler": "ticks"}.get(cal.pattern, "points")
        ax.plot(pts[:, 0], pts[:, 1], "+", color="tab:red", markersize=6, markeredgewidth=1.0,
                label=f"{cal.n_points} {what} found")
    ax.plot(*cal.centre_px, "o", color="tab:cyan", markersize=6, label="scale taken here")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(f"{cal.mm_per_px:.5g} mm/px ± {100 * cal.rel_sd:.2g} % ({cal.pattern}, pitch {cal.pitch_mm:g} mm), "
                 f"tilt {cal.tilt_deg:+.2f}°, variation {100 * cal.scale_variation:.2g} %", fontsize=9)
    ax.set_axis_off()
    return fig
