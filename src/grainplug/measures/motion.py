"""Motion of the plug train: celerity, oscillation frequency and amplitude, regime.

Notes
-----
*Celerity.* Every upper plug edge of every track enters one least-squares fit,

.. math:: s_{i,k} = c\\,t_k + o_i + \\sum_{h=1}^{H} [a_h \\cos(2\\pi h f t_k) + b_h \\sin(2\\pi h f t_k)]

with one offset ``o_i`` per track (Tukey-biweighted, so that a plug that
does not follow the common motion, or a false edge, loses its weight) and, in the oscillating regime, a periodic
part of fundamental frequency ``f`` and ``H`` harmonics (the sinusoid of the
paper's low-amplitude waves, or the sawtooth-like steps of stick-slip). ``c`` is
the mean (drift) celerity of the paper's Tables 1 and 2: the slope of the upper
positions, estimated from the whole diagram at once rather than plug by plug,
and unbiased by an oscillation that does not hold a whole number of periods.
The upper edge is used, as in the paper, because grains leaving a plug's lower
edge in free fall blur it.

*Oscillation.* The displacement of the train ``X(t)`` is the per-frame mean of
the edges' residuals from the drift fit. Its periodogram (Hann window,
zero-padded) gives a candidate peak; the frequency is then refined by
least squares on the full model, and the lowest candidate ``f_peak / m`` whose
harmonic model explains nearly as well as the best is kept as the fundamental,
so that a stick-slip motion is not reported at its second harmonic.

*Regime.* Oscillating when the periodic part explains at least half of the
variance of ``X(t)`` about the drift, its amplitude (half peak-to-peak) is above
``max(0.1 mm, 0.5 px)`` and the record holds at least 1.5 periods; static when,
at every celerity of the 95% interval, the plugs would have moved by less than a
pixel over the record (a jammed tube, or a scene where nothing flows); otherwise
propagative. A periodic part that repeats every whole number of frames, up to
:data:`FRAME_LOCKED_FRAMES` (``f = h fps / P``), is not looked for: the plugs do not know the camera's
frame clock, the recording does (a compressed movie's group of pictures holds the edges still in its
predicted frames and moves them at its reference frames: a staircase of period ``P`` frames; alternate
exposures; a lamp's ripple locked to the frame rate, 100 Hz at 250 fps repeating every 5 frames). When
it stands above the oscillation's amplitude threshold it is reported apart (``frame_locked_hz``).

*Confidence interval.* From the drift fit of ``X(t)``, with the standard error
inflated for the residuals' lag-one autocorrelation ``rho`` by
``sqrt((1 + rho) / (1 - rho))``, and the scale's relative uncertainty added in
quadrature.

*The oscillation's figures* (:func:`oscillation_detail`). ``X(t)`` again, each track's offset now from the full
fit with up to :data:`SHAPE_HARMONICS` harmonics; a Gauss-Newton fit of drift and harmonics with the frequency
free refines the frequency. The amplitude is half the peak-to-peak of the period-averaged motion (the fitted
shape over one period), not the spectrum's peak (the fundamental's alone). Their 95 % intervals: the fit's
sandwich covariance with a Newey-West long-run variance of the scores (Bartlett kernel, Andrews' AR(1)
bandwidth) and Kiefer and Vogelsang's fixed-b quantile; plus what holds over whole periods (an edge's error
that depends on where it stands times each period, and each extreme, once), the shape's truncation, the scale,
and, on the amplitude's upper end, what an exposure of up to a frame takes from the swing. Calibrated on
``benchmarks/oscillation_intervals.py`` (docs/accuracy.md). The kind is stick-slip when the train's speed is
below :data:`STILL_SPEED_SHARE` of its peak over at least :data:`STICK_SLIP_SHARE` of the period.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

log = logging.getLogger(__name__)

N_HARMONICS = 3
#: a periodic part of the plugs' motion that repeats every this many frames or fewer is the recording's
FRAME_LOCKED_FRAMES = 8


def frame_locked_hz(fps: float, f_max: float) -> tuple[float, ...]:
    """The frequencies up to ``f_max`` of a pattern that repeats every ``P <= FRAME_LOCKED_FRAMES`` frames:
    ``h fps / P`` (the recording's cadence, not the plugs')."""
    out = {round(h * fps / p, 9) for p in range(2, FRAME_LOCKED_FRAMES + 1) for h in range(1, p)
           if h * fps / p <= f_max}
    return tuple(sorted(out))


@dataclass(frozen=True)
class Motion:
    """What the edges tell about the motion of the plugs.

    Attributes
    ----------
    celerity_m_s : float
        Mean celerity, positive downstream.
    celerity_ci95_m_s : tuple of float
        95% confidence interval.
    regime : str
        ``"propagative"``, ``"oscillating"`` or ``"static"`` (no motion of a pixel over the record).
    oscillation_frequency_hz : float or None
        Fundamental frequency of the oscillation (None when propagative).
    oscillation_amplitude_mm : float
        Half the peak-to-peak of the period-averaged motion about the drift (:class:`Oscillation`; when its
        frequency could not be refined, of the celerity fit's periodic part); 0 when not oscillating.
    explained_fraction : float
        Share of the variance of ``X(t)`` about the drift that the periodic part explains.
    spectrum_hz, spectrum_mm : ndarray
        Amplitude spectrum of ``X(t)`` about the drift.
    time_s, displacement_mm : ndarray
        The train's displacement ``X(t)`` (NaN where no edge was seen).
    n_edges, n_tracks_used : int
        Observations and tracks in the fit.
    celerity_se_tracks_m_s : float
        The celerity's standard error from the tracks' scatter alone (the interval adds the scale's,
        ``|celerity| * scale_rel_sd``, and the camera's, in quadrature).
    celerity_se_camera_m_s : float
        Its standard error from a motion of the view along the tube that could not be measured (``wander_mm``).
    frame_locked_hz : float or None
        Frequency of a periodic part that repeats every few whole frames (the recording's cadence, see the
        module's notes), strong enough to have been taken for an oscillation; not reported as one.
    frame_locked_mm : float
        Its amplitude (0 without one).
    oscillation : Oscillation or None
        The oscillation's intervals, kind and stick fraction (None when not oscillating, or when its frequency
        could not be refined).
    periodic_coef_mm : ndarray
        Coefficients ``a_1, b_1, a_2, b_2 ...`` of the periodic part of the celerity's fit (empty when not
        oscillating); :meth:`periodic_mm` evaluates it.
    """

    celerity_m_s: float
    celerity_ci95_m_s: tuple[float, float]
    regime: str
    oscillation_frequency_hz: float | None
    oscillation_amplitude_mm: float
    explained_fraction: float
    spectrum_hz: np.ndarray = field(repr=False)  # arrays out of the repr: a print shows the numbers, not 10^4 values
    spectrum_mm: np.ndarray = field(repr=False)
    time_s: np.ndarray = field(repr=False)
    displacement_mm: np.ndarray = field(repr=False)
    n_edges: int
    n_tracks_used: int
    celerity_se_tracks_m_s: float = float("nan")
    celerity_se_camera_m_s: float = 0.0
    frame_locked_hz: float | None = None
    frame_locked_mm: float = 0.0
    oscillation: Oscillation | None = None
    periodic_coef_mm: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)

    def periodic_mm(self, t_s: np.ndarray) -> np.ndarray:
        """The periodic part of the celerity's fit at times ``t_s`` (the motion every plug shares about the drift;
        zeros when not oscillating): a plug's edge less this is its straight line."""
        t = np.asarray(t_s, dtype=float)
        f = self.oscillation_frequency_hz
        if not f or not len(self.periodic_coef_mm):
            return np.zeros_like(t)
        n_harm = len(self.periodic_coef_mm) // 2
        return _harmonic_columns(t, f, n_harm) @ self.periodic_coef_mm


def _drift_and_harmonics(t: np.ndarray, f: float | None, n_harm: int) -> np.ndarray:
    """Columns ``t, cos(2 pi h f t), sin(2 pi h f t)`` for ``h = 1 .. n_harm`` (``t`` alone without ``f``)."""
    cols = [t]
    if f:
        for h in range(1, n_harm + 1):
            ph = 2 * np.pi * h * f * t
            cols += [np.cos(ph), np.sin(ph)]
    return np.stack(cols, axis=1)


def edge_design(t: np.ndarray, track_idx: np.ndarray, n_tracks: int, f: float | None,
            n_harm: int) -> np.ndarray:
    """The full design: drift, one offset per track, harmonics (what ``fit_edges`` solves)."""
    onehot = np.zeros((len(t), n_tracks))
    onehot[np.arange(len(t)), track_idx] = 1.0
    B = _drift_and_harmonics(t, f, n_harm)
    return np.hstack([B[:, :1], onehot, B[:, 1:]])


class _TrackFit:
    """(Weighted) least squares of ``edge_design`` on fixed edges, for any frequency.

    Solved without forming the one-hot block: the track offsets are projected out
    by weighted within-track centring (Frisch-Waugh-Lovell), which leaves a small
    least-squares problem in the drift and the harmonics; the offsets follow as the
    weighted track means of what the rest leaves. Same solution as the full
    design, at a cost linear in the number of edges (a track whose weights are all
    zero gets offset 0, as the minimum-norm solution of the full design would).

    What does not depend on the frequency (the centred drift column and data, the
    track sums) is computed once, so a scan over frequencies pays only for the
    harmonics, which are evaluated once per distinct time (edges of the same frame
    share it) by powers of ``exp(2 pi i f t)``.
    """

    def __init__(self, t: np.ndarray, y: np.ndarray, tix: np.ndarray, n_tracks: int,
                 weights: np.ndarray | None = None) -> None:
        self.t, self.y, self.tix, self.n_tracks = t, y, tix, n_tracks
        self.w = np.ones_like(y) if weights is None else weights
        wsum = np.bincount(tix, weights=self.w, minlength=n_tracks)
        self.inv = np.divide(1.0, wsum, out=np.zeros(n_tracks), where=wsum > 0)
        self.sw = np.sqrt(self.w)
        self.times, self.at_time = np.unique(t, return_inverse=True)
        tc, yc = self._centred(np.stack([t, y], axis=1)).T
        self.tc_w, self.yc_w = tc * self.sw, yc * self.sw

    def _centred(self, x: np.ndarray) -> np.ndarray:
        """``x`` (edges x k) minus its weighted mean over each track, all columns at once."""
        k = x.shape[1]
        cell = (self.tix[:, None] * k + np.arange(k)).ravel()
        sums = np.bincount(cell, weights=(self.w[:, None] * x).ravel(), minlength=self.n_tracks * k)
        return x - (sums.reshape(self.n_tracks, k) * self.inv[:, None])[self.tix]

    def harmonics(self, f: float, n_harm: int) -> np.ndarray:
        """Columns ``cos(2 pi h f t), sin(2 pi h f t)``, ``h = 1 .. n_harm``, of every edge."""
        z = np.exp(2j * np.pi * f * self.times)
        zh = np.cumprod(np.broadcast_to(z[:, None], (len(z), n_harm)), axis=1)
        cols = np.stack([zh.real, zh.imag], axis=2).reshape(len(z), 2 * n_harm)
        return cols[self.at_time]

    def solve(self, f: float | None, n_harm: int) -> tuple[np.ndarray, float, np.ndarray]:
        """Coefficients (drift, track offsets, harmonics), residual sum of squares, residuals."""
        if f and n_harm > 0:
            h = self.harmonics(f, n_harm)
            a = np.column_stack([self.tc_w, self._centred(h) * self.sw[:, None]])
            beta = _least_squares(a, self.yc_w)
            rest = self.y - beta[0] * self.t - h @ beta[1:]
        else:
            beta, *_ = np.linalg.lstsq(self.tc_w[:, None], self.yc_w, rcond=None)
            rest = self.y - beta[0] * self.t
        offsets = np.bincount(self.tix, weights=self.w * rest, minlength=self.n_tracks) * self.inv
        res = rest - offsets[self.tix]
        coef = np.concatenate(([beta[0]], offsets, beta[1:]))
        return coef, float(self.w @ (res * res)), res


def _least_squares(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``argmin |a x - b|`` for a tall, thin ``a``: by the normal equations when they are
    well conditioned (drift and harmonic columns are: a few times faster than an SVD
    of ``a``), else by ``lstsq`` (minimum-norm, for a rank-deficient design)."""
    g = a.T @ a
    if np.linalg.cond(g) < 1e8:
        return np.linalg.solve(g, a.T @ b)
    return np.linalg.lstsq(a, b, rcond=None)[0]


def fit_edges(t: np.ndarray, y: np.ndarray, tix: np.ndarray, n_tracks: int, f: float | None,
             n_harm: int, weights: np.ndarray | None = None) -> tuple[np.ndarray, float, np.ndarray]:
    """(Weighted) least squares of ``edge_design``: coefficients, residual sum of squares, residuals
    (see :class:`_TrackFit`)."""
    return _TrackFit(t, y, tix, n_tracks, weights).solve(f, n_harm)


def _robust_weights(t: np.ndarray, y: np.ndarray, tix: np.ndarray, n_tracks: int,
                    n_iter: int = 6) -> np.ndarray:
    """Tukey biweights of the drift fit: edges that do not follow the common motion
    (a plug sliding alone, a misdetection) lose their weight."""
    w = np.ones_like(y)
    for _ in range(n_iter):
        _, _, res = fit_edges(t, y, tix, n_tracks, None, 0, w)
        scale = 1.4826 * np.median(np.abs(res - np.median(res))) + 1e-9
        u = res / (6.0 * max(scale, 0.05))  # never tighter than 0.3 mm: oscillations stay in
        w = np.where(np.abs(u) < 1, (1 - u * u) ** 2, 0.0)
        if w.sum() < 0.3 * len(w):
            return np.ones_like(y)
    return w


def _harmonics_for(f: float, fps: float) -> int:
    return max(1, min(N_HARMONICS, int((0.45 * fps) // max(f, 1e-9))))


def _periodic_part(coef: np.ndarray, n_tracks: int, f: float, n_harm: int, t: np.ndarray) -> np.ndarray:
    out = np.zeros_like(t)
    base = 1 + n_tracks
    for h in range(1, n_harm + 1):
        a, b = coef[base + 2 * (h - 1)], coef[base + 2 * (h - 1) + 1]
        out += a * np.cos(2 * np.pi * h * f * t) + b * np.sin(2 * np.pi * h * f * t)
    return out


def _without_frequencies(x: np.ndarray, t: np.ndarray, freqs: tuple[float, ...], *,
                         lowest_hz: float) -> np.ndarray:
    """``x`` less its least-squares sinusoids at ``freqs`` (those at or above ``lowest_hz``: a slower one is
    not told from the drift), fitted together with a straight line that is kept."""
    fs = [float(f) for f in freqs if f >= lowest_hz]
    if not fs or len(x) < 2 * len(fs) + 4:
        return x
    cols = [np.ones_like(t), t - t.mean()]
    for f in fs:
        cols += [np.cos(2 * np.pi * f * t), np.sin(2 * np.pi * f * t)]
    A = np.stack(cols, axis=1)
    coef, *_ = np.linalg.lstsq(A, x, rcond=None)
    return x - A[:, 2:] @ coef[2:]


def _spectrum(x: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """One-sided amplitude spectrum (mm) of an evenly sampled series, Hann window, zero-padded."""
    n = len(x)
    win = np.hanning(n)
    nfft = int(2 ** np.ceil(np.log2(max(8 * n, 64))))
    spec = np.abs(np.fft.rfft((x - x.mean()) * win, nfft)) * 2 / win.sum()
    return np.fft.rfftfreq(nfft, 1 / fps), spec


#: why a result with plugs has no celerity
NO_FOLLOWED_EDGE = ("plugs were seen, but no upper edge was followed over 3 frames or more: the celerity is "
                    "measured from the upper edges, so none is given (tracks.csv gives each track's own, from "
                    "the edge it has)")


def measure_motion(time_s: np.ndarray, top_mm: np.ndarray, track: np.ndarray, frame: np.ndarray,
                   *, fps: float, mm_per_px: float, scale_rel_sd: float = 0.0,
                   min_track_edges: int = 3, not_hz: tuple[float, ...] = (),
                   frame_cadence: bool = False, wander_mm: float = 0.0) -> Motion | None:
    """Celerity, oscillation and regime from the upper edges of all plug tracks.

    Parameters
    ----------
    time_s : ndarray
        Time of every frame.
    top_mm, track, frame : ndarray
        Upper edge, track id and frame index of every run (NaN edges are ignored).
    fps : float
        Frame rate (for the spectrum).
    mm_per_px : float
        Scale (for the amplitude threshold).
    scale_rel_sd : float
        Relative standard uncertainty of the scale, added to the interval.
    not_hz : tuple of float
        Frequencies that are not the plugs' (the camera's shake, :mod:`grainplug.measures.shake`): an
        oscillation is not looked for within ``max(0.3 Hz, 2 bins)`` of them.
    frame_cadence : bool
        The recording may move the edges at a cadence of a few frames (a lossy codec that predicts frames
        from others): a periodic part that repeats every :data:`FRAME_LOCKED_FRAMES` frames or fewer is then not
        looked for (and is reported in ``frame_locked_hz`` when strong); otherwise an oscillation found at such a
        frequency is reported, and named in ``frame_locked_hz`` too.

    Returns
    -------
    Motion or None
        None when fewer than two usable edge observations exist.
    """
    from .._filters import t_quantile_975
    ok = np.isfinite(top_mm)
    tr = track[ok]
    counts = np.bincount(tr) if tr.size else np.zeros(0, int)
    ok &= np.isin(track, np.nonzero(counts >= min_track_edges)[0]) if counts.size else ok
    if ok.sum() < 3:
        return None
    y = top_mm[ok]
    fr = frame[ok]
    t = time_s[fr]
    ids, tix = np.unique(track[ok], return_inverse=True)
    n_tr = len(ids)
    if np.ptp(t) <= 0:
        return None
    weights = _robust_weights(t, y, tix, n_tr)
    fitter = _TrackFit(t, y, tix, n_tr, weights)  # the drift, then the same edges at every frequency
    coef, _, _ = fitter.solve(None, 0)
    # the train's displacement about the drift: mean residual per frame (outliers left out)
    res = y - (coef[0] * t + coef[1 + tix])
    keep = weights > 0
    res, fr_k = res[keep], fr[keep]
    n_frames = len(time_s)
    sums = np.bincount(fr_k, weights=res, minlength=n_frames)
    cnt = np.bincount(fr_k, minlength=n_frames)
    X = np.full(n_frames, np.nan)
    X[cnt > 0] = sums[cnt > 0] / cnt[cnt > 0]
    valid = np.isfinite(X)
    idx = np.arange(n_frames)
    Xf = np.interp(idx, idx[valid], X[valid]) if valid.sum() >= 2 else np.zeros(n_frames)
    first, last = idx[valid][0], idx[valid][-1]
    seg = Xf[first: last + 1]
    duration = (last - first) / fps
    freqs, spec = _spectrum(seg, fps)
    regime, f_osc, amp, explained = "propagative", None, 0.0, 0.0
    osc: Oscillation | None = None
    n_harm_osc = 0
    f_lo = max(1.5 / max(duration, 1e-9), 0.3)
    band = (freqs >= f_lo) & (freqs <= 0.45 * fps)
    tol = max(0.3, 2.0 * (freqs[1] - freqs[0]) if len(freqs) > 1 else 0.3)
    for f_no in not_hz:  # the camera's frequency is not the plugs'
        band &= np.abs(freqs - f_no) > tol
    locked_hz = frame_locked_hz(fps, 0.45 * fps) if frame_cadence else ()
    locked = np.zeros_like(band)
    for f_l in locked_hz:  # nor is the recording's cadence
        locked |= band & (np.abs(freqs - f_l) <= tol)
    threshold = max(0.1, 0.5 * mm_per_px)
    locked_f, locked_mm = None, 0.0
    if locked.any() and float(spec[locked].max()) >= threshold and spec[locked].max() >= spec[band].max():
        i = int(np.argmax(np.where(locked, spec, -np.inf)))
        locked_f, locked_mm = float(freqs[i]), float(spec[i])
    band &= ~locked
    var_x = float(np.var(seg))
    if band.any() and var_x > 0:
        f_peak = float(freqs[band][np.argmax(spec[band])])
        step = freqs[1] - freqs[0]
        # best frequency near f_peak / m for m = 1, 2, 3; a sub-harmonic is kept only
        # when it explains clearly more (the peak was a harmonic of the true fundamental)
        best = None
        for m in (1, 2, 3):
            f0 = f_peak / m
            if f0 < f_lo:
                continue
            nh = max(m, _harmonics_for(f0, fps))

            def scan(grid: np.ndarray, cand: tuple | None, m: int = m, nh: int = nh) -> tuple:
                for f in grid:
                    c_f, rss, _ = fitter.solve(float(f), nh)
                    if cand is None or rss < cand[2]:
                        cand = (float(f), c_f, rss, m, nh)
                return cand

            # a grid of 13 over +-1.5 bins, then 11 around the best: the resolution of 61 in one grid
            width = 1.5 * step / m
            cand = scan(np.linspace(f0 - width, f0 + width, 13), None)
            cand = scan(np.linspace(cand[0] - width / 6, cand[0] + width / 6, 11), cand)
            if best is None or (cand[2] < 0.8 * best[2] and _own_share(cand[1][1 + n_tr:], m) >= SUBHARMONIC_SHARE):
                best = cand
        if best is not None:
            f_best, c_best, _, _, nh = best
            tt = np.linspace(0, 1 / f_best, 400, endpoint=False)
            per = _periodic_part(c_best, n_tr, f_best, nh, tt)
            amp_fit = 0.5 * float(np.ptp(per))
            per_frames = _periodic_part(c_best, n_tr, f_best, nh, time_s[first: last + 1])
            resid = seg - (per_frames - per_frames.mean()) - np.polyval(
                np.polyfit(time_s[first: last + 1], seg - per_frames, 1), time_s[first: last + 1])
            explained = float(1 - np.var(resid) / var_x)
            camera = any(abs(f_best * h - f_no) <= tol for f_no in not_hz for h in (1, 2, 3)) or \
                any(abs(f_best - f_l) <= tol for f_l in locked_hz)
            if explained >= 0.5 and amp_fit >= threshold and f_best * duration >= 1.5 and not camera:
                regime, f_osc, amp = "oscillating", f_best, amp_fit
                coef = c_best
                # the train's motion with each track's offset from the full fit with the shape's harmonics (the
                # drift-only offsets of a track seen over part of a period take in part of the swing, and a
                # three-harmonic fit's offsets part of a stick-slip's sharper shape), its frequency refined, the
                # intervals
                n_shape = max(nh, min(SHAPE_HARMONICS, int((0.45 * fps) // f_best)))
                c_shape = fitter.solve(f_best, n_shape)[0] if n_shape > nh else coef
                x_tr = np.bincount(fr_k, weights=(y - c_shape[1 + tix])[keep], minlength=n_frames)
                seen = cnt > 0
                osc = oscillation_detail(time_s[seen], x_tr[seen] / cnt[seen], f_best, fps=fps,
                                         scale_rel_sd=scale_rel_sd, not_hz=not_hz)
                if abs(osc.frequency_hz - f_best) <= step:  # within a bin of the spectrum: the same peak
                    f_osc, amp = osc.frequency_hz, osc.amplitude_mm
                    coef = fitter.solve(f_osc, nh)[0]
                else:
                    log.debug("the refined frequency %.4g Hz left the peak at %.4g Hz: no interval", osc.frequency_hz,
                              f_best)
                    osc = None
                n_harm_osc = nh
                if any(abs(f_best - f_l) <= tol for f_l in frame_locked_hz(fps, 0.45 * fps)):
                    locked_f, locked_mm = f_osc, amp  # reported, and said to repeat every few frames
    celerity = float(coef[0]) / 1000.0  # mm/s -> m/s
    # interval from the drift fit of X(t) + drift, inflated for autocorrelation
    tt = time_s[first: last + 1]
    drift_series = seg + coef[0] * tt
    if regime == "oscillating":
        drift_series = drift_series - _periodic_part(coef, n_tr, f_osc, n_harm_osc, tt)
    # the camera's motion (its frequencies, measured on the tube's walls) is not the plugs' scatter about the drift
    drift_series = _without_frequencies(drift_series, tt, not_hz, lowest_hz=f_lo)
    xm = float(tt.mean())
    sxx = float(((tt - xm) ** 2).sum())
    slope = float(((tt - xm) * (drift_series - drift_series.mean())).sum() / sxx)
    intercept = float(drift_series.mean() - slope * xm)
    r = drift_series - (slope * tt + intercept)
    se = float(np.sqrt((r @ r) / max(len(tt) - 2, 1) / sxx))
    rho = float(np.corrcoef(r[:-1], r[1:])[0, 1]) if len(r) > 3 and np.std(r) > 0 else 0.0
    rho = float(np.clip(np.nan_to_num(rho), 0.0, 0.98))
    se_tracks = float(se * np.sqrt((1 + rho) / (1 - rho)) / 1000.0)
    # a motion of the view along the tube that could not be measured (the camera's wander, rms ``wander_mm``) moves
    # every edge alike: the drift takes up its trend over the record, at most that of a ramp of that rms
    se_camera = float(np.sqrt(12.0) * max(wander_mm, 0.0) / max(duration, 1e-9) / 1000.0)
    se_c = float(np.sqrt(se_tracks**2 + (abs(celerity) * scale_rel_sd) ** 2 + se_camera**2))
    tq = t_quantile_975(max(len(tt) - 2, 1))
    ci = (celerity - tq * se_c, celerity + tq * se_c)
    # static: no celerity of the interval (the camera's unmeasured wander left out) moves the plugs over the record
    # by more than a pixel and what that wander could make of still plugs
    se_seen = float(np.hypot(se_tracks, abs(celerity) * scale_rel_sd))
    reach = max(abs(celerity - tq * se_seen), abs(celerity + tq * se_seen)) * 1000.0 * duration
    if regime == "propagative" and reach < mm_per_px + np.sqrt(12.0) * max(wander_mm, 0.0):
        regime = "static"
    return Motion(
        celerity_m_s=celerity, celerity_ci95_m_s=ci, regime=regime,
        oscillation_frequency_hz=f_osc, oscillation_amplitude_mm=amp,
        explained_fraction=explained, spectrum_hz=freqs, spectrum_mm=spec,
        time_s=np.asarray(time_s), displacement_mm=X + coef[0] * np.asarray(time_s),
        n_edges=int(ok.sum()), n_tracks_used=n_tr, celerity_se_tracks_m_s=se_tracks,
        celerity_se_camera_m_s=se_camera, frame_locked_hz=locked_f,
        frame_locked_mm=locked_mm, oscillation=osc,
        periodic_coef_mm=np.asarray(coef[1 + n_tr:], dtype=float) if regime == "oscillating" else np.zeros(0),
    )


# ---- the oscillation's intervals, amplitude and kind ---------------------------------------------------------------

#: harmonics of the period-averaged motion (its shape: enough for a stick-slip staircase, whose slips are smooth)
SHAPE_HARMONICS = 16
#: a phase of the period is still when the train's speed there is below this share of its peak speed
STILL_SPEED_SHARE = 0.05
#: a motion still for at least this share of its period is stick-slip (a sinusoid is, at most, 14 %: when its
#: swing's speed just matches the drift's, ``|c + A w cos(phi)| < 0.05 (|c| + A w)`` over 14 % of the period)
STICK_SLIP_SHARE = 0.2


@dataclass(frozen=True)
class Oscillation:
    """The oscillation of the train, from the period-averaged motion of its plugs (see the module's notes).

    Attributes
    ----------
    frequency_hz : float
        Fundamental frequency.
    frequency_ci95_hz : tuple of float
        Its 95 % interval.
    amplitude_mm : float
        Half the peak-to-peak of the period-averaged motion about the drift.
    amplitude_ci95_mm : tuple of float
        Its 95 % interval (the scale's uncertainty included).
    kind : str
        ``"sinusoidal"`` or ``"stick-slip"`` (still for at least :data:`STICK_SLIP_SHARE` of the period).
    stick_fraction : float
        Share of the period in which the train's speed is below :data:`STILL_SPEED_SHARE` of its peak.
    n_periods : float
        Periods in the record.
    phase : ndarray
        ``0 .. 1`` over one period.
    shape_mm : ndarray
        The period-averaged motion about the drift at those phases.
    """

    frequency_hz: float
    frequency_ci95_hz: tuple[float, float]
    amplitude_mm: float
    amplitude_ci95_mm: tuple[float, float]
    kind: str
    stick_fraction: float
    n_periods: float
    phase: np.ndarray = field(repr=False, compare=False)
    shape_mm: np.ndarray = field(repr=False, compare=False)


def _fixed_b_quantile(b: float) -> float:
    """97.5 % quantile of a t-ratio studentised by a Bartlett-kernel long-run variance with bandwidth ``b`` times
    the sample (Kiefer & Vogelsang 2005, their cubic fit): wider than 1.96 when few independent stretches are left."""
    b = float(np.clip(b, 0.0, 1.0))
    return 1.96 + 2.9694 * b + 0.4160 * b * b - 0.5324 * b ** 3


#: a sub-harmonic ``f_peak / m`` is the fundamental only if its own harmonics (those not multiples of ``m``) reach this
#: share of the peak's amplitude: otherwise its extra terms only fit the record's slow wobbles (two periods of a
#: sub-harmonic in a short record) and the peak is the fundamental
SUBHARMONIC_SHARE = 0.25


def _own_share(harmonics: np.ndarray, m: int) -> float:
    """The amplitude of the harmonics of ``f_peak / m`` that are not multiples of ``m`` (rss of their cos and sin
    coefficients), over that of its ``m``-th harmonic (the peak's): ``harmonics`` as ``(cos_1, sin_1, cos_2, ...)``."""
    amp = np.hypot(harmonics[0::2], harmonics[1::2])
    if len(amp) < m or amp[m - 1] <= 0:
        return 0.0
    own = np.array([h % m != 0 for h in range(1, len(amp) + 1)])
    return float(np.sqrt(np.sum(amp[own] ** 2)) / amp[m - 1])


def _harmonic_columns(tc: np.ndarray, f: float, n_harm: int) -> np.ndarray:
    ph = 2 * np.pi * f * tc
    return np.stack([fn(h * ph) for h in range(1, n_harm + 1) for fn in (np.cos, np.sin)], axis=1)


def _sinusoid_fit(tc: np.ndarray, x: np.ndarray, f: float, n_harm: int, extra: np.ndarray,
                  *, n_iter: int = 8) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """Least squares of ``x = a + b tc + sum_h (alpha_h cos + beta_h sin)(2 pi h f tc) + extra @ gamma`` with ``f``
    free (Gauss-Newton from ``f``, the linear part solved exactly at each step): ``f``, the linear coefficients
    (``a, b``, the harmonics', ``gamma``), the Jacobian of every parameter (the frequency last) and the residuals."""
    span = float(np.ptp(tc)) or 1.0

    def linear(freq: float) -> tuple[np.ndarray, np.ndarray]:
        design = np.column_stack([np.ones_like(tc), tc, _harmonic_columns(tc, freq, n_harm), extra])
        return design, _least_squares(design, x)

    def jacobian(freq: float, design: np.ndarray, beta: np.ndarray) -> np.ndarray:
        ph = 2 * np.pi * freq * tc
        d_f = np.zeros_like(tc)
        for h in range(1, n_harm + 1):
            a, b = beta[2 * h], beta[2 * h + 1]
            d_f += 2 * np.pi * h * tc * (-a * np.sin(h * ph) + b * np.cos(h * ph))
        return np.column_stack([design, d_f])

    design, beta = linear(f)
    for _ in range(n_iter):
        jac = jacobian(f, design, beta)
        step = _least_squares(jac, x - design @ beta)[-1]
        step = float(np.clip(step, -0.25 / span, 0.25 / span))  # a quarter of a period over the record at most
        f_new = f + step
        d_new, b_new = linear(f_new)
        if np.sum((x - d_new @ b_new) ** 2) > np.sum((x - design @ beta) ** 2):
            break
        f, design, beta = f_new, d_new, b_new
        if abs(step) * span < 1e-6:
            break
    return f, beta, jacobian(f, design, beta), x - design @ beta


def _long_run_covariance(jac: np.ndarray, res: np.ndarray) -> tuple[np.ndarray, int]:
    """Sandwich covariance of least-squares estimates with serially correlated residuals: Newey-West (Bartlett
    kernel) with Andrews' (1991) AR(1) plug-in bandwidth; the covariance and the bandwidth (samples)."""
    n, p = jac.shape
    rho = float(np.corrcoef(res[:-1], res[1:])[0, 1]) if n > 3 and np.std(res) > 0 else 0.0
    rho = float(np.clip(np.nan_to_num(rho), 0.0, 0.97))
    alpha = 4 * rho ** 2 / ((1 - rho) ** 2 * (1 + rho) ** 2)
    lag = int(min(np.ceil(1.1447 * (alpha * n) ** (1 / 3)), n // 2)) if rho > 0 else 0
    scores = jac * res[:, None]
    meat = scores.T @ scores
    for k in range(1, lag + 1):
        g = scores[k:].T @ scores[:-k]
        meat += (1 - k / (lag + 1)) * (g + g.T)
    bread = np.linalg.pinv(jac.T @ jac)
    return bread @ meat @ bread * n / max(n - p, 1), lag


def _still_share(phase: np.ndarray, shape_mm: np.ndarray, drift_mm_s: float, f: float) -> float:
    """Share of the period in which the train's speed (the drift's plus the period-averaged motion's) is below
    :data:`STILL_SPEED_SHARE` of its peak."""
    dphi = phase[1] - phase[0]
    v = drift_mm_s + (np.roll(shape_mm, -1) - np.roll(shape_mm, 1)) / (2 * dphi) * f
    peak = float(np.max(np.abs(v)))
    return float(np.mean(np.abs(v) < STILL_SPEED_SHARE * peak)) if peak > 0 else 1.0


def oscillation_detail(time_s: np.ndarray, x_mm: np.ndarray, f_hz: float, *, fps: float,
                       scale_rel_sd: float = 0.0, not_hz: tuple[float, ...] = ()) -> Oscillation:
    """Frequency and amplitude of the train's oscillation with their 95 % intervals, its kind and stick fraction.

    Parameters
    ----------
    time_s, x_mm : ndarray
        The train's displacement (drift included) in each frame where it was seen.
    f_hz : float
        The oscillation's frequency as found (refined here).
    fps : float
        Frame rate (bounds the harmonics).
    scale_rel_sd : float
        Relative standard uncertainty of the scale (the amplitude's interval takes it in).
    not_hz : tuple of float
        The camera's frequencies: fitted apart (their sinusoids are not the plugs'); the shape keeps only the
        harmonics below the first that the record cannot tell from one of them.

    Returns
    -------
    Oscillation
    """
    from .._filters import t_quantile_975
    tc = time_s - time_s.mean()
    span = float(np.ptp(tc)) or 1.0
    n_harm = max(1, min(SHAPE_HARMONICS, int((0.45 * fps) // f_hz), (len(tc) - 3) // 2 - 1))
    camera = [float(g) for g in not_hz if 1.0 / span <= g <= 0.45 * fps]
    for h in range(2, n_harm + 1):  # a harmonic the record cannot tell from the camera's motion ends the shape
        if any(abs(h * f_hz - g) < 1.0 / span for g in camera):
            n_harm = h - 1
            break
    camera = [g for g in camera if all(abs(h * f_hz - g) >= 1.0 / span for h in range(1, n_harm + 1))]
    extra = (np.stack([fn(2 * np.pi * g * tc) for g in camera for fn in (np.cos, np.sin)], axis=1) if camera
             else np.zeros((len(tc), 0)))
    f, beta, jac, res = _sinusoid_fit(tc, x_mm, f_hz, n_harm, extra)
    cov, lag = _long_run_covariance(jac, res)
    n = len(tc)
    q = max(_fixed_b_quantile(lag / n), t_quantile_975(max(n - jac.shape[1], 1)))
    phase = np.linspace(0.0, 1.0, 720, endpoint=False)
    basis = _harmonic_columns(phase, 1.0, n_harm)
    coef_h = beta[2: 2 + 2 * n_harm]
    shape = basis @ coef_h
    # an error of the edges that holds over a period (where they stand, the glass, a slow nuisance) times each
    # period once: its instant is off by the residuals' scatter over the swing's speed, and the periods' instants
    # give the frequency as a straight line's slope through ``n_periods`` points
    n_periods = max(f * span, 2.0)
    speed = 2 * np.pi * f * np.sqrt(2.0) * float(np.std(shape)) or np.inf
    se_period = f * f * float(np.std(res)) / speed * np.sqrt(12.0 / (n_periods * (n_periods ** 2 - 1)))
    se_f = float(np.sqrt(max(cov[-1, -1], 0.0) + se_period ** 2))
    hi, lo = int(np.argmax(shape)), int(np.argmin(shape))
    amp = 0.5 * float(shape[hi] - shape[lo])
    grad = np.zeros(jac.shape[1])
    grad[2: 2 + 2 * n_harm] = 0.5 * (basis[hi] - basis[lo])  # the extremes' phases do not move to first order
    # the shape's truncation: what its last harmonic changes in the amplitude (a smooth shape's tail is smaller)
    se_shape = abs(amp - 0.5 * float(np.ptp(basis[:, :-2] @ coef_h[:-2]))) if n_harm > 1 else 0.0
    # the train dwells at its extremes: an edge's error that depends on where it stands (its sub-pixel place, the
    # glass) is the same over a dwell, so each extreme is seen once a period, with the residuals' scatter
    se_dwell = float(np.std(res)) / np.sqrt(2.0 * n_periods)
    se_a = float(np.sqrt(max(grad @ cov @ grad, 0.0) + se_shape ** 2 + se_dwell ** 2 + (amp * scale_rel_sd) ** 2))
    # a camera's exposure (up to a frame) averages the motion over it: harmonic h shrinks by sinc(h f / fps) at most,
    # so the swing may be larger than seen by what that shrinking takes from it (the interval's upper end only)
    blur = np.repeat(np.sinc(np.arange(1, n_harm + 1) * f / fps), 2)
    exposure = max(amp - 0.5 * float(np.ptp(basis @ (coef_h * blur))), 0.0)
    still = _still_share(phase, shape - shape.mean(), float(beta[1]), f)
    return Oscillation(
        frequency_hz=float(f), frequency_ci95_hz=(float(f - q * se_f), float(f + q * se_f)),
        amplitude_mm=amp, amplitude_ci95_mm=(float(max(amp - q * se_a, 0.0)), float(amp + q * se_a + exposure)),
        kind="stick-slip" if still >= STICK_SLIP_SHARE else "sinusoidal", stick_fraction=still,
        n_periods=float(f * span), phase=phase, shape_mm=shape - shape.mean())
