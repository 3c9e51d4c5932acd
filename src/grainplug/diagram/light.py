"""The lamp's light, read beside the tube, frame by frame and row by row.

A back-lit tube stands in front of the lamp it is seen against; the background beside the tube is
that lamp. Its level at each position along the tube and in each frame is the light the tube's
contents were seen under there and then: mains ripple, a slow drift, a shadow passing along the
tube (someone walking by the lamp). Dividing the diagram by it, before plugs and bubbles are told
apart, leaves the contents only. The light is sampled every few positions
(each sample their mean: :data:`grainplug.diagram.extract.BESIDE_STEP`) and interpolated between,
never smoothed in time.

A front-lit tube has no lamp beside it (the background is dark), nor has a tube framed without
background beside it: the light is then read on the diagram itself, frame by frame
(:func:`frame_light`). The contents move little between consecutive frames while a lamp's ripple
scales every position alike, so the median along the tube of the log ratio of a frame to the one
before is the light's change between them; chained over the record and taken about its running
mean (:data:`FRAME_WINDOW` frames, applied twice: a triangle, which neither takes in nor overshoots a ripple of
a few frames a period), it is the ripple and the flicker, and the diagram is divided
by it before doubtful frames are looked for (a ripple of +-30 % was taken for dark and
over-exposed frames and 44 % of the frames bridged). The slow drift is left to the diagram's own
per-frame gain (:func:`grainplug.diagram.normalize`). A frame
that is not its neighbour times one factor (a blank frame, a flash) is not divided:
it is left to :func:`grainplug.diagram.frames.repair_frames`.

*A passing shadow without a lamp beside the tube* (:func:`moving_light`) is read on the contents
themselves, once plugs and bubbles are told apart: each material has one level (a plug's grains, a
bubble's air), so a pixel's log ratio to its material's level is the light there, apart from the
texture and the noise. Averaged over a few millimetres and a few hundredths of a second (weighted by
each material's brightness: the lit material says the most; the samples beside an edge between the
materials, and the still objects over the tube, blind or seen through, left out) and taken about each
position's median over the record (what stays is the still light, the diagram's own per-position
gain's), it is the light that moves:
a shadow passing along the tube. What stays under 5 % is left alone, and nothing is divided unless
it changes at least 1 % of the diagram by more than 10 %. On an independent renderer's
front-lit tube, a 40 % shadow 6 mm wide crossing at 40 mm/s cut the plugs by 26-38 %, silently; read
this way, they are within 0.3 %.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._format import rounded
from .normalize import Normalized

#: the background beside the tube must be at least this share of the tube's brightest contents to be a lamp
LAMP_SHARE = 0.5
#: a lamp dimmer than this share of its median (a clamp's shadow on the probes) is not trusted there
TRUSTED_SHARE = 0.25
#: a lamp steadier than this (rms of its frame-to-frame level, and deepest local dimming, relative) is not divided
#: by: the diagram's own per-frame and per-position gains take what is left
STEADY_RIPPLE, STEADY_SHADOW = 0.005, 0.06
#: frames over which the light read on the diagram itself is averaged: what changes slower is left to the diagram's
#: own per-frame gain (a ripple aliased to fewer than this many frames a period is taken out)
FRAME_WINDOW = 16
#: a pair of frames whose log ratio spreads along the tube this many times the typical pair's is not one frame
#: scaled from the other
SCALED_SPREAD = 3.0
#: positions along the tube read for the light on the diagram itself, at most
FRAME_POSITIONS = 256


@dataclass(frozen=True)
class Lamp:
    """What the background beside the tube said of the light.

    Attributes
    ----------
    corrected : bool
        Whether the diagram was divided by the lamp's light.
    source : str
        What the light was read on, or why it was not corrected.
    ripple_rms : float or None
        The frame-to-frame rms of the lamp's level, relative to its median (flicker, mains ripple).
    shadow_depth : float or None
        The deepest local dimming along the tube, relative to the frame's level (a passing shadow).
    """

    corrected: bool
    source: str
    ripple_rms: float | None = None
    shadow_depth: float | None = None

    def as_dict(self) -> dict[str, object]:
        return {"corrected": self.corrected, "source": self.source, "ripple_rms": rounded(self.ripple_rms, 4),
                "shadow_depth": rounded(self.shadow_depth, 4)}


def lamp_light(beside: np.ndarray, at: np.ndarray, n_positions: int) -> np.ndarray | None:
    """The lamp's level ``(n_frames, n_positions)`` from the background beside the tube (``beside``: frames x
    samples at positions ``at``, each the mean over a few positions), linearly interpolated between them and held
    beyond them; None when they cover too little of the tube."""
    at = np.asarray(at, float)
    if not _covers(beside, at, n_positions):
        return None
    idx = np.arange(n_positions, dtype=float)
    j = np.clip(np.searchsorted(at, idx) - 1, 0, len(at) - 2)
    f = np.clip((idx - at[j]) / np.maximum(at[j + 1] - at[j], 1e-9), 0.0, 1.0).astype(np.float32)
    b = np.asarray(beside, np.float32)
    return b[:, j] * (1 - f) + b[:, j + 1] * f


def _covers(beside: np.ndarray, at: np.ndarray, n_positions: int) -> bool:
    """Whether the samples beside the tube (at positions ``at``) reach over half of its view."""
    return beside.shape[1] == len(at) and len(at) >= 4 and float(np.ptp(at)) >= 0.5 * n_positions


def frame_light(values: np.ndarray, *, window: int = FRAME_WINDOW) -> tuple[np.ndarray, float, float]:
    r"""The light's fast change from frame to frame, read on the diagram itself (no lamp beside the tube).

    Parameters
    ----------
    values : ndarray, shape (n_frames, n_positions)
        The diagram.
    window : int
        Frames of the running mean the level is taken about (the slow light is not returned).

    Returns
    -------
    gain : ndarray, shape (n_frames,)
        Each frame's light relative to the frames around it (1 for a frame that is not its neighbour
        scaled by one factor, and for one whose light would be under :data:`TRUSTED_SHARE` or over its inverse).
    ripple_rms : float
        The rms of ``log gain`` over the frames read (the ripple's relative rms).
    noise_rms : float
        What the same figure would be from the contents and the noise alone, in a steady light.

    Notes
    -----
    With :math:`\ell_k(s) = \log D_k(s)`, the step between consecutive frames is
    :math:`m_k = \mathrm{median}_s(\ell_k - \ell_{k-1})`: a lamp scales every position alike, the contents
    change at a few (the plugs' edges, the falling grains). Its spread (the median absolute deviation) says
    whether frame ``k`` is frame ``k-1`` under another light; where it is not (a blank frame, a flash), or the
    step is beyond :data:`TRUSTED_SHARE`, the chain breaks, and each stretch is read on its own. The level
    :math:`L_k = \sum m` less its running mean over ``window`` frames taken twice (a triangular window of
    ``2 window`` frames: its response has no negative lobe, so a ripple of 10 frames a period is not overshot,
    and a change every other frame cancels in it) is returned, so the chain's error (a random walk) does not
    build up over the record.
    """
    v = np.asarray(values, np.float32)
    n, p = v.shape
    if n < 3 or p < 8:
        return np.ones(n, np.float32), 0.0, 0.0
    v = v[:, :: max(1, -(-p // FRAME_POSITIONS))]
    floor = np.float32(max(1e-3 * float(np.median(v[:: max(1, n // 200)])), 1e-6))
    lv = np.log(np.maximum(v, floor))
    d = lv[1:] - lv[:-1]
    step = np.median(d, axis=1)
    spread = np.median(np.abs(d - step[:, None]), axis=1)
    del d
    typical = float(np.median(spread))
    # pair (k-1, k) is frame k-1 in another light: its log ratio is one number along the tube, and a lamp's
    # number (a blank frame, a flash, a cut is not: the chain breaks there)
    scaled = (spread <= SCALED_SPREAD * max(typical, 1e-6)) & (np.abs(step) <= -np.log(TRUSTED_SHARE))
    piece = np.concatenate(([0], np.cumsum(~scaled)))  # stretches of frames joined by scaled pairs
    gain = np.ones(n, np.float32)
    fast_all = []
    for k in np.unique(piece):
        idx = np.flatnonzero(piece == k)
        if len(idx) < 3:  # a frame or two apart: left to the bridging of doubtful frames
            continue
        level = np.concatenate(([0.0], np.cumsum(step[idx[1:] - 1])))
        fast = level - _running_mean(_running_mean(level, window), window)  # triangular: no negative lobe
        gain[idx] = np.exp(fast)
        fast_all.append(fast)
    if not fast_all:
        return gain, 0.0, 0.0
    fast = np.concatenate(fast_all)
    gain[(gain < TRUSTED_SHARE) | (gain > 1 / TRUSTED_SHARE)] = 1.0
    # a steady light's figure: the steps' own error (median of p values: 1.25 sd / sqrt(p)), over the window
    noise = 1.4826 * 1.25 * typical / np.sqrt(v.shape[1])
    return gain, float(np.std(fast)), float(noise * np.sqrt(0.5 * min(window, n)))


def _running_mean(x: np.ndarray, window: int) -> np.ndarray:
    """The mean of ``x`` over ``window`` samples centred on each (an even window: the two end samples at half
    weight, so that a change every other frame cancels), over those there are at the record's ends."""
    h = max(1, window // 2)
    n = len(x)
    c = np.concatenate(([0.0], np.cumsum(x)))
    i = np.arange(n)
    lo, hi = np.maximum(i - h, 0), np.minimum(i + h + 1, n)
    out = (c[hi] - c[lo]) / (hi - lo)
    inner = (i >= h) & (i + h < n)
    k = i[inner]
    out[inner] = (c[k + h + 1] - c[k - h] - 0.5 * (x[k - h] + x[k + h])) / (2 * h)
    return out


def _from_the_diagram(v: np.ndarray, why: str) -> tuple[np.ndarray, Lamp]:
    """The diagram divided by the light read on itself (:func:`frame_light`) when it flickers; ``why`` says why
    there was no lamp beside the tube to read it on."""
    gain, ripple, noise = frame_light(v)
    if ripple < max(STEADY_RIPPLE, 3.0 * noise):
        return v, Lamp(False, f"{why}: each frame's level against the frames around it, read on the diagram itself, "
                              "is steady; the drift from the diagram's own per-frame gain; a passing shadow is read "
                              "on the contents", ripple)
    return v / gain[:, None], Lamp(
        True, f"{why}: each frame's level against the frames around it, read on the diagram itself (ripple, "
              f"flicker; over {FRAME_WINDOW} frames); the drift from the diagram's own per-frame gain; a passing "
              "shadow is read on the contents", ripple)


def divide_by_lamp(values: np.ndarray, beside: np.ndarray, at: np.ndarray, *,
                   back_lit: bool | None) -> tuple[np.ndarray, Lamp]:
    """The diagram divided by the lamp's light (scaled back to its median level), and what was done; ``beside``
    and ``at`` as :func:`lamp_light` takes them. Without a lamp beside the tube, the light is read on the diagram
    itself (:func:`frame_light`)."""
    v = np.asarray(values, np.float32)
    if not back_lit:
        return _from_the_diagram(v, "front light (no lamp beside the tube)")
    b = np.asarray(beside, np.float32)
    if not _covers(b, np.asarray(at, float), v.shape[1]):
        return _from_the_diagram(v, "no background beside the tube in the frame")
    few = b[:: max(1, len(b) // 500)]  # the light's figures, on at most 500 frames
    typical = float(np.median(few))
    top = float(np.percentile(v[:: max(1, len(v) // 200)], 95))
    if not typical > LAMP_SHARE * top:
        return _from_the_diagram(v, "the background beside the tube is darker than the tube (not a lamp)")
    rel = few / np.maximum(np.median(few, axis=0), 1e-6)[None, :]
    frame_level = np.median(rel, axis=1)
    ripple = float(np.std(frame_level))
    lit = frame_level > 0.1  # a frame the lamp does not light (blank, dropped) says nothing of a shadow
    shadow = float(np.max(1.0 - rel[lit].min(axis=1) / frame_level[lit])) if lit.any() else 0.0
    if ripple < STEADY_RIPPLE and shadow < STEADY_SHADOW:  # a steady lamp: the diagram's own gains suffice
        return v, Lamp(False, "the lamp beside the tube is steady: nothing to correct", ripple, shadow)
    gain = lamp_light(b, at, v.shape[1])  # in place below: relative to its median, 1 where a clamp shades it
    gain[gain <= TRUSTED_SHARE * typical] = typical
    gain /= np.float32(typical)
    np.divide(v, gain, out=gain)
    return gain, Lamp(True, "the background beside the tube, row by row and frame by frame", ripple, shadow)


#: a moving light weaker than this (relative, in logarithm) is not corrected: the texture's and the noise's share
SHADOW_FLOOR = 0.05
#: ... nor one that changes less than this share of the diagram by more than twice that
SHADOW_MIN_SHARE = 0.01
#: the time over which the moving light is averaged, s
SHADOW_WINDOW_S = 0.03


@dataclass(frozen=True)
class MovingLight:
    """A light that moves along the tube (a passing shadow), read on the contents (:func:`moving_light`).

    Attributes
    ----------
    log_gain : ndarray or None
        Its logarithm at every frame and position (the diagram's shape); None when none was found.
    depth : float
        The deepest dimming (relative: 0.4 is 40 % darker).
    share : float
        The share of the diagram it changes by more than twice :data:`SHADOW_FLOOR`.
    """

    log_gain: np.ndarray | None
    depth: float = 0.0
    share: float = 0.0

    def then(self, other: MovingLight) -> MovingLight:
        """This light and ``other``, read after this one was divided out: their product."""
        if self.log_gain is None or other.log_gain is None:
            return other if self.log_gain is None else self
        g = self.log_gain + other.log_gain
        return MovingLight(g, float(1.0 - np.exp(min(float(g.min()), 0.0))),
                           float(np.mean(np.abs(g) > np.float32(SHADOW_FLOOR))))

    def divide(self, values: np.ndarray) -> np.ndarray:
        """``values`` with this light divided out (float32)."""
        v = np.asarray(values, np.float32)
        return v if self.log_gain is None else (v * np.exp(-self.log_gain)).astype(np.float32)


def moving_light(norm: Normalized, *, fps: float, window_px: int, edge_px: int,
                 blind: np.ndarray | None = None) -> MovingLight:
    """The light that moves along the tube, read on the contents (see module notes).

    Parameters
    ----------
    norm : Normalized
        The diagram's two materials and contrast (:func:`grainplug.diagram.normalize`).
    fps : float
        Frame rate: the light is averaged over :data:`SHADOW_WINDOW_S`.
    window_px : int
        Positions along the tube it is averaged over.
    edge_px : int
        Samples beside an edge between the materials left out (its blur, a codec's smear).
    blind : ndarray of bool, optional
        Positions whose contents are hidden (clamps, labels): left out.
    """
    from .._filters import minimum_filter1d, uniform_filter1d

    z = norm.z
    lp, lb = float(norm.plug_level), float(norm.bubble_level)
    top = max(lp, lb, 1e-9)
    plug = z > 0.5
    level = z * np.float32(lp - lb) + np.float32(lb)  # the pixel's light at unit gains
    ref = np.where(plug, np.float32(lp), np.float32(lb))
    r = np.log(np.maximum(level, np.float32(1e-3 * top)) / ref).astype(np.float32)
    w = np.where(plug, np.float32((lp / top) ** 2), np.float32((lb / top) ** 2))
    steady = np.ones(z.shape, np.float32)
    steady[:, 1:] = plug[:, 1:] == plug[:, :-1]
    w *= minimum_filter1d(steady, 2 * edge_px + 1, axis=1)  # 0 within edge_px of a change of material
    if blind is not None and np.any(blind):
        w[:, np.asarray(blind, bool)] = 0
    frames = max(3, int(round(SHADOW_WINDOW_S * fps)) | 1)
    num = uniform_filter1d(uniform_filter1d(r * w, frames, axis=0, mode="nearest"), window_px, axis=1,
                           mode="nearest")
    den = uniform_filter1d(uniform_filter1d(w, frames, axis=0, mode="nearest"), window_px, axis=1, mode="nearest")
    g = np.where(den > 1e-3, num / np.maximum(den, 1e-9), np.float32(0)).astype(np.float32)
    g -= np.median(g[:: max(1, len(g) // 400)], axis=0)[None, :]  # the still light is the per-position gain's
    g = np.sign(g) * np.maximum(np.abs(g) - np.float32(SHADOW_FLOOR), 0)  # the texture's and the noise's share
    share = float(np.mean(np.abs(g) > np.float32(SHADOW_FLOOR)))  # changed by more than twice the floor
    if share < SHADOW_MIN_SHARE:
        return MovingLight(None, 0.0, share)
    return MovingLight(g.astype(np.float32), float(1.0 - np.exp(min(float(g.min()), 0.0))), share)
