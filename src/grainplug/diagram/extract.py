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


#: the background beside the tube is sampled this many inner widths from the axis (beyond the walls of a tube
#: up to twice as wide outside as inside), on each side
BESIDE_WIDTHS = (1.8, 2.3)
#: heights along the tube of the profiles across it (for its motion across)
ACROSS_PROFILES = 3
#: the background beside the tube is read every this many positions along it (each sample averages them)
BESIDE_STEP = 4
#: the profiles across the tube reach this many inner widths either side of the axis (beyond the walls)
ACROSS_WIDTHS = 1.6
#: where the tube's motion along it is read at every position (inner widths from the axis, when its outer
#: silhouette was not measured): in its walls, and just beyond them, where what is fixed to the tube (a clamp's
#: overhang, a label's edges, a mark) stands still against the tube while the grains move inside
NEAR_WALL_WIDTHS = (0.7, 1.15)
#: what the profiles along the tube at :data:`NEAR_WALL_WIDTHS` are read on
NEAR_NAMES = ("the tube's walls", "the background just beyond the walls", "a mark beside the tube")
#: just beyond the outer silhouette, this far out (px, at least; or this share of the inner width)
NEAR_OUTSIDE_PX, NEAR_OUTSIDE_WIDTHS = 2.0, 0.1


@dataclass(frozen=True)
class Probes:
    """Where, in the output of one :meth:`~grainplug.readers.Movie.read_band` of :func:`probes_along_tube`'s band,
    each kind of sample lies (column indices of the ``frames x samples`` array).

    Attributes
    ----------
    core : slice
        The diagram: the bore's core at every position along the tube.
    beside : ndarray
        The background beside the tube (both sides averaged, or the one the frame reaches) every
        :data:`BESIDE_STEP` positions along it (-1 where neither is in the frame).
    across : ndarray, shape (n_profiles, n_offsets)
        Profiles across the tube at a few heights along it (each sample averages a few rows).
    """

    core: slice
    beside: np.ndarray
    across: np.ndarray
    #: the position (in samples along the tube) of each sample beside it
    beside_at: np.ndarray
    #: profiles along the tube at every position, in its walls and just beyond them (:data:`NEAR_WALL_WIDTHS`):
    #: one row of output columns each, all in the frame
    near: tuple[np.ndarray, ...] = ()

    def core_band(self, band: Band) -> Band:
        """The core's samples of ``band`` alone (what :func:`band_along_tube` gives)."""
        c = self.core
        return Band(band.rows[c], band.cols[c], band.weights[c], band.frame_shape)

    def split(self, values: np.ndarray) -> tuple[np.ndarray, list[np.ndarray], np.ndarray, np.ndarray]:
        """``(core, across, beside, at)`` of one read's ``frames x samples`` values: the diagram, the profiles
        across the tube (samples in the frame only), the background beside it at the positions ``at`` (in samples
        along the tube) the frame reaches. ``core`` and ``beside`` are views of ``values`` (no copy)."""
        core = values[:, self.core]
        across = [values[:, row[row >= 0]] for row in self.across]
        where = self.beside >= 0
        cols = self.beside[where]
        beside = values[:, cols[0]: cols[-1] + 1] if cols.size else values[:, :0]  # the columns are consecutive
        return core, across, beside, self.beside_at[where]

    def along(self, values: np.ndarray) -> list[tuple[np.ndarray, float, str]]:
        """The profiles along the tube of what does not move with the grains (views of ``values``), each with its
        spacing in positions along the tube and what it is: the ones read at every position (:meth:`near_profiles`),
        and the background beside the tube every :data:`BESIDE_STEP` (where the frame reaches it all)."""
        out = [(p, 1.0, name) for p, name in zip(self.near_profiles(values), NEAR_NAMES, strict=True)
               if p is not None]
        if self.beside.size and (self.beside >= 0).all():
            cols = self.beside
            out.append((values[:, cols[0]: cols[-1] + 1], float(BESIDE_STEP), "the background beside the tube"))
        return out

    def near_of(self, band: Band, frames: list[np.ndarray]) -> list[np.ndarray | None]:
        """:meth:`near_profiles` of a few frames (``frames x positions`` each), reading those profiles' samples of
        ``band`` only (:meth:`grainplug.band.Band.profile`, plainly)."""
        cols = [c for c in self.near[: len(NEAR_NAMES)] if c.size]
        if not cols or not frames:
            return [None] * len(NEAR_NAMES)
        every = np.concatenate(cols)
        used = max(int((band.weights[every] != 0).sum(axis=1).max()), 1)  # their samples lead, the padding follows
        sub = Band(band.rows[every, :used], band.cols[every, :used], band.weights[every, :used], band.frame_shape)
        values = np.stack([sub.profile(f) for f in frames])
        out: list[np.ndarray | None] = [None] * len(NEAR_NAMES)
        start = 0
        for k, c in enumerate(self.near[: len(NEAR_NAMES)]):
            if c.size:
                out[k] = values[:, start: start + c.size]
                start += c.size
        return out

    def near_jumps(self, band: Band) -> list[np.ndarray | None]:
        """Where each profile of :meth:`near_profiles` jumps a pixel across the tube (True at a position whose
        samples are not the previous position's shifted along): there the profile steps by the image's gradient
        across, a step fixed to the sensor, not to the tube (None for a profile not read)."""
        out: list[np.ndarray | None] = []
        for c in self.near[: len(NEAR_NAMES)]:
            if not c.size:
                out.append(None)
                continue
            r, k = band.rows[c], band.cols[c]
            # the pixel's coordinate across the tube: the one that stays put from one position to the next
            across = k if (np.diff(r[:, 0]) != 0).mean() >= (np.diff(k[:, 0]) != 0).mean() else r
            jump = np.zeros(len(c), bool)
            jump[1:] = (np.diff(across, axis=0) != 0).any(axis=1)
            out.append(jump)
        return out

    def near_profiles(self, values: np.ndarray) -> list[np.ndarray | None]:
        """The profiles along the tube in its walls and just beyond them (views of ``values``; None for one not
        read), in the order of :data:`NEAR_NAMES`."""
        out: list[np.ndarray | None] = [None] * len(NEAR_NAMES)
        for k, cols in enumerate(self.near[: len(NEAR_NAMES)]):
            if cols.size:
                out[k] = values[:, cols[0]: cols[-1] + 1]
        return out


def resample_positions(values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The diagram read at fractional sample indices ``at`` along the tube (linear interpolation between samples).

    Parameters
    ----------
    values : ndarray, shape (n_frames, n_positions)
        The band's samples, evenly spaced in pixels along the tube.
    at : ndarray, shape (n_positions,)
        Increasing fractional indices in ``[0, n_positions - 1]`` (e.g.
        :func:`grainplug.calibration.scale.uniform_samples`).

    Returns
    -------
    ndarray, shape (n_frames, n_positions)
        Of ``values``' dtype when it is floating, else float32.
    """
    dtype = values.dtype if np.issubdtype(values.dtype, np.floating) else np.dtype(np.float32)
    at = np.clip(np.asarray(at, float), 0.0, values.shape[1] - 1)
    i0 = np.minimum(np.floor(at).astype(np.intp), values.shape[1] - 2)
    frac = (at - i0).astype(dtype)
    return (values[:, i0] * (1 - frac) + values[:, i0 + 1] * frac).astype(dtype, copy=False)


def probes_along_tube(tube: TubeGeometry, *, core_fraction: float = CORE_FRACTION,
                      near: tuple[bool, ...] = (True, True, True)) -> tuple[Band, np.ndarray, Probes]:
    """The core band of the bore (:func:`band_along_tube`) and, read in the same pass, what does not move
    with the grains: the background beside the tube along it (the lamp's light, row by row and frame by frame)
    and profiles across the tube through its walls (the tube's own motion in the image: camera shake).

    Returns
    -------
    band : Band
        Every sample, the core's first (the same as :func:`band_along_tube`'s); other samples are
        padded with zero weights to the core's width.
    axis_px : ndarray
        As :func:`band_along_tube`.
    probes : Probes
        Which output columns hold what.

    ``near``: whether the profiles along the tube at every position in its walls, just beyond them and beside the
    tube (where a ruler or a mark would stand: :data:`NEAR_NAMES`) are read (each costs about a fifth of the
    core's reading: :func:`grainplug.measures.shake.best_along` on the sampled frames tells which measures best).
    """
    core, axis_px = band_along_tube(tube, core_fraction=core_fraction)
    h, w = tube.canonical_shape
    width = core.rows.shape[1]
    d = float(tube.inner_diameter_px)
    horizontal = tube.orientation == "horizontal"
    # canonical (row along, column across) of the core's samples
    along_c, across_c = (core.cols, core.rows) if horizontal else (core.rows, core.cols)
    rows = along_c[:, 0]
    groups_r: list[np.ndarray] = []
    groups_c: list[np.ndarray] = []
    groups_w: list[np.ndarray] = []
    n = core.n_positions

    def add(r: np.ndarray, c: np.ndarray) -> np.ndarray:
        """Groups of canonical pixels (one group a row of ``r``/``c``, equal weights where in the frame);
        returns their output columns, -1 for a group wholly out of the frame."""
        inside = (c >= 0) & (c < w) & (r >= 0) & (r < h)
        ok = inside.any(axis=1)
        k = int(ok.sum())
        pad = np.zeros((k, width), np.int64)
        rr, cc, ww = pad.copy(), pad.copy(), np.zeros((k, width), np.float32)
        m = min(width, r.shape[1])
        rr[:, :m] = np.clip(r[ok][:, :m], 0, h - 1)
        cc[:, :m] = np.clip(c[ok][:, :m], 0, w - 1)
        ww[:, :m] = inside[ok][:, :m]
        ww /= ww.sum(axis=1, keepdims=True)
        rr[:, m:], cc[:, m:] = rr[:, :1], cc[:, :1]  # padding: a sample of the group, weight 0
        start = n + sum(len(g) for g in groups_r)
        groups_r.append(rr)
        groups_c.append(cc)
        groups_w.append(ww)
        out = np.full(len(r), -1, np.int64)
        out[ok] = start + np.arange(k)
        return out

    lo, hi = BESIDE_WIDTHS
    # both sides in one sample every BESIDE_STEP positions (the lamp's level there; where one side is out of the
    # frame, the other): BESIDE_STEP rows by a column each side at the middle distance
    at = np.arange(0, n - BESIDE_STEP + 1, BESIDE_STEP)
    per_side = min(BESIDE_STEP, width // 2)  # rows a sample averages on each side (the band's width holds both)
    r = rows[at][:, None] + np.tile(np.linspace(0, BESIDE_STEP - 1, per_side).round().astype(int), 2)[None, :]
    side = np.repeat([-1.0, 1.0], per_side)[None, :] * (0.5 * (lo + hi) * d)
    c = np.rint(tube.axis_x(r.astype(float)) + side).astype(np.int64)
    beside = add(r, c)
    beside_at = at + 0.5 * (BESIDE_STEP - 1)
    wanted, near = near, []
    for offset, read in zip(_near_offsets(tube), wanted, strict=True):
        if not read:  # kept in place: the profiles' order says what each is
            near.append(np.zeros(0, np.int64))
            continue
        # a pixel a side, every position; a side out of the frame anywhere is dropped (its switch from two sides to
        # one would be an edge fixed to the frame, not to the tube)
        r = rows[:, None]
        sides = []
        for sign in (-1.0, 1.0):
            c = np.rint(tube.axis_x(r.astype(float)) + sign * offset).astype(np.int64)
            if ((c >= 0) & (c < w) & (r >= 0) & (r < h)).all():
                sides.append(c)
        near.append(add(np.repeat(r, len(sides), axis=1), np.concatenate(sides, axis=1)) if sides
                    else np.zeros(0, np.int64))
    offsets = np.arange(-np.ceil(ACROSS_WIDTHS * d), np.ceil(ACROSS_WIDTHS * d) + 1)
    heights = rows[np.linspace(0, n - 1, ACROSS_PROFILES + 2).round().astype(int)[1:-1]]
    tall = width
    across = []
    for y in heights:
        r = (y + np.arange(tall) - tall // 2)[None, :].repeat(len(offsets), axis=0)
        c = np.rint(tube.axis_x(r.astype(float)) + offsets[:, None]).astype(np.int64)
        across.append(add(r, c))
    rr = np.concatenate([along_c, *groups_r]) if groups_r else along_c
    cc = np.concatenate([across_c, *groups_c]) if groups_c else across_c
    ww = np.concatenate([core.weights, *groups_w]) if groups_w else core.weights
    band = Band(cc, rr, np.ascontiguousarray(ww), (w, h)) if horizontal else \
        Band(rr, cc, np.ascontiguousarray(ww), (h, w))
    probes = Probes(slice(0, n), beside, np.stack(across) if across else np.zeros((0, 0), np.int64), beside_at,
                    tuple(near))
    return band, axis_px, probes


def _near_offsets(tube: TubeGeometry) -> tuple[float, float, float]:
    """Distances (px from the axis, across it) of the profiles along the tube in its walls, just beyond them (from
    the outer silhouette when it was measured, else :data:`NEAR_WALL_WIDTHS`) and beside the tube (where the lamp is
    read: :data:`BESIDE_WIDTHS`)."""
    d = float(tube.inner_diameter_px)
    beside = 0.5 * (BESIDE_WIDTHS[0] + BESIDE_WIDTHS[1]) * d
    outer = None if tube.walls is None else float(tube.walls.outer_half_px)
    if outer is None or not np.isfinite(outer) or outer <= 0.5 * d + 1.0:
        return NEAR_WALL_WIDTHS[0] * d, NEAR_WALL_WIDTHS[1] * d, beside
    return 0.5 * (0.5 * d + outer) - 0.5, outer + max(NEAR_OUTSIDE_PX, NEAR_OUTSIDE_WIDTHS * d), beside
