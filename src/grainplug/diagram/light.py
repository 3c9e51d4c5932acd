"""The lamp's light, read beside the tube, frame by frame and row by row.

A back-lit tube stands in front of the lamp it is seen against; the background beside the tube is
that lamp. Its level at each position along the tube and in each frame is the light the tube's
contents were seen under there and then: mains ripple, a slow drift, a shadow passing along the
tube (someone walking by the lamp). Dividing the diagram by it, before plugs and bubbles are told
apart, leaves the contents only. A front-lit tube has no lamp beside it (the background is dark):
nothing is divided, and the diagram's own per-frame gain (:func:`grainplug.diagram.normalize`) takes
the ripple and the drift; a passing shadow is then not corrected.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: the background beside the tube must be at least this share of the tube's brightest contents to be a lamp
LAMP_SHARE = 0.5
#: the lamp's light is smoothed along the tube over this many samples (noise), never in time (ripple)
SMOOTH_SAMPLES = 3.0
#: a lamp dimmer than this share of its median (a clamp's shadow on the probes) is not trusted there
TRUSTED_SHARE = 0.25


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
        def r(x: float | None) -> float | None:
            return None if x is None or not np.isfinite(x) else round(float(x), 4)

        return {"corrected": self.corrected, "source": self.source, "ripple_rms": r(self.ripple_rms),
                "shadow_depth": r(self.shadow_depth)}


def lamp_light(beside: np.ndarray, where: np.ndarray) -> np.ndarray | None:
    """The lamp's level ``(n_frames, n_positions)`` from the background beside the tube (``beside``: frames x the
    positions ``where`` the frame reaches it; the others take the nearest one's level); None when too few
    positions are seen."""
    from .._filters import gaussian_filter1d

    n_positions = len(where)
    if where.sum() < max(8, n_positions // 4) or beside.shape[1] != where.sum():
        return None
    level = np.empty((len(beside), n_positions), np.float32)
    idx = np.arange(n_positions)
    seen = idx[where]
    nearest = seen[np.clip(np.searchsorted(seen, idx), 0, len(seen) - 1)]
    level[:, where] = beside
    if not where.all():
        level[:, ~where] = level[:, nearest[~where]]
    return gaussian_filter1d(level, SMOOTH_SAMPLES, axis=1, mode="nearest")


def divide_by_lamp(values: np.ndarray, beside: np.ndarray, where: np.ndarray, *,
                   back_lit: bool | None) -> tuple[np.ndarray, Lamp]:
    """The diagram divided by the lamp's light (scaled back to its median level), and what was done; ``beside``
    and ``where`` as :func:`lamp_light` takes them."""
    v = np.asarray(values, np.float32)
    if not back_lit:
        return v, Lamp(False, "front light (no lamp beside the tube): the ripple and drift from the diagram's own "
                              "per-frame gain; a passing shadow is not corrected")
    light = lamp_light(beside, where)
    if light is None:
        return v, Lamp(False, "no background beside the tube in the frame: the ripple and drift from the "
                              "diagram's own per-frame gain; a passing shadow is not corrected")
    typical = float(np.median(light))
    top = float(np.percentile(v[:: max(1, len(v) // 200)], 95))
    if not typical > LAMP_SHARE * top:
        return v, Lamp(False, "the background beside the tube is darker than the tube (not a lamp): the ripple and "
                              "drift from the diagram's own per-frame gain; a passing shadow is not corrected")
    gain = light  # in place: the lamp's level relative to its median, 1 where it is not trusted (a clamp's shadow)
    gain[gain <= TRUSTED_SHARE * typical] = typical
    gain /= np.float32(typical)
    frame_level = np.median(gain[:: max(1, len(gain) // 2000)], axis=1)
    ripple = float(np.std(frame_level))
    shadow = float(np.max(1.0 - gain.min(axis=1) / np.median(gain, axis=1))) if gain.size else 0.0
    np.divide(v, gain, out=gain)
    return gain, Lamp(True, "the background beside the tube, row by row and frame by frame", ripple, shadow)
