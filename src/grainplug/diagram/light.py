"""The lamp's light, read beside the tube, frame by frame and row by row.

A back-lit tube stands in front of the lamp it is seen against; the background beside the tube is
that lamp. Its level at each position along the tube and in each frame is the light the tube's
contents were seen under there and then: mains ripple, a slow drift, a shadow passing along the
tube (someone walking by the lamp). Dividing the diagram by it, before plugs and bubbles are told
apart, leaves the contents only. The light is sampled every few positions
(each sample their mean: :data:`grainplug.diagram.extract.BESIDE_STEP`) and interpolated between,
never smoothed in time. A front-lit tube has no lamp beside it (the background is dark):
nothing is divided, and the diagram's own per-frame gain (:func:`grainplug.diagram.normalize`) takes
the ripple and the drift; a passing shadow is then not corrected.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._format import rounded

#: the background beside the tube must be at least this share of the tube's brightest contents to be a lamp
LAMP_SHARE = 0.5
#: a lamp dimmer than this share of its median (a clamp's shadow on the probes) is not trusted there
TRUSTED_SHARE = 0.25
#: a lamp steadier than this (rms of its frame-to-frame level, and deepest local dimming, relative) is not divided
#: by: the diagram's own per-frame and per-position gains take what is left
STEADY_RIPPLE, STEADY_SHADOW = 0.005, 0.06


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


def divide_by_lamp(values: np.ndarray, beside: np.ndarray, at: np.ndarray, *,
                   back_lit: bool | None) -> tuple[np.ndarray, Lamp]:
    """The diagram divided by the lamp's light (scaled back to its median level), and what was done; ``beside``
    and ``at`` as :func:`lamp_light` takes them."""
    v = np.asarray(values, np.float32)
    if not back_lit:
        return v, Lamp(False, "front light (no lamp beside the tube): the ripple and drift from the diagram's own "
                              "per-frame gain; a passing shadow is not corrected")
    b = np.asarray(beside, np.float32)
    if not _covers(b, np.asarray(at, float), v.shape[1]):
        return v, Lamp(False, "no background beside the tube in the frame: the ripple and drift from the "
                              "diagram's own per-frame gain; a passing shadow is not corrected")
    few = b[:: max(1, len(b) // 500)]  # the light's figures, on at most 500 frames
    typical = float(np.median(few))
    top = float(np.percentile(v[:: max(1, len(v) // 200)], 95))
    if not typical > LAMP_SHARE * top:
        return v, Lamp(False, "the background beside the tube is darker than the tube (not a lamp): the ripple and "
                              "drift from the diagram's own per-frame gain; a passing shadow is not corrected")
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
