"""Frames in which the tube is not in view: something passed in front of it, the camera was knocked off it, the
lamp went out for longer than a flicker.

Such frames carry no plug flow, and a stretch of them is too long to bridge by interpolation (the frames'
repair, :mod:`grainplug.diagram.frames`, bridges a few frames unlike their neighbours). The tube's walls tell:
they are the same in every frame where the tube is seen, whatever the grains do inside it. Each profile across
the tube (:func:`grainplug.diagram.probes_along_tube`) is compared, frame by frame, with its median over the
record; a frame whose profiles no longer look like the walls' is one where the tube is not seen.

Notes
-----
The likeness is the correlation, over the profile's samples, between the frame's profile and the median one,
each about its mean — insensitive to the lamp's level and gain (ripple, a shadow) — at the best of the whole-pixel
shifts within ``SHIFT_PX`` (a camera's shake and wander move the walls). The bore's samples are left out (the grains
change them); only the outer thirds of the profile, the walls and the background beside them, count.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._filters import true_runs

#: a frame whose walls correlate with the record's below this is one where the tube is not seen
UNSEEN_CORRELATION = 0.5
#: ... judged only on profiles whose median has this much structure (the walls' contrast over the profile's noise)
MIN_STRUCTURE = 3.0
#: the walls are looked for within this many pixels of their median place (a camera's shake and wander)
SHIFT_PX = 6
#: stretches of unseen frames shorter than this are left to the frames' repair (a flicker, a dropped frame)
MIN_UNSEEN_FRAMES = 3


@dataclass(frozen=True)
class TubeView:
    """Which frames show the tube.

    Attributes
    ----------
    unseen : ndarray of bool
        Per frame: the tube's walls are not seen (True), in stretches of at least ``MIN_UNSEEN_FRAMES``.
    likeness : ndarray
        Per frame, the walls' correlation with the record's (median over the profiles; NaN when no profile
        could judge).
    """

    unseen: np.ndarray = field(repr=False)
    likeness: np.ndarray = field(repr=False)

    @property
    def stretches(self) -> list[tuple[int, int]]:
        """The unseen stretches as ``(first, last)`` frame indices."""
        return [(a, b - 1) for a, b in true_runs(self.unseen)]


def unseen_mask(stretches: tuple[tuple[int, int], ...] | list[tuple[int, int]], n_frames: int) -> np.ndarray:
    """Per frame, whether it lies in one of ``stretches`` (``(first, last)`` frame indices)."""
    out = np.zeros(n_frames, bool)
    for a, b in stretches:
        out[a: b + 1] = True
    return out


def tube_view(across: list[np.ndarray], n_frames: int) -> TubeView:
    """Which of ``n_frames`` frames show the tube, from profiles across it (each ``frames x samples``)."""
    scores = []
    for prof in across:
        p = np.asarray(prof, np.float32)
        if p.ndim != 2 or p.shape[0] != n_frames or p.shape[1] < 9:
            continue
        n = p.shape[1]
        k = n // 3
        keep = np.r_[0:k, n - k: n]  # the walls and what is beside them, not the bore
        full = np.median(p, axis=0)
        noise = float(np.median(np.abs(np.diff(p[:, keep], axis=0)))) / 0.954 + 1e-6  # frame to frame, robust
        if float(np.ptp(full[keep])) < MIN_STRUCTURE * noise:
            continue
        best = np.full(n_frames, -np.inf, np.float32)
        for s in range(-SHIFT_PX, SHIFT_PX + 1):  # the walls moved by the camera's shake still match
            idx = keep - s
            ok = (idx >= 0) & (idx < n)
            ref = full[idx[ok]] - full[idx[ok]].mean()
            q = p[:, keep[ok]]
            dev = q - q.mean(axis=1, keepdims=True)
            r = (dev @ ref) / (np.sqrt((dev * dev).sum(axis=1) * float(ref @ ref)) + 1e-12)
            best = np.maximum(best, r)
        scores.append(best)
    if not scores:
        nan = np.full(n_frames, np.nan)
        return TubeView(np.zeros(n_frames, bool), nan)
    likeness = np.median(np.stack(scores), axis=0)
    # only stretches long enough: shorter ones are the frames' repair's (and a noisy frame's dip)
    unseen = unseen_mask([(a, b - 1) for a, b in true_runs(likeness < UNSEEN_CORRELATION, MIN_UNSEEN_FRAMES)],
                         n_frames)
    return TubeView(unseen, likeness)
