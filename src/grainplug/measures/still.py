"""Blind stretches: places along the tube whose contents cannot be seen (a clamp, a label, a fitting, the
tube's end), given by the user or found where nothing changes over the record while the train moves.

A plug touching a blind stretch is cut there (its edge there is missing, as at an end of the view; its
other edge still times the train), and a bubble across one is not measured (a plug may hide in it):
lengths come only from plugs and bubbles seen whole elsewhere.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..diagram import Diagram
from .lengths import Lengths
from .motion import Motion

#: positions whose grey level varies over the record less than this share of the tube's typical variation are still
STILL_REGION_SHARE = 0.1
#: a still stretch shorter than this (mm) is not taken as blind (a speck of dust)
STILL_MIN_MM = 1.0
#: how a blind stretch was found: given, still over the record, or added on the review page (a correction)
GIVEN, STILL_CONTENTS, REVIEW = "mask_mm", "still contents", "review"


@dataclass(frozen=True)
class BlindStretch:
    """A stretch of the tube whose contents are hidden, in mm from the upstream end of the view.

    Attributes
    ----------
    from_mm, to_mm : float
        Its ends.
    found_by : str
        ``"mask_mm"`` (given), ``"still contents"`` (nothing changed there over the record) or ``"review"``
        (added as a correction).
    kept : bool
        False when a correction removed it (kept in the list, so that the result says what was removed):
        then its positions are measured as any other.
    """

    from_mm: float
    to_mm: float
    found_by: str
    kept: bool = True

    def as_dict(self) -> dict[str, object]:
        return {"from_mm": round(self.from_mm, 3), "to_mm": round(self.to_mm, 3), "found_by": self.found_by,
                "kept": self.kept}


def still_stretches(diagram: Diagram, motion: Motion | None, lengths: Lengths | None) -> list[tuple[float, float]]:
    """The stretches (1 mm or more) where nothing changes over the record while the rest of the tube does.

    Judged only where the plug train travelled a plug and a bubble over the record, so that every place
    should have seen both (in a shorter record a long plug may cover a place throughout); none otherwise.
    """
    if (motion is None or motion.regime != "propagative" or motion.celerity_m_s is None or lengths is None
            or lengths.plug_length_mm is None or lengths.bubble_length_mm is None):
        return []
    travel_mm = abs(motion.celerity_m_s) * 1000.0 * float(diagram.time_s[-1] - diagram.time_s[0])
    if travel_mm < lengths.plug_length_mm + lengths.bubble_length_mm:
        return []
    values = diagram.values
    d = np.asarray(values[:: max(1, values.shape[0] // 1000)], np.float32)
    # in grey levels, not their logarithm: a dark clamp's noise is small in grey levels and large in logarithm
    sd = d.std(axis=0)
    typical = float(np.median(sd))
    if not typical > 0.01 * max(float(np.median(np.abs(d))), 1e-6):  # nothing moves anywhere (a jammed or empty
        return []  # record): no contrast to judge by
    step = np.diff(np.concatenate([[0], (sd < STILL_REGION_SHARE * typical).astype(np.int8), [0]]))
    starts, stops = np.nonzero(step == 1)[0], np.nonzero(step == -1)[0]
    pos, half = diagram.position_mm, 0.5 * diagram.mm_per_px
    return [(float(pos[a] - half), float(pos[b - 1] + half)) for a, b in zip(starts, stops, strict=True)
            if (b - a) * diagram.mm_per_px >= STILL_MIN_MM]


def blind_positions(position_mm: np.ndarray, stretches: tuple[BlindStretch, ...] | list[BlindStretch], *,
                    margin_samples: int = 1) -> np.ndarray:
    """Which positions along the tube (samples of the diagram) are blind: inside a kept stretch, or within
    ``margin_samples`` of it (its edge is blurred into its neighbours)."""
    pos = np.asarray(position_mm, float)
    out = np.zeros(pos.shape, bool)
    for b in stretches:
        if b.kept:
            out |= (pos >= b.from_mm) & (pos <= b.to_mm)
    if margin_samples > 0 and out.any():
        grown = out.copy()
        for k in range(1, margin_samples + 1):
            grown[k:] |= out[:-k]
            grown[:-k] |= out[k:]
        out = grown
    return out
