"""The spatiotemporal diagram and the band of the tube it is made from.

Each frame is reduced to one profile along the tube axis: the mean grey level
over the core of the bore (the central 70% of the inner diameter, away from the
walls), sampled at every pixel row along the axis. :func:`band_along_tube` says
which pixels those are (a :class:`grainplug.band.Band`); the movie's reader
computes the profiles (:meth:`grainplug.readers.Movie.read_band`), reading only
those pixels, so memory does not depend on the movie's length.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..band import Band
from ..calibration.tube import TubeGeometry

log = logging.getLogger(__name__)

CORE_FRACTION = 0.7


@dataclass(frozen=True)
class Diagram:
    """Spatiotemporal diagram: grey level along the tube (columns) against time (rows).

    Attributes
    ----------
    values : ndarray, shape (n_frames, n_positions)
        Mean grey level of the bore's core, float32.
    time_s : ndarray, shape (n_frames,)
        Time of each frame from the first one.
    position_mm : ndarray, shape (n_positions,)
        Position along the tube from the upstream end of the view, increasing with the flow.
    mm_per_px : float
        Scale used to turn axis samples into mm.
    """

    values: np.ndarray
    time_s: np.ndarray
    position_mm: np.ndarray
    mm_per_px: float

    @property
    def n_frames(self) -> int:
        return self.values.shape[0]


def display_stride(shape: tuple[int, int], max_side: int = 1200) -> tuple[int, int]:
    """Strides (time, position) that bring a diagram to at most ``max_side`` samples a side.

    A figure ~1000 px wide shows no more; matplotlib resamples the image to RGBA
    floats, which for a long record would cost more memory than the analysis.
    """
    return -(-shape[0] // max_side), -(-shape[1] // max_side)


def band_along_tube(tube: TubeGeometry, *, core_fraction: float = CORE_FRACTION) -> tuple[Band, np.ndarray]:
    """The core band of the bore along the axis: which pixels make each profile sample.

    Parameters
    ----------
    tube : TubeGeometry
        The tube found by :func:`grainplug.calibration.find_tube`.
    core_fraction : float
        Part of the inner diameter that is averaged across the tube.

    Returns
    -------
    band : Band
        Pixels and weights, in frame coordinates, from the top (left) of the view; the
        pipeline turns the diagram once the flow direction is known
        (:func:`grainplug.pipeline.analyze`).
    axis_px : ndarray
        Distance of each position along the axis from the top (left) edge of the
        view, in pixels.

    Notes
    -----
    At canonical row :math:`y` the axis lies at :math:`x_a(y)` (:meth:`TubeGeometry.axis_x`);
    the samples are the pixels :math:`x_a(y) + j`, :math:`|j| \\le \\lfloor c D / 2 \\rfloor`
    with :math:`c` the core fraction and :math:`D` the inner diameter in pixels, equally
    weighted, rows where fewer than half of them lie in the frame dropped. Along a
    tilted axis a row step is :math:`1 / \\cos\\theta` pixels of axis.
    """
    h, w = tube.canonical_shape
    half = max(1.0, 0.5 * core_fraction * tube.inner_diameter_px)
    offsets = np.arange(-np.floor(half), np.floor(half) + 1)
    rows = np.arange(h)
    cols = np.rint(tube.axis_x(rows)[:, None] + offsets[None, :]).astype(np.int64)
    valid = (cols >= 0) & (cols < w)
    keep = valid.mean(axis=1) >= 0.5  # rows where the band is mostly in the frame
    rows = rows[keep]
    cols = np.clip(cols[keep], 0, w - 1)
    weights = valid[keep].astype(np.float32)
    weights /= weights.sum(axis=1, keepdims=True)
    along = np.repeat(rows[:, None], cols.shape[1], axis=1)
    if tube.orientation == "horizontal":  # canonical view = the frame transposed
        band = Band(cols, along, np.ascontiguousarray(weights), (w, h))
    else:
        band = Band(along, cols, np.ascontiguousarray(weights), (h, w))
    cos_t = np.cos(np.radians(tube.tilt_deg))
    return band, (rows + 0.5) / cos_t
