"""Illumination normalisation and plug/bubble contrast, learnt from the diagram itself.

Notes
-----
The diagram ``D(t, s)`` of a plug flow holds two kinds of material, grains
(plugs) and air (bubbles), seen through a light that changes from frame to
frame (flicker, ``g(t)``) and along the tube (illumination gradient, ``L(s)``).
In logarithms the model is additive:

.. math:: \\log D(t, s) = a(t) + b(s) + \\mu_{k(t,s)} + \\varepsilon

with ``k`` the class of the pixel (plug or bubble) and ``mu_k`` the class level.
It is fitted by alternating steps, as a bias-field correction with two classes:
classify the corrected values by Otsu's threshold, take each class's median
level, then update ``a(t)`` as the per-frame median and ``b(s)`` as a smooth
per-position median of what the class levels leave (on at most 400 frames
spread over the record; the gains of all frames are then found in one pass,
each frame classified with the fitted levels). A frame's gain is bounded
to 40% of the gap between the class levels, so that a frame filled by one
material is not read as the other under another light. The normalised contrast
is taken in linear intensity, ``z = (e^R - e^mu_bubble) / (e^mu_plug - e^mu_bubble)``
with ``R = log D - a - b``: 0 in bubbles and 1 in plugs whatever the polarity,
and an edge blurred by optics or by averaging lies at ``z = 0.5``.

Which class is the plugs: the one whose level lies farther from the light of
the background outside the tube (grains block a back light, and scatter a
front light, while air changes neither much).

Whether there are plugs at all: the classes must be well separated (Otsu's
between-class share of the variance ``eta``) and the minority class must hold
enough of the diagram; otherwise the flow is compact or the tube empty. One grey
level with noise gives ``eta = 2/pi = 0.64`` (a Gaussian split at its mean), two
levels ``d`` apart under noise ``s`` give ``eta = 1 / (1 + 4 s^2 / d^2)`` (even
classes): ``eta >= 0.8`` asks for ``d >= 4 s`` pixel by pixel. Plugs are long, noise
and grain texture are not: where ``0.7 <= eta < 0.8``, the classes are looked for
again in the diagram averaged along the tube over a third of the shortest plug
(``confirm_px``), which keeps plugs and bubbles at their levels and cuts the noise,
and two materials separated there (``eta >= 0.85``, ``d >= 4.8 s``) are two.
Measured on an independent renderer's plugs in grain-laden bubbles: ``eta`` 0.74, 0.86
averaged over 1 mm, and the plugs measured within 0.4 % (celerity) and 2.5 % (lengths);
``eta`` 0.67 averaged to 0.78, where the classes came out swapped, stays refused.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MIN_SEPARATION_ETA = 0.8
MIN_CLASS_FRACTION = 0.02
#: a separation under ``MIN_SEPARATION_ETA`` but at least this is confirmed by averaging along the tube
LOW_SEPARATION_ETA = 0.7
#: the separation the averaged diagram must reach
CONFIRMED_ETA = 0.85


@dataclass(frozen=True)
class Normalized:
    """The diagram in plug/bubble contrast units, with what was learnt.

    Attributes
    ----------
    z : ndarray
        Contrast, 0 = bubble level, 1 = plug level (float32, same shape as the diagram).
    frame_gain : ndarray
        ``exp(a(t))``: relative light of each frame (flicker).
    position_gain : ndarray
        ``exp(b(s))``: relative light along the tube (illumination gradient).
    plug_level, bubble_level : float
        Class levels (grey, at unit gains).
    plugs_darker : bool
        Plugs are darker than bubbles (back light).
    separation_eta : float
        Otsu's between-class share of the variance (1 = two perfectly separate levels).
    averaged_eta : float or None
        The same in the diagram averaged along the tube over ``confirm_px`` positions,
        where ``separation_eta`` alone was short of two materials (None otherwise).
    plug_fraction : float
        Share of the diagram classed as plug.
    two_phase : bool
        Whether the diagram holds two distinct materials (plugs and bubbles).
    """

    z: np.ndarray
    frame_gain: np.ndarray
    position_gain: np.ndarray
    plug_level: float
    bubble_level: float
    plugs_darker: bool
    separation_eta: float
    plug_fraction: float
    two_phase: bool
    averaged_eta: float | None = None


def _otsu(values: np.ndarray) -> tuple[float, float]:
    """Otsu threshold and its effectiveness (between-class / total variance)."""
    from .._filters import threshold_otsu
    v = values[np.isfinite(values)]
    if v.size < 4:
        return float(np.median(v)) if v.size else 0.0, 0.0
    # a range of a few rounding steps of the values given is flat
    eps = np.finfo(v.dtype).eps if np.issubdtype(v.dtype, np.floating) else 0.0
    lo, hi_v = float(v.min()), float(v.max())
    if hi_v - lo <= 64 * eps * max(1.0, abs(lo), abs(hi_v)):
        return float(np.median(v)), 0.0
    # about 0: log grey levels carry their light's level (log 16000 = 9.7 under a camera's dark offset), and
    # a contrast of 1 % there was too narrow for the histogram's bins in float32 (it was taken as flat)
    centre = v.dtype.type(0.5 * (lo + hi_v)) if np.issubdtype(v.dtype, np.floating) else 0
    v = v - centre
    thr = threshold_otsu(v, nbins=512)
    hi = v > thr
    w1 = hi.mean()
    if w1 in (0.0, 1.0):
        return thr + float(centre), 0.0
    between = w1 * (1 - w1) * (v[hi].mean() - v[~hi].mean()) ** 2
    return thr + float(centre), float(between / v.var())


def _class_levels(R: np.ndarray) -> tuple[float, float, float, np.ndarray]:
    thr, eta = _otsu(R)
    cls = R > thr
    mu_hi = float(np.median(R[cls])) if cls.any() else thr
    mu_lo = float(np.median(R[~cls])) if (~cls).any() else thr
    return mu_hi, mu_lo, eta, cls


def normalize(values: np.ndarray, *, background_level: float | None = None,
              smooth_positions: float = 0.08, n_iter: int = 6, max_fit_frames: int = 400,
              tol: float = 1e-4, confirm_px: int = 1) -> Normalized:
    """Fit the two-class illumination model and return the plug contrast.

    Parameters
    ----------
    values : ndarray, shape (n_frames, n_positions)
        The raw diagram.
    background_level : float, optional
        Grey level of the background outside the tube, to tell plugs from bubbles.
        Without it, the class with the more texture is taken as plugs.
    smooth_positions : float
        Width of the Gaussian that smooths ``b(s)``, as a share of the view.
    n_iter : int
        Alternating steps, at most.
    tol : float
        Stop when no log-gain (``a`` about its median, ``b``) moves by more than this.
    max_fit_frames : int
        The class levels and ``b(s)`` are fitted on at most this many frames spread
        over the record; the per-frame gains ``a(t)`` are then found for every frame.
    confirm_px : int
        Positions along the tube over which a weak separation is looked for again
        (a third of the shortest plug); 1: not looked for.
    """
    from .._filters import gaussian_filter1d
    d = np.asarray(values, dtype=np.float32)
    scale = max(float(np.percentile(d[:: max(1, d.shape[0] // 200)], 99)), 1e-9)
    L = np.maximum(d, np.float32(1e-3 * scale))
    np.log(L, out=L)
    n_t, n_s = L.shape
    rows = np.unique(np.linspace(0, n_t - 1, min(n_t, max_fit_frames)).round().astype(int))
    Lf = L[rows]
    a = np.zeros(len(rows), np.float32)
    b = np.zeros(n_s, np.float32)
    sigma_s = max(2.0, smooth_positions * n_s)
    bound = np.inf
    for _ in range(n_iter):
        a_prev, b_prev = a - np.median(a), b
        R = Lf - a[:, None] - b[None, :]
        mu_hi, mu_lo, _, cls = _class_levels(R)
        E = Lf - np.where(cls, np.float32(mu_hi), np.float32(mu_lo))
        # medians over every 2nd position / frame: the same estimate at a quarter of the cost
        a = np.median(E[:, ::2] - b[None, ::2], axis=1)
        # a frame's light cannot explain most of the gap between the classes: this keeps a
        # frame filled by one material from being read as the other under another light
        bound = 0.4 * abs(mu_hi - mu_lo)
        a = np.clip(a, np.median(a) - bound, np.median(a) + bound)
        b_raw = np.median(E[::2] - a[::2, None], axis=0)
        b = gaussian_filter1d(b_raw, sigma_s, mode="nearest").astype(np.float32)
        b -= b.mean()
        if max(float(np.max(np.abs(a - np.median(a) - a_prev))), float(np.max(np.abs(b - b_prev)))) < tol:
            break  # converged: gains steady to 0.01%
    # every frame's gain, with the class levels and b(s) found above
    L -= b[None, :]
    thr = 0.5 * (mu_hi + mu_lo)
    a_med = float(np.median(a))
    a_all = np.empty(n_t, np.float32)
    for lo in range(0, n_t, 512):  # in blocks: no full-size temporaries
        blk = L[lo: lo + 512, ::2]
        guess = blk - a_med
        level = np.where(guess > thr, np.float32(mu_hi), np.float32(mu_lo))
        a_all[lo: lo + 512] = np.clip(np.median(blk - level, axis=1), a_med - bound, a_med + bound)
    L -= a_all[:, None]
    R = L  # corrected log values, in place
    sub = R[:: max(1, n_t // 400), ::2]
    mu_hi, mu_lo, eta, _ = _class_levels(sub)
    frac_hi = float((sub > 0.5 * (mu_hi + mu_lo)).mean())
    averaged = None
    if LOW_SEPARATION_ETA <= eta < MIN_SEPARATION_ETA and confirm_px > 1:  # weak: looked for again, averaged
        from .._filters import uniform_filter1d

        _, averaged = _otsu(uniform_filter1d(R[:: max(1, n_t // 400)], int(confirm_px), axis=1)[:, ::2])
    if background_level is not None and background_level > 0:
        bg = np.log(background_level) - a_med
        plugs_high = abs(mu_hi - bg) > abs(mu_lo - bg)
    else:  # plugs carry the grain texture: the class with the larger spread
        thr = 0.5 * (mu_hi + mu_lo)
        plugs_high = np.std(sub[sub > thr]) > np.std(sub[sub <= thr])
    mu_plug, mu_bub = (mu_hi, mu_lo) if plugs_high else (mu_lo, mu_hi)
    # contrast in linear intensity: optical blur, pixel and band averaging mix the two
    # materials linearly, so an edge lies where the light is halfway between their levels
    lp, lb = np.float32(np.exp(mu_plug)), np.float32(np.exp(mu_bub))
    denom = lp - lb
    z = np.exp(R, out=R)
    if denom != 0:
        z -= lb
        z /= denom
    else:
        z[:] = 0
    plug_fraction = frac_hi if plugs_high else 1 - frac_hi
    separated = eta >= MIN_SEPARATION_ETA or (averaged is not None and averaged >= CONFIRMED_ETA)
    two_phase = bool(separated and MIN_CLASS_FRACTION <= plug_fraction <= 1 - MIN_CLASS_FRACTION)
    return Normalized(
        z=z, frame_gain=np.exp(a_all - a_med), position_gain=np.exp(b),
        plug_level=float(np.exp(mu_plug + a_med)), bubble_level=float(np.exp(mu_bub + a_med)),
        plugs_darker=bool(not plugs_high), separation_eta=eta, plug_fraction=plug_fraction,
        two_phase=two_phase, averaged_eta=averaged,
    )
