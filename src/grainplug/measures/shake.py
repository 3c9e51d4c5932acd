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
    #: the farthest the tube moved across (px from its median position, the 99th percentile of the frames)
    reach_across_px: float | None = None
    #: how far the tube may move across before a share of the diagram's band lies on its walls (px; None: not
    #: said; :func:`band_margin_px`)
    band_margin_px: float | None = None
    #: the sampled frames' motion across the tube (rms, px), measured before the tube was found on them
    sample_rms_across_px: float | None = None
    #: whether the sampled frames were moved back before the tube was found (:func:`register_sample`)
    sample_registered: bool = False
    #: the scale, for the figures in mm (None: not known yet)
    mm_per_px: float | None = None
    #: the typical standard error (px) of the motion along the tube, when it was measured
    along_sd_px: float = float("inf")

    @property
    def held_along(self) -> bool:
        """Whether the diagram is moved back by the motion along the tube: it was measured and stands above the
        registration's noise (a steady camera's diagram is left as read)."""
        if self.along_px is None or not len(self.along_px):
            return False
        rms = float(np.std(self.along_px))
        return rms >= SHAKE_MIN_RMS_PX and rms >= SHAKE_MIN_SNR * self.along_sd_px

    @property
    def too_large(self) -> bool:
        """Whether the tube moved across farther than its band's margin: the band took in the walls."""
        return (self.reach_across_px is not None and self.band_margin_px is not None
                and self.reach_across_px > self.band_margin_px)

    def as_dict(self) -> dict[str, object]:
        def mm(px: float | None) -> float | None:
            return None if px is None or self.mm_per_px is None else px * self.mm_per_px

        return {"shaking": self.shaking, "rms_across_px": rounded(self.rms_across_px, 4),
                "rms_along_px": rounded(self.rms_along_px, 4), "frequency_hz": rounded(self.frequency_hz, 4),
                "wander_hz": rounded(self.wander_hz, 4),
                "along_measured": self.along_px is not None, "along_corrected": self.held_along,
                "along_source": self.along_source,
                "rms_across_mm": rounded(mm(self.rms_across_px), 5), "rms_along_mm": rounded(mm(self.rms_along_px), 5),
                "reach_across_px": rounded(self.reach_across_px, 4),
                "band_margin_px": rounded(self.band_margin_px, 4), "too_large": self.too_large,
                "sample_registered": self.sample_registered,
                "sample_rms_across_px": rounded(self.sample_rms_across_px, 4)}


#: the registration's working arrays hold at most this many samples (frames x profile length) at once
CHUNK_SAMPLES = 1 << 17
#: the profile registered on is the median of at most this many frames spread over the record (its noise is a
#: shift common to all frames, taken out with their median): a long record is not copied whole to take it
REFERENCE_FRAMES = 512
#: frames spread over the record on which a probe is first tried: registered in full only where it measures
TRIAL_FRAMES = 48
#: ... along the tube (profiles of every position, a thousand samples or more: fewer frames suffice to see structure)
TRIAL_ALONG_FRAMES = 24
#: Gauss-Newton steps of that first try (its standard error is what is asked of it, not the shifts to a thousandth)
TRIAL_ITERATIONS = 3


def _spread(n: int, k: int) -> np.ndarray:
    """At most ``k`` indices spread evenly over ``range(n)`` (all of them when ``n <= k``)."""
    return np.arange(n) if n <= k else np.unique(np.linspace(0, n - 1, k).round().astype(np.int64))


def _moved_back(P: np.ndarray, whole: np.ndarray | None, rows: slice | np.ndarray) -> np.ndarray:
    """Rows ``rows`` of ``P`` (float32), each moved back by its whole samples ``whole`` (held at its ends)."""
    block = np.asarray(P[rows], np.float32)
    if whole is None:
        return block
    n_x = P.shape[1]
    idx = np.clip(np.arange(n_x)[None, :] + np.asarray(whole[rows], np.int64)[:, None], 0, n_x - 1)
    return np.take_along_axis(block, idx, axis=1)


def register(profiles: np.ndarray, *, n_iter: int = 4, chunk: int | None = None,
             reference: np.ndarray | None = None,
             whole: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
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
    reference : ndarray, optional
        The profile registered on (by default the median of at most :data:`REFERENCE_FRAMES` rows spread over
        them).
    whole : ndarray of int, optional
        Whole samples each row is first moved back by (:func:`register_wide`); the shifts returned include them.
        The rows are moved a chunk at a time: no moved copy of the record is held.
    """
    P = np.asarray(profiles)
    n_t, n_x = P.shape
    chunk = chunk or max(8, CHUNK_SAMPLES // max(n_x, 1))
    if reference is None:
        reference = np.median(_moved_back(P, whole, _spread(n_t, REFERENCE_FRAMES)), axis=0)
    ref = np.asarray(reference).astype(np.float64)
    grad = np.gradient(ref)
    var = np.zeros(n_x)
    for lo in range(0, n_t, chunk):  # the variance about the reference, a chunk at a time
        var += ((_moved_back(P, whole, slice(lo, lo + chunk)) - ref[None, :]) ** 2).sum(axis=0)
    var = var / max(n_t, 1) + 1e-6 * (np.var(ref) + 1e-12)
    w = grad**2 / var
    w[[0, -1]] = 0.0  # the ends have a one-sided gradient
    s = np.zeros(n_t)
    sd = np.full(n_t, np.inf)
    if not np.any(w > 0):
        return s, sd
    for lo in range(0, n_t, chunk):
        s[lo: lo + chunk], sd[lo: lo + chunk] = _gauss_newton(
            _moved_back(P, whole, slice(lo, lo + chunk)).astype(np.float64), ref, grad, w, n_iter)
    if whole is not None:
        s += whole
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


#: the tube has moved too far across when this share of the diagram's band lies outside its bore
BAND_OUT_SHARE = 0.25


def band_margin_px(bore_px: float, core_fraction: float) -> float:
    """How far (px) the tube may move across before :data:`BAND_OUT_SHARE` of the diagram's band (the central
    ``core_fraction`` of the bore) lies outside the bore, on the walls."""
    half = 0.5 * core_fraction * bore_px
    return 0.5 * bore_px - half + 2.0 * BAND_OUT_SHARE * half


#: a motion along the tube wider than this (px, peak to peak) read on the tube's walls or just beyond them (a clamp, a
#: label) is not the camera's: a shake and a wander of a few pixels each stay within it
MAX_NEAR_SWING_PX = 12.0


def measure_shake(across: list[np.ndarray], along: list[tuple[np.ndarray, float, str]], *, fps: float,
                  band_margin_px: float | None = None) -> Shake:
    """The tube's motion from its probes.

    Parameters
    ----------
    across : list of ndarray, shape (n_frames, n_offsets)
        Profiles across the tube, through its walls.
    along : list of (ndarray, float, str)
        Profiles along the tube (``n_frames x n_samples``) of what does not move with the grains, each with its
        spacing (positions along the tube a sample stands for) and what it is read on
        (:meth:`grainplug.diagram.extract.Probes.along`: the walls, just beyond them, the background beside the
        tube). A background beside the tube (spacing above 1) must swing by less than :data:`MAX_ALONG_SWING_PX`
        (a passing shadow is structure that moves), the walls by less than :data:`MAX_NEAR_SWING_PX`.
    fps : float
        Frame rate.
    band_margin_px : float, optional
        How far the tube may move across before the diagram's band takes in its walls (:func:`band_margin_px`,
        :attr:`Shake.too_large`).
    """
    # the profiles across the tube at its several heights move together (the camera moves the whole image): their
    # mean is registered once, with less noise
    full = [p for p in across if p.size and p.shape[1] == max(q.shape[1] for q in across)]
    across = [np.mean(full, axis=0, dtype=np.float32)] if full else []
    x_across, sd_across = _combine([register_wide(p) for p in _measuring(across, MEASURABLE_SD_PX)])
    read_along: list[tuple[np.ndarray, np.ndarray]] = []
    names: list[str] = []
    for p, step, name in along:
        if not _along_measurable(p, step):
            continue
        s, sd = register_along(p, step)
        if np.ptp(s) > (MAX_ALONG_SWING_PX if step > 1 else MAX_NEAR_SWING_PX):
            continue  # not the camera's motion
        read_along.append((s, sd))
        names.append(name)
    x_along, sd_along = _combine(read_along, limit_px=MEASURABLE_ALONG_SD_PX)
    used = [n for n, (_, sd) in zip(names, read_along, strict=True) if np.median(sd) <= MEASURABLE_ALONG_SD_PX]
    rms_a = None if x_across is None else _detrended_rms(x_across, fps)
    rms_l = None if x_along is None else _detrended_rms(x_along, fps)
    candidates = [(r, x, sd) for r, x, sd in ((rms_a, x_across, sd_across), (rms_l, x_along, sd_along))
                  if r is not None]
    shaking, freq, wander = False, None, None
    if candidates:
        r, x, sd = max(candidates, key=lambda c: c[0])
        shaking = r >= SHAKE_MIN_RMS_PX and r >= SHAKE_MIN_SNR * sd
        freq = main_frequency(_detrended(x, fps), fps) if shaking else None
    for x, sd in ((x_along, sd_along), (x_across, sd_across)):  # the camera's slow wander, along first
        if x is None:
            continue
        slow = x - _detrended(x, fps)
        if np.ptp(slow) >= 1.0 and np.ptp(slow) >= 2 * SHAKE_MIN_SNR * sd:  # by a pixel or more
            wander = main_frequency(slow, fps, lowest_hz=0.3)
            break
    source = (" and ".join(used) if x_along is not None else
              "nothing still along the tube to register it on: plain walls, a flat background beside it")
    reach = None if x_across is None else float(np.percentile(np.abs(x_across - np.median(x_across)), 99))
    return Shake(x_across, x_along, rms_a, rms_l, freq, bool(shaking), source, wander,
                 reach_across_px=reach, band_margin_px=band_margin_px, along_sd_px=sd_along)


#: a profile along the tube is registered on at most this many samples (neighbours averaged): fine enough for a
#: ruler's millimetre ticks at 0.2 mm/px (a period of 2.5 samples or more)
ALONG_REGISTERED_SAMPLES = 640


def register_along(profile: np.ndarray, step: float = 1.0, *, continuous: bool = True,
                   n_iter: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """The shift (px along the tube, about the median) of every frame's profile along the tube, and its standard
    error: :func:`register_wide` (shifts of a few pixels) on at most :data:`ALONG_REGISTERED_SAMPLES` samples
    (neighbours averaged); ``step``: the positions along the tube one sample of ``profile`` stands for;
    ``continuous``: the rows are a record's frames in order (:func:`register_wide`), not frames spread over it."""
    P = np.asarray(profile)
    k = max(1, P.shape[1] // ALONG_REGISTERED_SAMPLES)
    if k > 1:  # averaged a chunk of frames at a time: only the averaged profile is held
        n = P.shape[1] // k * k
        binned = np.empty((len(P), n // k), np.float32)
        chunk = max(8, CHUNK_SAMPLES // n)
        for lo in range(0, len(P), chunk):
            binned[lo: lo + chunk] = np.asarray(P[lo: lo + chunk, :n], np.float32).reshape(-1, n // k, k).mean(axis=2)
        P = binned
    search = max(3, int(np.ceil(SAMPLE_SEARCH_PX / (k * step))))
    s, sd = register_wide(P, search_px=search, continuous=continuous, n_iter=n_iter)
    return s * k * step, sd * k * step


#: a profile along the tube with more than this share of its structure (its mean's squared gradient) within a sample
#: of the positions where it jumps a pixel across is read on the sampling's steps, fixed to the sensor: not tried
SAMPLING_STEP_SHARE = 0.5


def sampling_step_share(profile: np.ndarray, jumps: np.ndarray) -> float:
    """The share of ``profile``'s structure (the squared gradient of its mean over the frames) that lies within a
    sample of ``jumps`` (positions where its pixels jump across the tube: :meth:`Probes.near_jumps
    <grainplug.diagram.extract.Probes.near_jumps>`)."""
    g2 = np.gradient(np.mean(np.asarray(profile, np.float64), axis=0)) ** 2
    near = np.convolve(np.asarray(jumps, float), np.ones(3), mode="same") > 0
    total = float(g2.sum())
    return float(g2[near].sum()) / total if total > 0 else 0.0


def best_along(profiles: list[np.ndarray | None], jumps: list[np.ndarray | None] | None = None) -> int | None:
    """Which of the profiles along the tube (on a few frames spread over the record: the sampled frames) measures
    a motion along it best (the smallest standard error), if any can (:func:`along_sd_px`); None when none.
    ``jumps``: where each jumps a pixel across the tube; one whose structure is mostly there
    (:data:`SAMPLING_STEP_SHARE`, :func:`sampling_step_share`) is the sampling's, fixed to the sensor: not tried."""
    jumps = jumps if jumps is not None else [None] * len(profiles)
    sds = [np.inf if p is None or (j is not None and sampling_step_share(p, j) > SAMPLING_STEP_SHARE)
           else along_sd_px(p) for p, j in zip(profiles, jumps, strict=True)]
    k = int(np.argmin(sds)) if sds else 0
    return k if sds and sds[k] <= MEASURABLE_ALONG_SD_PX else None  # no margin: a marginal one costs its reading


def along_sd_px(profile: np.ndarray, step: float = 1.0) -> float:
    """The typical standard error (px) of a motion along the tube registered on ``profile``, tried on at most
    :data:`TRIAL_ALONG_FRAMES` of its frames spread over the record (a plain wall or a flat background is so found
    without registering every frame); inf when it is too short."""
    if not profile.size or profile.shape[1] < 8:
        return float("inf")
    p = profile
    trial = p[np.unique(np.linspace(0, len(p) - 1, min(len(p), TRIAL_ALONG_FRAMES)).round().astype(int))]
    return float(np.median(register_along(trial, step, continuous=False, n_iter=TRIAL_ITERATIONS)[1]))


def _along_measurable(profile: np.ndarray, step: float) -> bool:
    """Whether a profile along the tube can measure its motion (:func:`along_sd_px`, with a margin: the full
    record's reference is better)."""
    return along_sd_px(profile, step) <= 1.5 * MEASURABLE_ALONG_SD_PX


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


# ---- the sampled frames, registered before the tube is found -----------------------------------------------------

#: the sampled frames are moved back when the tube's motion across them reaches this rms (px): below, the frames are
#: used as they are (a steady camera costs nothing more)
SAMPLE_MIN_RMS_PX = 0.15
#: the profile across the tube is projected along at most this many rows, spread along it (a frame's thousand rows
#: are not needed: 32 rows average the noise to a fraction of a grey level, and the walls run along every one)
SAMPLE_ROWS = 32


@dataclass(frozen=True)
class SampleShake:
    """The sampled frames' motion across the tube, measured on the structure that does not move with the grains
    (the walls, the background), before the tube is found on them.

    Attributes
    ----------
    across_px : ndarray or None
        Each sampled frame's displacement across the tube (px, about their median; None when it could not
        be measured: nothing but the tube's contents has structure across it).
    sd_px : float
        The shifts' typical standard error (inf when not measured).
    registered : bool
        Whether the frames were moved back (the motion's rms reached :data:`SAMPLE_MIN_RMS_PX` and stood
        :data:`SHAKE_MIN_SNR` standard errors above the registration's noise).
    """

    across_px: np.ndarray | None
    sd_px: float
    registered: bool

    @property
    def rms_px(self) -> float | None:
        """The rms of the shifts about their mean."""
        return None if self.across_px is None else float(np.std(self.across_px))


#: the sampled frames' shifts are first searched in whole pixels up to this far (px): a wander and a shake
#: together move a camera by a few pixels, more than a wall's edge is wide
SAMPLE_SEARCH_PX = 8


#: in a record followed frame by frame (:func:`register_wide`'s ``continuous``), a jump of ``j`` whole samples
#: between consecutive frames costs ``JUMP_COST * j**2`` of a frame's best match: a camera moves by a pixel or so
#: between frames (1.3 px for a 1.5 px shake at 35 Hz filmed at 250 fps: 0.4 of a match), while a periodic pattern
#: (a ruler's ticks) that matches as well a period away (5 px or more) would cost 6 to jump to
JUMP_COST = 0.25


def _continuous_path(score: np.ndarray, lags: np.ndarray) -> np.ndarray:
    """The whole-sample shift of every frame that best matches each frame's profile (``score``, frames x lags) and
    moves least from frame to frame (a jump of ``j`` samples costing :data:`JUMP_COST` ``j**2`` of a frame's best
    score): a Viterbi path, so that a pattern that repeats (a ruler) is followed, not matched a period away."""
    top = np.max(np.abs(score), axis=1, keepdims=True)
    s = score / np.where(top > 0, top, 1.0)
    jump = JUMP_COST * ((lags[:, None] - lags[None, :]).astype(float)) ** 2  # [to, from]
    value = s[0].copy()
    back = np.empty(score.shape, np.int64)
    for t in range(1, len(s)):
        cand = value[None, :] - jump
        back[t] = np.argmax(cand, axis=1)
        value = s[t] + cand[np.arange(len(lags)), back[t]]
    path = np.empty(len(s), np.int64)
    path[-1] = int(np.argmax(value))
    for t in range(len(s) - 1, 0, -1):
        path[t - 1] = back[t, path[t]]
    return lags[path]


def register_wide(profiles: np.ndarray, *, search_px: int = SAMPLE_SEARCH_PX,
                  continuous: bool = False, n_iter: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """:func:`register` for shifts of up to ``search_px`` (a few pixels, beyond the reach of its Gauss-Newton steps
    from zero): each profile's gradient is first matched in whole pixels with the median's (its cross-correlation's
    peak), the profiles moved back, their median taken again as the reference, and :func:`register` refines.
    ``continuous``: the profiles are the frames of a record, in order: the whole-pixel shifts are the path that
    matches well and moves least from frame to frame (:func:`_continuous_path`), not each frame's best alone.
    ``n_iter``: Gauss-Newton steps after the whole-pixel match (fewer for a first look at a few frames).

    Returns the shifts (samples, positive: the profile moved to higher indices, about their median) and their
    standard errors.
    """
    P = np.asarray(profiles)
    n_t, n_x = P.shape
    k = int(min(search_px, n_x // 4))
    chunk = max(8, CHUNK_SAMPLES // max(n_x, 1))  # the gradients are taken a chunk of frames at a time
    ref = np.median(np.gradient(np.asarray(P[_spread(n_t, REFERENCE_FRAMES)], np.float32), axis=1), axis=0)
    lags = np.arange(-k, k + 1)
    score = np.empty((n_t, len(lags)))
    core = slice(k, n_x - k)
    for lo in range(0, n_t, chunk):
        d = np.gradient(np.asarray(P[lo: lo + chunk], np.float32), axis=1)[:, core]
        for j, lag in enumerate(lags):  # d_t(x) ~ ref(x - lag)
            score[lo: lo + chunk, j] = (d * ref[k - lag: n_x - k - lag][None, :]).sum(axis=1)
    whole = (_continuous_path(score, lags) if continuous and n_t > 1 else lags[np.argmax(score, axis=1)])
    whole = whole - int(np.median(whole).round())
    if not whole.any():  # a steady camera: Gauss-Newton from zero is enough
        return register(P, n_iter=min(n_iter, 4))
    # Gauss-Newton from the whole-pixel guess: the profiles moved back by it (p(x + w), a chunk at a time), their
    # median the reference, the guess added back
    return register(P, n_iter=n_iter, whole=whole.astype(np.int64))


def across_profiles(frames: list[np.ndarray], *, orientation: str, tilt_deg: float,
                    max_rows: int = SAMPLE_ROWS) -> np.ndarray:
    """Every frame's mean grey level along lines parallel to the tube's axis, at every pixel across it
    (``n_frames x n_columns`` of the canonical view; columns some line leaves the frame for are dropped).

    Parameters
    ----------
    frames : list of ndarray
        Grey or colour frames.
    orientation : {"vertical", "horizontal"}
        The tube's axis in the frame (a horizontal tube's frames are transposed: the canonical view).
    tilt_deg : float
        The axis' angle from the canonical view's columns.
    max_rows : int
        At most this many rows along the tube are projected (every ``k``-th).
    """
    from ..calibration.tube import sheared_profile, to_grey

    out = []
    for f in frames:
        view = np.swapaxes(f, 0, 1) if orientation == "horizontal" else f
        step = max(1, view.shape[0] // max_rows)
        g = to_grey(view[::step])  # only the rows projected are made grey
        # row k of g is the view's row k * step: the lines' slope per row of g is step times theirs (the constant
        # left over, the same for every frame, does not move one frame against another)
        tan_b = float(np.tan(np.radians(tilt_deg))) * step
        out.append(sheared_profile(g, tan_b, np.arange(g.shape[1], dtype=float)))
    P = np.stack(out) if out else np.zeros((0, 0))
    return P[:, np.isfinite(P).all(axis=0)] if P.size else P


def register_sample(frames: list[np.ndarray], *, orientation: str,
                    tilt_deg: float = 0.0) -> tuple[list[np.ndarray], SampleShake]:
    """The sampled frames moved back by the camera's motion across the tube, so that the tube is found where it
    is on average and as wide as it is (a shaking wall is not taken for a second tube, nor the bore for wider).

    The profiles across the tube (:func:`across_profiles`: the walls, the background, the bore's mean contents)
    are registered on their median by :func:`register`; the walls' edges weigh most, the bore's changing contents
    least. The motion along the tube is left: the tube looks the same wherever it is along its axis.

    Parameters
    ----------
    frames : list of ndarray
        The sampled frames (grey or colour).
    orientation : {"vertical", "horizontal"}
        The tube's axis (a first look at the unregistered frames finds it: the walls stay parallel to it).
    tilt_deg : float
        The axis' angle (canonical view).

    Returns
    -------
    frames : list of ndarray
        Grey float32 frames moved back, or ``frames`` themselves when the camera did not move.
    shake : SampleShake
    """
    if len(frames) < 4:
        return frames, SampleShake(None, np.inf, False)
    P = across_profiles(frames, orientation=orientation, tilt_deg=tilt_deg)
    if P.shape[1] < 8:
        return frames, SampleShake(None, np.inf, False)
    s, sd = register_wide(P)
    typical_sd = float(np.median(sd))
    if not typical_sd <= MEASURABLE_SD_PX:
        return frames, SampleShake(None, typical_sd, False)
    rms = float(np.std(s))
    if rms < SAMPLE_MIN_RMS_PX or rms < SHAKE_MIN_SNR * typical_sd:
        return frames, SampleShake(s, typical_sd, False)
    import cv2

    from ..calibration.tube import to_grey

    moved = []
    for f, dx in zip(frames, s, strict=True):
        # the canonical x is the frame's column (vertical tube) or row (horizontal): moved back by -dx
        m = np.array([[1.0, 0.0, -dx], [0.0, 1.0, 0.0]] if orientation != "horizontal" else
                     [[1.0, 0.0, 0.0], [0.0, 1.0, -dx]], np.float64)
        g = to_grey(f)
        moved.append(cv2.warpAffine(g, m, (g.shape[1], g.shape[0]), flags=cv2.INTER_LANCZOS4,
                                    borderMode=cv2.BORDER_REPLICATE))
    return moved, SampleShake(s, typical_sd, True)


def shake_line(block: dict[str, object] | None) -> str:
    """One line on the camera's shake from ``summary.json``'s ``shake`` block (empty when the camera was steady):
    its rms across and along the tube (px and mm), its main frequency, and whether it was too large."""
    if not block or not (block.get("shaking") or block.get("too_large")):
        return ""

    def part(name: str, key: str) -> str:
        px, mm = block.get(f"rms_{key}_px"), block.get(f"rms_{key}_mm")
        if px is None:
            return f"{name} not measured"
        return f"{px:.2g} px rms {name}" + (f" ({mm:.2g} mm)" if mm is not None else "")

    f = block.get("frequency_hz")
    out = f"{part('across', 'across')}, {part('along', 'along')}" + (f", at {f:.3g} Hz" if f else "")
    return out + (" — too large: the diagram's band took in the walls" if block.get("too_large") else "")
