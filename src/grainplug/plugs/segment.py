"""Plugs in each frame of the diagram: runs of grains with sub-pixel edges.

Notes
-----
The contrast ``z`` (0 bubble, 1 plug) is smoothed lightly (Gaussian, ``sigma``
of 0.7 frame and 0.7 sample) and thresholded at 0.5. Along the tube, holes in a
plug shorter than ``min_gap_mm`` are filled (a crack or a texture patch, not a
bubble) and grain runs shorter than ``min_plug_mm`` are dropped (falling
grains, clusters; the paper keeps regions longer than 3 mm). Each remaining run
is a plug in that frame. Its upper and lower edges are where ``z``, smoothed
along the tube only, crosses 0.5, found by linear interpolation between
samples; a run touching either end of the view has that edge missing (NaN).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage


@dataclass(frozen=True)
class Runs:
    """All plugs of all frames, one row per (frame, plug).

    Attributes
    ----------
    frame : ndarray of int
        Frame index.
    start, stop : ndarray of int
        Sample range ``[start, stop)`` of the run along the tube.
    top_mm, bottom_mm : ndarray of float
        Upper (upstream) and lower (downstream) edge, NaN where the run is cut
        by the end of the view.
    """

    frame: np.ndarray
    start: np.ndarray
    stop: np.ndarray
    top_mm: np.ndarray
    bottom_mm: np.ndarray

    def __len__(self) -> int:
        return len(self.frame)

    def in_frame(self, k: int) -> np.ndarray:
        """Indices of the runs of frame ``k``."""
        lo = np.searchsorted(self.frame, k, "left")
        hi = np.searchsorted(self.frame, k, "right")
        return np.arange(lo, hi)


def _runs_1d(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    padded = np.concatenate(([False], mask, [False]))
    d = np.diff(padded.astype(np.int8))
    return np.nonzero(d == 1)[0], np.nonzero(d == -1)[0]


def plug_mask(z: np.ndarray, *, mm_per_sample: float, min_plug_mm: float = 3.0,
              min_gap_mm: float = 0.6) -> np.ndarray:
    """Boolean plug mask of the diagram (frames x positions)."""
    zs = ndimage.gaussian_filter(z.astype(np.float32), (0.7, 0.7), mode="nearest")
    mask = zs > 0.5
    gap = max(1, int(round(min_gap_mm / mm_per_sample)))
    mask = ndimage.binary_closing(mask, structure=np.ones((1, gap + 1), bool), border_value=0) | mask
    min_len = max(1, int(round(min_plug_mm / mm_per_sample)))
    out = np.zeros_like(mask)
    for k in range(mask.shape[0]):
        starts, stops = _runs_1d(mask[k])
        for a, b in zip(starts, stops, strict=True):
            if b - a >= min_len:
                out[k, a:b] = True
    return out


def _crossing(profile: np.ndarray, i_out: int, i_in: int) -> float:
    """Sub-sample position of the 0.5 crossing between samples ``i_out`` and ``i_in``."""
    a, b = float(profile[i_out]), float(profile[i_in])
    if a == b:
        return 0.5 * (i_out + i_in)
    f = np.clip((0.5 - a) / (b - a), 0.0, 1.0)
    return i_out + f * (i_in - i_out)


def find_runs(z: np.ndarray, mask: np.ndarray, position_mm: np.ndarray) -> Runs:
    """Runs of the mask with sub-pixel edges measured on ``z``."""
    zs = ndimage.gaussian_filter1d(z.astype(np.float32), 0.7, axis=1, mode="nearest")
    n_s = z.shape[1]
    ds = float(position_mm[1] - position_mm[0]) if n_s > 1 else 1.0
    s0 = float(position_mm[0])
    frames, starts, stops, tops, bots = [], [], [], [], []
    for k in range(z.shape[0]):
        st, sp = _runs_1d(mask[k])
        prof = zs[k]
        for a, b in zip(st, sp, strict=True):
            top = np.nan if a == 0 else s0 + ds * _crossing(prof, a - 1, a)
            bot = np.nan if b == n_s else s0 + ds * _crossing(prof, b, b - 1)
            frames.append(k)
            starts.append(a)
            stops.append(b)
            tops.append(top)
            bots.append(bot)
    return Runs(np.asarray(frames, int), np.asarray(starts, int), np.asarray(stops, int),
                np.asarray(tops, float), np.asarray(bots, float))
