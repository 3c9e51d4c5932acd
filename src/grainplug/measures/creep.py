"""The packed grains' velocity inside the plugs, from their texture on the diagram.

Notes
-----
Grains join a plug at its top and rain off its bottom, so the plug *pattern* may climb at tens of mm/s
while the grains inside creep downstream at a few mm/s. The pattern's edges say nothing of the grains;
the texture of the packed grains does. It survives the diagram's average across the bore's core (the
average of a few grains across is still a random pattern along the tube, tested on rendered discs).

For frames ``k`` and ``k + L`` (``L`` the lag), windows ``window_mm`` long are placed where the tube is a
plug in both frames, far enough from every edge that neither the window nor its search range reaches a
bubble (the edges, moving the other way, are masked, not fought). Each window is detrended and
cross-correlated (normalised) with frame ``k + L`` over shifts ``-S..S``; the peak is refined to a
sub-sample shift by a parabola through the three best values. A window's velocity is its shift times
the sample spacing over the time between the frames, positive downstream.

The lag is chosen from the movie: it grows (1, 2, 3, 4, 6, 8, ...) until the texture's typical shift
reaches ``target_shift_px``, while enough windows stay inside the plugs and the texture still correlates
(grains rearrange; plugs end). The search range follows the shift found at the shorter lag, so grains
moving with oscillating plugs (several px per frame) are followed as well as a creep of 0.1 px per frame.

The mean is over time (each pair's windows averaged, then the pairs: a time of many plugs counts as
much as one of few); its 95 % interval comes from batch means over blocks of time (each several lags
long, so that a window's error is not shared by two blocks) with Student's t. When too few windows
correlate (no texture, too few or too short plugs) the velocity is not given and a coded
warning (``grains.texture_weak``) says why.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..warning_codes import coded

log = logging.getLogger(__name__)

#: lags tried, in frames (the longest one that meets the conditions is kept)
LAGS = (1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128)


@dataclass(frozen=True)
class GrainVelocity:
    """The grains' velocity inside the plugs, window by window, and its mean.

    Attributes
    ----------
    frame : ndarray of int
        First frame of each window's pair (the second is ``frame + lag_frames``).
    time_s : ndarray of float
        Mid-time of the pair.
    position_mm : ndarray of float
        Centre of the window along the tube (the diagram's positions).
    run : ndarray of int
        Row of :class:`~grainplug.plugs.Runs` holding the window in the first frame (which plug).
    velocity_m_s : ndarray of float
        The grains' velocity in the window, positive downstream.
    peak : ndarray of float
        The window's normalised correlation at its peak (0..1).
    lag_frames : int
        Frames between the two of a pair (0: not measured).
    mean_m_s : float or None
        Mean over time (the windows of each pair averaged, then the pairs); None when the texture is too weak.
    ci95_m_s : tuple of float or None
        Its 95 % interval (batch means over independent blocks of time).
    warnings : tuple of str
        Coded warnings (``grains.texture_weak``).
    """

    frame: np.ndarray
    time_s: np.ndarray
    position_mm: np.ndarray
    run: np.ndarray
    velocity_m_s: np.ndarray
    peak: np.ndarray
    lag_frames: int
    mean_m_s: float | None
    ci95_m_s: tuple[float, float] | None
    warnings: tuple[str, ...] = ()

    def per_plug(self, track_of_run: np.ndarray | None = None) -> dict[int, tuple[float, int]]:
        """Mean velocity (m/s) and number of windows of each plug.

        Parameters
        ----------
        track_of_run : ndarray of int, optional
            The track of each row of the runs (a plug followed through time); without it, each run
            (one plug in one frame) is its own plug.
        """
        key = self.run if track_of_run is None else np.asarray(track_of_run)[self.run]
        out: dict[int, tuple[float, int]] = {}
        for k in np.unique(key):
            sel = key == k
            out[int(k)] = (float(np.mean(self.velocity_m_s[sel])), int(sel.sum()))
        return out


def _plug_mask(frame: np.ndarray, start: np.ndarray, stop: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The runs as a boolean ``frames x positions`` mask, and each sample's run row (-1 outside)."""
    owner = np.full(shape, -1, np.int64)
    for r, (k, a, b) in enumerate(zip(frame, start, stop, strict=True)):
        owner[int(k), int(a):int(b)] = r
    return owner


def _erode(mask: np.ndarray, n: int) -> np.ndarray:
    """``mask`` (1D bool) shrunk by ``n`` samples at every end of its runs."""
    if n <= 0:
        return mask
    c = np.concatenate([[0], np.cumsum(~mask)])
    m = len(mask)
    i = np.arange(m)
    lo, hi = i - n, i + n + 1
    ok = (lo >= 0) & (hi <= m)
    out = np.zeros(m, bool)
    out[ok] = (c[hi[ok]] - c[lo[ok]]) == 0
    return out


def _pairs(values: np.ndarray, owner: np.ndarray, starts: np.ndarray, lag: int, half: int, search: int,
           margin: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Windows of frames ``starts`` against ``starts + lag``: frame, centre, run, shift (samples), peak."""
    n_pos = values.shape[1]
    fr, cen = [], []
    step = 2 * half
    for k in starts:
        a = _erode(owner[k] >= 0, half + margin)
        b = _erode(owner[k + lag] >= 0, half + search + margin)
        ok = a & b
        if not ok.any():
            continue
        # centres a window apart along each stretch of valid centres
        idx = np.flatnonzero(ok)
        brk = np.flatnonzero(np.diff(idx) > 1) + 1
        for seg in np.split(idx, brk):
            n = 1 + (len(seg) - 1) // step
            off = (len(seg) - 1 - (n - 1) * step) // 2
            cen.extend(seg[off::step][:n])
            fr.extend([k] * n)
    if not fr:
        e = np.empty(0)
        return e.astype(int), e.astype(int), e.astype(int), e, e
    fr_a, cen_a = np.asarray(fr), np.asarray(cen)
    w = np.arange(-half, half)
    a = values[fr_a[:, None], np.clip(cen_a[:, None] + w, 0, n_pos - 1)].astype(np.float64)
    a = _detrend(a)
    shifts = np.arange(-search, search + 1)
    cc = np.empty((len(fr_a), len(shifts)))
    for j, s in enumerate(shifts):
        b = values[fr_a[:, None] + lag, np.clip(cen_a[:, None] + w + s, 0, n_pos - 1)].astype(np.float64)
        b = _detrend(b)
        cc[:, j] = np.sum(a * b, axis=1)
    best = np.argmax(cc, axis=1)
    peak = cc[np.arange(len(best)), best]
    inner = np.clip(best, 1, len(shifts) - 2)
    y0, y1, y2 = (cc[np.arange(len(best)), inner + d] for d in (-1, 0, 1))
    den = y0 - 2 * y1 + y2
    sub = np.where(den < 0, 0.5 * (y0 - y2) / np.where(den < 0, den, -1.0), 0.0)
    shift = shifts[inner] + np.clip(sub, -0.5, 0.5)
    edge = (best == 0) | (best == len(shifts) - 1)  # the peak at the search's end: not found
    peak = np.where(edge, 0.0, peak)
    return fr_a, cen_a, owner[fr_a, cen_a], shift, peak


def _detrend(x: np.ndarray) -> np.ndarray:
    """Each row less its straight-line fit, scaled to unit norm (zero rows stay zero)."""
    n = x.shape[1]
    t = np.arange(n) - (n - 1) / 2.0
    x = x - x.mean(axis=1, keepdims=True)
    x = x - np.outer(x @ t / (t @ t), t)
    norm = np.sqrt(np.sum(x * x, axis=1, keepdims=True))
    return x / np.where(norm > 0, norm, 1.0)


def grain_velocity(values: np.ndarray, time_s: np.ndarray, spacing_mm: float, position_mm: np.ndarray,
                   frame: np.ndarray, start: np.ndarray, stop: np.ndarray, *, window_mm: float = 3.0,
                   edge_margin_mm: float = 0.6, target_shift_px: float = 3.0, min_peak: float = 0.6,
                   min_windows: int = 40, max_pairs: int = 4000, n_blocks: int = 10) -> GrainVelocity:
    """The packed grains' velocity inside the plugs (see the module's notes).

    Parameters
    ----------
    values : ndarray, shape (n_frames, n_positions)
        The diagram's grey levels, positions increasing downstream.
    time_s : ndarray
        Each frame's time.
    spacing_mm : float
        Distance between the diagram's samples.
    position_mm : ndarray
        The diagram's positions.
    frame, start, stop : ndarray of int
        The plugs of each frame (:class:`~grainplug.plugs.Runs`): frame, first and past-last sample.
    window_mm : float, optional
        Length of a correlation window along the tube.
    edge_margin_mm : float, optional
        Distance kept from every plug edge beyond the window and its search range.
    target_shift_px : float, optional
        The texture's typical shift, in samples, that the lag is chosen to reach.
    min_peak : float, optional
        Least normalised correlation of a window kept.
    min_windows : int, optional
        Fewest windows kept for a velocity to be given.
    max_pairs : int, optional
        Most pairs of frames correlated (evenly spread over the record).
    n_blocks : int, optional
        Blocks of time for the interval (fewer when the record is short for the lag).

    Returns
    -------
    GrainVelocity
    """
    values = np.asarray(values)
    t_n, n_pos = values.shape
    half = max(4, int(round(window_mm / spacing_mm / 2)))
    margin = max(1, int(round(edge_margin_mm / spacing_mm)))
    owner = _plug_mask(np.asarray(frame), np.asarray(start), np.asarray(stop), (t_n, n_pos))
    empty = GrainVelocity(np.empty(0, int), np.empty(0), np.empty(0), np.empty(0, int), np.empty(0), np.empty(0),
                          0, None, None)
    if t_n < 3 or not len(frame):
        return _weak(empty, "no plugs to measure the grains' velocity in")
    dt = float(np.median(np.diff(time_s)))
    chosen = None
    v_px = None  # the largest typical shift per frame at the last lag (samples), for the next search range
    for lag in LAGS:
        if lag >= t_n // 3:
            break
        search = half if v_px is None else int(np.ceil(1.5 * v_px * lag)) + 3
        probe = np.unique(np.linspace(0, t_n - lag - 1, min(300, t_n - lag)).round().astype(int))
        _, _, _, shift, peak = _pairs(values, owner, probe, lag, half, search, margin)
        good = peak >= min_peak
        if good.sum() < max(10, min_windows // 4) or np.median(peak) < min_peak:
            log.debug("lag %d: %d windows, stopped", lag, good.sum())
            break
        if np.mean(peak == 0.0) > 0.05:  # the shift outran the search range: the last lag is the longest
            break
        v_px = float(np.quantile(np.abs(shift[good]), 0.95)) / lag
        chosen = (lag, search)
        if np.median(np.abs(shift[good])) >= target_shift_px:
            break
    if chosen is None:
        return _weak(empty, "the plugs' texture does not correlate from frame to frame")
    lag, search = chosen
    starts = np.unique(np.linspace(0, t_n - lag - 1, min(max_pairs, t_n - lag)).round().astype(int))
    fr, cen, run, shift, peak = _pairs(values, owner, starts, lag, half, search, margin)
    keep = peak >= min_peak
    fr, cen, run, shift, peak = fr[keep], cen[keep], run[keep], shift[keep], peak[keep]
    span = np.asarray(time_s)[fr + lag] - np.asarray(time_s)[fr]
    span = np.where(span > 0, span, lag * dt)
    vel = shift * spacing_mm / span / 1000.0
    t_mid = 0.5 * (np.asarray(time_s)[fr] + np.asarray(time_s)[fr + lag])
    out = GrainVelocity(fr, t_mid, np.asarray(position_mm)[cen], run, vel, peak, lag, None, None)
    if len(vel) < min_windows:
        return _weak(out, f"only {len(vel)} windows of the plugs' texture correlate")
    frames, per_frame = _per_frame(fr, vel)
    mean = float(np.mean(per_frame))
    ci = _batch_interval(frames, per_frame, t_n, lag, n_blocks)
    return GrainVelocity(fr, t_mid, out.position_mm, run, vel, peak, lag, mean, ci)


def _per_frame(fr: np.ndarray, vel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The mean velocity of each pair's windows: a time series (each time weighted once, whatever the
    number of plugs then: oscillating plugs carry more of the tube at some phases than at others)."""
    frames, inv = np.unique(fr, return_inverse=True)
    return frames, np.bincount(inv, weights=vel) / np.bincount(inv)


def _batch_interval(fr: np.ndarray, vel: np.ndarray, t_n: int, lag: int, n_blocks: int) -> tuple[float, float] | None:
    """95 % interval of the mean from batch means over blocks of time at least four lags long."""
    from scipy import stats

    n_b = int(min(n_blocks, t_n // max(4 * lag, 1)))
    if n_b < 4:
        return None
    edges = np.linspace(0, t_n, n_b + 1)
    blk = np.clip(np.searchsorted(edges, fr, "right") - 1, 0, n_b - 1)
    means = np.array([vel[blk == b].mean() for b in range(n_b) if np.any(blk == b)])
    if len(means) < 4:
        return None
    centre = float(np.mean(vel))
    half = float(stats.t.ppf(0.975, len(means) - 1) * means.std(ddof=1) / np.sqrt(len(means)))
    return centre - half, centre + half


def _weak(gv: GrainVelocity, why: str) -> GrainVelocity:
    """``gv`` without a velocity, with the warning that says why."""
    w = coded("grains.texture_weak", f"the grains' velocity inside the plugs is not given: {why} "
              "(too little texture, or plugs too short or too few); light the grains so that they show")
    return GrainVelocity(gv.frame, gv.time_s, gv.position_mm, gv.run, gv.velocity_m_s, gv.peak, gv.lag_frames,
                         None, None, (w,))
