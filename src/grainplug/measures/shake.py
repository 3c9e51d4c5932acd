"""Camera shake: the tube's own motion in the image, measured on what does not move with the grains.

A pump, a fan or a door shakes the camera by a pixel or two at tens of hertz. Every edge in the image
then moves together, and the plug train seems to oscillate at the shake's frequency. The tube itself
tells the two apart: its walls (across it) and the background beside it and anything fixed to it
(along it) move with the camera only.

Notes
-----
Each probe (a profile across the tube through its walls, or the background beside the tube along it,
:func:`grainplug.diagram.probes_along_tube`) is registered, frame by frame, on its median over the
record, by Gauss-Newton on the model

.. math:: P_t(x) = g_t\\, R(x - s_t) + o_t

(a gain and an offset for the lamp's ripple and a passing shadow, a shift ``s_t`` for the motion). The
samples are weighted by ``R'(x)^2`` over their variance across the record: a wall's edge counts, the
bore's changing contents and a flat background do not. A shift is measurable where the weighted
gradient makes its standard error small (:data:`MEASURABLE_SD_PX`); the probes across the tube give
the motion across it, the background beside it the motion along it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._format import rounded

#: a profile across the tube whose shift's standard error (px) exceeds this does not measure the motion
MEASURABLE_SD_PX = 0.5
#: the same along the tube, stricter: a shadow passing along the background beside the tube is structure that
#: moves, and must not be taken for the camera's motion
MEASURABLE_ALONG_SD_PX = 0.15
#: a camera shakes and wanders by a few pixels: a motion along the tube wider than this (px, peak to peak) is
#: something moving along the background (a passing shadow), not the camera
MAX_ALONG_SWING_PX = 6.0
#: the tube shakes when the motion's rms (px) reaches this and stands this many standard errors above noise
SHAKE_MIN_RMS_PX = 0.2
SHAKE_MIN_SNR = 4.0
#: frequencies within this (Hz, or two spectral bins) of the shake's are the camera's, not the plugs'
SAME_FREQUENCY_HZ = 0.3


@dataclass(frozen=True)
class Shake:
    """The tube's motion in the image, frame by frame (px, about its median position).

    Attributes
    ----------
    across_px : ndarray or None
        Across the tube (None when the walls could not be registered).
    along_px : ndarray or None
        Along it, downstream positive (None when nothing still along the tube could be registered).
    rms_across_px, rms_along_px : float or None
        Their rms about their mean (after a slow drift is removed).
    frequency_hz : float or None
        The main frequency of the motion (its larger component), when the tube shakes.
    shaking : bool
        Whether the motion stands above the registration's noise (:data:`SHAKE_MIN_RMS_PX`).
    along_source : str
        What the motion along the tube was measured on, or why it was not.
    """

    across_px: np.ndarray | None
    along_px: np.ndarray | None
    rms_across_px: float | None
    rms_along_px: float | None
    frequency_hz: float | None
    shaking: bool
    along_source: str
    #: the frequency of the camera's slow wander (a pixel or more, slower than :data:`WANDER_S`), when it wanders
    wander_hz: float | None = None

    def as_dict(self) -> dict[str, object]:
        return {"shaking": self.shaking, "rms_across_px": rounded(self.rms_across_px, 4),
                "rms_along_px": rounded(self.rms_along_px, 4), "frequency_hz": rounded(self.frequency_hz, 4),
                "wander_hz": rounded(self.wander_hz, 4),
                "along_measured": self.along_px is not None, "along_source": self.along_source}


#: the registration's working arrays hold at most this many samples (frames x profile length) at once
CHUNK_SAMPLES = 1 << 17
#: frames spread over the record on which a probe is first tried: registered in full only where it measures
TRIAL_FRAMES = 48


def register(profiles: np.ndarray, *, n_iter: int = 4, chunk: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Shift (samples, positive: the profile moved to higher indices) of each row of ``profiles`` against
    their median over the rows, and its standard error.

    Parameters
    ----------
    profiles : ndarray, shape (n_frames, n_samples)
        One profile per frame.
    n_iter : int
        Gauss-Newton steps.
    chunk : int, optional
        Frames registered at once (the working memory is that of ``chunk`` frames, whatever the record's length);
        by default as many as :data:`CHUNK_SAMPLES` allows.
    """
    P = np.asarray(profiles, np.float32)
    n_t, n_x = P.shape
    chunk = chunk or max(8, CHUNK_SAMPLES // max(n_x, 1))
    ref = np.median(P, axis=0).astype(np.float64)
    grad = np.gradient(ref)
    var = np.zeros(n_x)
    for lo in range(0, n_t, chunk):  # the variance about the reference, a chunk at a time
        var += ((P[lo: lo + chunk] - ref[None, :]) ** 2).sum(axis=0)
    var = var / max(n_t, 1) + 1e-6 * (np.var(ref) + 1e-12)
    w = grad**2 / var
    w[[0, -1]] = 0.0  # the ends have a one-sided gradient
    s = np.zeros(n_t)
    sd = np.full(n_t, np.inf)
    if not np.any(w > 0):
        return s, sd
    for lo in range(0, n_t, chunk):
        s[lo: lo + chunk], sd[lo: lo + chunk] = _gauss_newton(P[lo: lo + chunk].astype(np.float64), ref, grad, w,
                                                              n_iter)
    s -= np.median(s)
    return s, sd


def _gauss_newton(P: np.ndarray, ref: np.ndarray, grad: np.ndarray, w: np.ndarray,
                  n_iter: int) -> tuple[np.ndarray, np.ndarray]:
    """Shifts and their standard errors of a chunk of frames (see :func:`register`)."""
    n_t, n_x = P.shape
    x = np.arange(n_x, dtype=np.float64)
    s = np.zeros(n_t)
    sd = np.full(n_t, np.inf)
    eye = 1e-12 * np.eye(3)[None]
    for _ in range(n_iter):
        xs = x[None, :] - s[:, None]  # R(x - s): the reference moved by s
        R = _interp_rows(ref, xs)
        dR = _interp_rows(grad, xs)
        # least squares for (g, c, o) in P = g R + c dR + o: then the step is -c / g
        A = np.stack([R, dR, np.ones_like(R)], axis=2)
        Aw = A * w[None, :, None]
        M = np.einsum("tij,tik->tjk", Aw, A)
        b = np.einsum("tij,ti->tj", Aw, P)
        try:
            sol = np.linalg.solve(M + eye, b[..., None])[..., 0]
        except np.linalg.LinAlgError:
            break
        g, c = sol[:, 0], sol[:, 1]
        safe = np.abs(g) > 1e-9
        step = np.where(safe, -c / np.where(safe, g, 1.0), 0.0)
        s = s + np.clip(step, -3.0, 3.0)
        res = P - np.einsum("tij,tj->ti", A, sol)
        sigma2 = (w[None, :] * res**2).sum(axis=1) / max(int((w > 0).sum()) - 3, 1)
        inv = np.linalg.inv(M + eye)
        sd = np.sqrt(np.maximum(sigma2 * inv[:, 1, 1], 0.0)) / np.maximum(np.abs(g), 1e-9)
        if np.max(np.abs(step)) < 1e-3:
            break
    return s, sd


def _interp_rows(values: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """``values`` (one profile) linearly interpolated at every row of positions ``xs`` (held at its ends)."""
    n = len(values)
    xc = np.clip(xs, 0, n - 1)
    i0 = np.minimum(np.floor(xc).astype(np.int64), n - 2)
    f = xc - i0
    return values[i0] * (1 - f) + values[i0 + 1] * f


def _combine(shifts: list[tuple[np.ndarray, np.ndarray]], *,
             limit_px: float = MEASURABLE_SD_PX) -> tuple[np.ndarray | None, float]:
    """The measurable probes' shifts averaged by their inverse variance; None when none is measurable."""
    good = [(s, sd) for s, sd in shifts if np.median(sd) <= limit_px]
    if not good:
        return None, np.inf
    w = np.stack([1.0 / np.maximum(sd, 1e-6) ** 2 for _, sd in good])
    s = np.stack([s for s, _ in good])
    mean = (w * s).sum(axis=0) / w.sum(axis=0)
    return mean - np.median(mean), float(np.median(1.0 / np.sqrt(w.sum(axis=0))))


#: the motion slower than this (s, a running mean) is the camera's wander, not its shake
WANDER_S = 1.0


def _detrended(x: np.ndarray, fps: float) -> np.ndarray:
    """``x`` about a slow wander (a running mean over :data:`WANDER_S`, at most a third of the record)."""
    from .._filters import uniform_filter1d

    k = max(3, min(int(round(WANDER_S * fps)), len(x) // 3) | 1)
    return x - uniform_filter1d(x, k, mode="nearest")


def _detrended_rms(x: np.ndarray, fps: float) -> float:
    """rms of ``x`` about its slow wander."""
    return float(np.std(_detrended(x, fps)))


def main_frequency(x: np.ndarray, fps: float, *, lowest_hz: float = 1.0) -> float | None:
    """The strongest frequency of ``x`` above ``lowest_hz`` (a periodogram, Hann window, zero-padded)."""
    n = len(x)
    if n < 16:
        return None
    y = (x - np.mean(x)) * np.hanning(n)
    nfft = 1 << int(np.ceil(np.log2(4 * n)))
    spec = np.abs(np.fft.rfft(y, nfft))
    f = np.fft.rfftfreq(nfft, 1.0 / fps)
    band = f >= max(lowest_hz, 1.5 * fps / n)
    if not band.any():
        return None
    return float(f[band][np.argmax(spec[band])])


def measure_shake(across: list[np.ndarray], along: list[np.ndarray], *, fps: float) -> Shake:
    """The tube's motion from its probes.

    Parameters
    ----------
    across : list of ndarray, shape (n_frames, n_offsets)
        Profiles across the tube, through its walls.
    along : list of ndarray, shape (n_frames, n_positions)
        Profiles along the tube of what does not move with the grains (the background beside it).
    fps : float
        Frame rate.
    """
    # the profiles across the tube at its several heights move together (the camera moves the whole image): their
    # mean is registered once, with less noise
    full = [p for p in across if p.size and p.shape[1] == max(q.shape[1] for q in across)]
    across = [np.mean(full, axis=0, dtype=np.float32)] if full else []
    x_across, sd_across = _combine([register(p) for p in _measuring(across, MEASURABLE_SD_PX)])
    x_along, sd_along = _combine([_register_binned(p) for p in _measuring(along, MEASURABLE_ALONG_SD_PX)],
                                 limit_px=MEASURABLE_ALONG_SD_PX)
    if x_along is not None and np.ptp(x_along) > MAX_ALONG_SWING_PX:
        x_along, sd_along = None, np.inf  # not the camera's motion
    rms_a = None if x_across is None else _detrended_rms(x_across, fps)
    rms_l = None if x_along is None else _detrended_rms(x_along, fps)
    candidates = [(r, x, sd) for r, x, sd in ((rms_a, x_across, sd_across), (rms_l, x_along, sd_along))
                  if r is not None]
    shaking, freq, wander = False, None, None
    if candidates:
        r, x, sd = max(candidates, key=lambda c: c[0])
        shaking = r >= SHAKE_MIN_RMS_PX and r >= SHAKE_MIN_SNR * sd
        freq = main_frequency(_detrended(x, fps), fps) if shaking else None
        slow = x - _detrended(x, fps)
        if np.ptp(slow) >= 1.0 and np.ptp(slow) >= 2 * SHAKE_MIN_SNR * sd:  # the camera wanders by a pixel or more
            wander = main_frequency(slow, fps, lowest_hz=0.3)
    source = ("the background beside the tube" if x_along is not None else
              "nothing still along the tube (a flat background beside it) to register it on")
    return Shake(x_across, x_along, rms_a, rms_l, freq, bool(shaking), source, wander)


#: a long profile is registered on at most this many samples (neighbours averaged): the same sub-pixel shift,
#: at a fraction of the cost
REGISTERED_SAMPLES = 256


def _register_binned(profile: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`register` on the profile with every ``k`` neighbouring samples averaged (at most
    :data:`REGISTERED_SAMPLES` left); shifts and errors in the profile's own samples."""
    k = max(1, profile.shape[1] // REGISTERED_SAMPLES)
    if k == 1:
        return register(profile)
    n = profile.shape[1] // k * k
    binned = np.asarray(profile[:, :n], np.float32).reshape(len(profile), -1, k).mean(axis=2)
    s, sd = register(binned)
    return s * k, sd * k


def _measuring(profiles: list[np.ndarray], limit_px: float) -> list[np.ndarray]:
    """The probes that can measure the motion, tried first on :data:`TRIAL_FRAMES` frames spread over the record
    (a flat background is found so without registering every frame)."""
    out = []
    for p in profiles:
        if not p.size or p.shape[1] < 8:
            continue
        trial = p[np.unique(np.linspace(0, len(p) - 1, min(len(p), TRIAL_FRAMES)).round().astype(int))]
        if np.median(_register_binned(trial)[1]) <= 1.5 * limit_px:  # a margin: the full record's reference is better
            out.append(p)
    return out


def shift_along(values: np.ndarray, along_px: np.ndarray, px_per_sample: float = 1.0) -> np.ndarray:
    """The diagram with each frame moved back by the tube's motion along it: ``out[t, i] = values[t, i + s_t]``
    (linear interpolation; held at the view's ends)."""
    v = np.asarray(values, np.float32)
    n = v.shape[1]
    x = np.arange(n, dtype=np.float64)[None, :] + (np.asarray(along_px, float) / px_per_sample)[:, None]
    xc = np.clip(x, 0, n - 1)
    i0 = np.minimum(np.floor(xc).astype(np.int64), n - 2)
    f = (xc - i0).astype(np.float32)
    rows = np.arange(v.shape[0])[:, None]
    return v[rows, i0] * (1 - f) + v[rows, i0 + 1] * f


def shake_hz(shake: Shake | None) -> tuple[float, ...]:
    """The frequencies that are the camera's, not the plugs' (none when the tube does not shake)."""
    if shake is None:
        return ()
    out = [shake.frequency_hz] if shake.shaking and shake.frequency_hz is not None else []
    if shake.along_px is None and shake.wander_hz is not None:  # a wander not corrected along the tube
        out.append(shake.wander_hz)
    return tuple(float(f) for f in out)
