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
(grains rearrange; plugs end). The pairs' lags are then dithered, from the lag chosen to a few frames more
(until the typical shift has gone one sample further): the parabola pulls a sub-sample peak towards the
nearest whole sample (by up to 0.08 sample for a texture 1.5 px fine, measured), and with every
sub-sample part represented that pull averages out instead of biasing a steady creep. The search range
follows the shift found at the shorter lag, so grains moving with oscillating plugs (several px per frame)
are followed as well as a creep of 0.1 px per frame.

The mean is over time (each pair's windows averaged, then the pairs: a time of many plugs counts as
much as one of few), over the whole record (the half lag at each end that no pair's middle reaches
takes the series' mean over as long again at that end); its 95 % interval comes from batch means over
blocks of time (each several lags long, so that a window's error is not shared by two blocks) with
Student's t, widened by what the dithering may leave of the sub-sample pull (:data:`SUBSAMPLE_BIAS`,
type B). When too few windows correlate (no texture, too few or too short plugs), or the record is too
short for four blocks, the velocity is not given and a coded warning (``grains.texture_weak``) says why.
When the texture's typical shift stays under a sample up to the longest lag, the velocity is given with
``grains.texture_still``: grains at rest and a pattern fixed to the tube or camera look the same.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from .._filters import t_quantile_975
from ..warning_codes import coded

log = logging.getLogger(__name__)

#: what remains of the sub-sample peak's pull towards whole samples once the lags are dithered (samples, a
#: standard uncertainty): an eighth of the largest pull measured without dithering (0.08 sample)
SUBSAMPLE_BIAS = 0.01

#: pairs of frames correlated at each lag tried while the lag is chosen
PROBE_PAIRS = 120

#: the texture's typical shift (samples) at the lag chosen below which it is said not to have moved
STILL_SHIFT_PX = 1.0

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
        Frames between the two of a pair, the shortest (0: not measured); the pairs' lags run from it to a few
        frames more (dithered: see the module's notes).
    lag : ndarray of int
        Each window's lag.
    mean_m_s : float or None
        Mean over the record's time (the windows of each pair averaged, then the pairs, the record's ends
        included); None when the texture is too weak.
    ci95_m_s : tuple of float or None
        Its 95 % interval (batch means over independent blocks of time).
    warnings : tuple of str
        Coded warnings (``grains.texture_weak``: no velocity; ``grains.texture_still``: the texture did not
        move by a sample over the longest lag).
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
    lag: np.ndarray | None = None

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
    owner = np.full(shape, -1, np.int32)
    for r, (k, a, b) in enumerate(zip(frame, start, stop, strict=True)):
        owner[int(k), int(a):int(b)] = r
    return owner


def _erode_rows(mask: np.ndarray, n: int) -> np.ndarray:
    """Every row of ``mask`` (2D bool) shrunk by ``n`` samples at every end of its runs."""
    if n <= 0:
        return mask
    m = mask.shape[1]
    c = np.concatenate([np.zeros((mask.shape[0], 1), np.int64), np.cumsum(~mask, axis=1)], axis=1)
    out = np.zeros(mask.shape, bool)
    if m >= 2 * n + 1:
        i = np.arange(n, m - n)
        out[:, i] = (c[:, i + n + 1] - c[:, i - n]) == 0
    return out


def _pairs(values: np.ndarray, owner: np.ndarray, starts: np.ndarray, lag: int | np.ndarray, half: int, search: int,
           margin: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Windows of frames ``starts`` against ``starts + lag`` (one lag, or one per start): frame, lag, centre, run,
    shift (samples), peak."""
    n_pos = values.shape[1]
    starts = np.asarray(starts, dtype=np.int64)
    lags = np.broadcast_to(np.asarray(lag, dtype=np.int64), starts.shape)
    step = 2 * half
    # valid centres: inside a plug in both frames, a window (and the search) from its ends; every frame at once
    ok = _erode_rows(owner[starts] >= 0, half + margin) & _erode_rows(owner[starts + lags] >= 0, half + search + margin)
    # centres a window apart along each stretch of valid centres, centred in it
    edges = np.diff(np.pad(ok, ((0, 0), (1, 1))).astype(np.int8), axis=1)
    row, lo = np.nonzero(edges == 1)
    _, hi = np.nonzero(edges == -1)  # row by row, in order: each stretch's end follows its start
    n = 1 + (hi - lo - 1) // step
    off = (hi - lo - 1 - (n - 1) * step) // 2
    which = np.repeat(np.arange(len(n)), n)
    within = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
    cen = lo[which] + off[which] + step * within
    fr, lg = starts[row[which]], lags[row[which]]
    if not len(fr):
        e = np.empty(0)
        return e.astype(int), e.astype(int), e.astype(int), e.astype(int), e, e
    fr_a, lg_a, cen_a = fr, lg, cen
    w = np.arange(-half, half)
    a = values[fr_a[:, None], np.clip(cen_a[:, None] + w, 0, n_pos - 1)].astype(np.float64)
    a = _detrend(a)
    shifts = np.arange(-search, search + 1)
    cc = _correlations(values, fr_a + lg_a, cen_a, a, half, search)
    best = np.argmax(cc, axis=1)
    peak = cc[np.arange(len(best)), best]
    inner = np.clip(best, 1, len(shifts) - 2)
    y0, y1, y2 = (cc[np.arange(len(best)), inner + d] for d in (-1, 0, 1))
    den = y0 - 2 * y1 + y2
    sub = np.where(den < 0, 0.5 * (y0 - y2) / np.where(den < 0, den, -1.0), 0.0)
    shift = shifts[inner] + np.clip(sub, -0.5, 0.5)
    edge = (best == 0) | (best == len(shifts) - 1)  # the peak at the search's end: not found
    peak = np.where(edge, 0.0, peak)
    return fr_a, lg_a, cen_a, owner[fr_a, cen_a], shift, peak


def _correlations(values: np.ndarray, frames: np.ndarray, centres: np.ndarray, a: np.ndarray, half: int,
                  search: int, chunk: int = 2048) -> np.ndarray:
    """Normalised correlation of each window ``a`` (detrended, unit norm) with frame ``frames`` around
    ``centres`` at every shift ``-search..search``: ``windows x shifts``.

    ``a`` is orthogonal to a constant and to a straight line, so its product with a window of the other
    frame is the same whether that window is detrended or not; only the detrended window's norm is needed,
    from running sums of ``b``, ``b^2`` and ``i b`` (one gather of the extended window, no loop over shifts).
    """
    n_pos = values.shape[1]
    width = 2 * half
    n_s = 2 * search + 1
    ext_i = np.arange(-half - search, half + search)
    t = np.arange(width) - (width - 1) / 2.0
    tt = float(t @ t)
    out = np.empty((len(frames), n_s))
    for lo in range(0, len(frames), chunk):
        sl = slice(lo, lo + chunk)
        b = values[frames[sl, None], np.clip(centres[sl, None] + ext_i, 0, n_pos - 1)].astype(np.float64)
        num = np.einsum("nsw,nw->ns", np.lib.stride_tricks.sliding_window_view(b, width, axis=1), a[sl])
        idx = np.arange(b.shape[1], dtype=np.float64)
        zero = np.zeros((b.shape[0], 1))
        c1 = np.concatenate([zero, np.cumsum(b, axis=1)], axis=1)
        c2 = np.concatenate([zero, np.cumsum(b * b, axis=1)], axis=1)
        ci = np.concatenate([zero, np.cumsum(b * idx, axis=1)], axis=1)
        start = np.arange(n_s)
        s1 = c1[:, start + width] - c1[:, start]
        s2 = c2[:, start + width] - c2[:, start]
        sj = ci[:, start + width] - ci[:, start] - start * s1  # sum of j b_(start + j)
        st = sj - (width - 1) / 2.0 * s1
        var = s2 - s1 * s1 / width - st * st / tt
        out[sl] = np.where(var > 1e-12 * np.maximum(s2, 1e-300), num / np.sqrt(np.maximum(var, 1e-300)), 0.0)
    return out


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
                   min_windows: int = 40, max_pairs: int = 4000, max_windows: int = 8000,
                   n_blocks: int = 10) -> GrainVelocity:
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
    max_windows : int, optional
        About the most windows correlated (the pairs thinned, evenly over the record, to keep the cost of a
        long record bounded).
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
        probe = np.unique(np.linspace(0, t_n - lag - 1, min(PROBE_PAIRS, t_n - lag)).round().astype(int))
        _, _, _, _, shift, peak = _pairs(values, owner, probe, lag, half, search, margin)
        good = peak >= min_peak
        if good.sum() < max(10, min_windows // 4) or np.median(peak) < min_peak:
            log.debug("lag %d: %d windows, stopped", lag, good.sum())
            break
        if np.mean(peak == 0.0) > 0.05:  # the shift outran the search range: the last lag is the longest
            break
        v_px = float(np.quantile(np.abs(shift[good]), 0.95)) / lag
        chosen = (lag, search, float(np.median(np.abs(shift[good]))) / lag, len(shift) / len(probe))
        if np.median(np.abs(shift[good])) >= target_shift_px:
            break
    if chosen is None:
        return _weak(empty, "the plugs' texture does not correlate from frame to frame")
    lag, search, v_typ, per_pair = chosen
    # the lags dithered (lag, lag + 1, ... until the typical shift has gone one sample further): a shift's
    # sub-sample part then takes every value, and the parabola's pull towards whole samples averages out
    n_dither = int(min(lag, max(1, np.ceil(1.0 / max(v_typ, 1e-6)))))
    n_dither = max(1, min(n_dither, t_n - lag - 2))
    search += int(np.ceil(1.5 * v_typ * (n_dither - 1)))
    n_pairs = min(max_pairs, t_n - lag - n_dither + 1, max(n_blocks * 8, int(np.ceil(max_windows / per_pair))))
    starts = np.unique(np.linspace(0, t_n - lag - n_dither, n_pairs).round().astype(int))
    lags = lag + np.arange(len(starts)) % n_dither
    fr, lg, cen, run, shift, peak = _pairs(values, owner, starts, lags, half, search, margin)
    keep = peak >= min_peak
    fr, lg, cen, run, shift, peak = fr[keep], lg[keep], cen[keep], run[keep], shift[keep], peak[keep]
    time_s = np.asarray(time_s)
    span = time_s[fr + lg] - time_s[fr]
    span = np.where(span > 0, span, lg * dt)
    vel = shift * spacing_mm / span / 1000.0
    t_mid = 0.5 * (time_s[fr] + time_s[fr + lg])
    out = GrainVelocity(fr, t_mid, np.asarray(position_mm)[cen], run, vel, peak, lag, None, None, lag=lg)
    if len(vel) < min_windows:
        return _weak(out, f"only {len(vel)} windows of the plugs' texture correlate")
    frames, per_frame = _per_frame(fr, vel)
    _, t_pair = _per_frame(fr, t_mid)
    mean = _record_mean(t_pair, per_frame, float(time_s[0]), float(time_s[-1]))
    # type B: what the dithering leaves of the parabola's pull, in samples over the pairs' mean span
    floor = SUBSAMPLE_BIAS * spacing_mm / float(np.mean(span)) / 1000.0
    ci = _batch_interval(frames, per_frame, t_n, lag, n_blocks, floor, mean)
    still = v_typ * lag < STILL_SHIFT_PX  # the longest lag came before the texture moved a sample
    if ci is None:  # a number without its interval is not given
        return _weak(out, f"the record is too short for an interval at a lag of {lag} frames (fewer than four "
                          "blocks of four lags)" + ("; the texture did not move by a sample over that lag (grains "
                                                    "at rest, or a pattern fixed to the tube or camera)"
                                                    if still else ""))
    warnings: tuple[str, ...] = ()
    if still:
        warnings = (coded("grains.texture_still", "the plugs' texture did not move by a sample over the longest "
                          f"lag ({lag} frames): the grains are at rest, or what correlates is fixed to the tube or "
                          "the camera (a scratch, dust, a codec's blocks); the grains' velocity given "
                          f"({mean * 1000:.3g} mm/s) may be that of the fixed pattern"),)
    return GrainVelocity(fr, t_mid, out.position_mm, run, vel, peak, lag, mean, ci, warnings, lag=lg)


def _record_mean(t: np.ndarray, v: np.ndarray, t0: float, t1: float) -> float:
    """The mean over the record ``[t0, t1]`` of the velocity series ``v(t)`` (one value per pair, at its
    middle): the series' mean stands for the time its pairs' middles span; the half lag at each end that no
    pair's middle reaches takes the series' mean over as long again at that end. A plain mean would leave
    those ends out, which, for grains moving with oscillating plugs, is up to the oscillation's speed times
    a lag over the record."""
    lo, hi = float(np.min(t)), float(np.max(t))
    if len(v) == 1 or t1 <= t0 or hi <= lo:
        return float(np.mean(v))
    head_s, tail_s = max(lo - t0, 0.0), max(t1 - hi, 0.0)
    head = float(np.mean(v[t <= lo + head_s]))
    tail = float(np.mean(v[t >= hi - tail_s]))
    return (float(np.mean(v)) * (hi - lo) + head * head_s + tail * tail_s) / (hi - lo + head_s + tail_s)


def _per_frame(fr: np.ndarray, vel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The mean of ``vel`` (a velocity, a time) over each pair's windows: a time series, each time weighted
    once whatever the number of plugs then (oscillating plugs carry more of the tube at some phases)."""
    frames, inv = np.unique(fr, return_inverse=True)
    return frames, np.bincount(inv, weights=vel) / np.bincount(inv)


def _batch_interval(fr: np.ndarray, vel: np.ndarray, t_n: int, lag: int, n_blocks: int,
                    floor: float, centre: float | None = None) -> tuple[float, float] | None:
    """95 % interval of the mean from batch means over blocks of time at least four lags long, with a
    systematic ``floor`` (a standard uncertainty) added in quadrature."""
    n_b = int(min(n_blocks, t_n // max(4 * lag, 1)))
    if n_b < 4:
        return None
    edges = np.linspace(0, t_n, n_b + 1)
    blk = np.clip(np.searchsorted(edges, fr, "right") - 1, 0, n_b - 1)
    means = np.array([vel[blk == b].mean() for b in range(n_b) if np.any(blk == b)])
    if len(means) < 4:
        return None
    centre = float(np.mean(vel)) if centre is None else centre
    half = float(t_quantile_975(len(means) - 1) * means.std(ddof=1) / np.sqrt(len(means)))
    half = float(np.hypot(half, 1.96 * floor))
    return centre - half, centre + half


def _weak(gv: GrainVelocity, why: str) -> GrainVelocity:
    """``gv`` without a velocity, with the warning that says why."""
    w = coded("grains.texture_weak", f"the grains' velocity inside the plugs is not given: {why} "
              "(too little texture, or plugs too short or too few); light the grains so that they show")
    return GrainVelocity(gv.frame, gv.time_s, gv.position_mm, gv.run, gv.velocity_m_s, gv.peak, gv.lag_frames,
                         None, None, (w,), lag=gv.lag)
