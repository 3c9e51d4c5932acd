"""Doubtful frames: dark, over-exposed or repeated frames found in the diagram and bridged.

A lamp that fails for a few frames, a flash, a camera that drops frames and
repeats the last one: such frames are not plug flow, and a tracker that believes
them reads plugs that jump or vanish (five black frames in a 60-frame movie cut
the measured celerity by 85 %). They are found on the diagram itself — the light
along the tube in every frame — and replaced by interpolation in time between
the nearest good frames, and the result says how many and which.

Notes
-----
A frame's level is the mean of its diagram row (it changes smoothly as plugs come
and go: a row's median would flip between the plugs' and the bubbles' levels);
its reference is the median level of the 11 frames around it. Lamp flicker moves the level by a few per cent;
a frame more than ``max_jump`` (30 %) off its reference is **dark** or
**over-exposed**. A frame identical to the one before it, to the last bit, is
**repeated** (sensor noise makes real consecutive frames differ; when more than a
fifth of the frames repeat, the scene is still or noiseless and repeats say nothing). Bad frames are
replaced, position by position, by linear interpolation in time between the
nearest good frames before and after (the first or last good one at the ends).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class FrameRepair:
    """What was found and done.

    Attributes
    ----------
    dark, bright, repeated : ndarray of int
        Indices of the frames of each kind (bridged by interpolation).
    """

    dark: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    bright: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    repeated: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    #: frames that repeat the one before when so many do that the scene is still (not bridged)
    n_still: int = 0

    @property
    def bridged(self) -> np.ndarray:
        """Indices of every frame that was bridged (interpolated, not seen), sorted."""
        return np.union1d(np.union1d(self.dark, self.bright), self.repeated).astype(int)

    @property
    def n_bad(self) -> int:
        return int(len(self.dark) + len(self.bright) + len(self.repeated))

    def describe(self, n_frames: int, *, first: int = 0) -> str | None:
        """One warning line, or None when every frame was good; frames are named ``first`` + their index (the
        movie's numbering in a window that starts at frame ``first``)."""
        still = (f"{self.n_still} of {n_frames} frames repeat the one before exactly: the camera froze, or "
                 "nothing moves in the tube — check the movie; any motion measured comes from the frames "
                 "that change") if self.n_still else None
        if not self.n_bad:
            return still
        parts = []
        for name, idx in (("dark", self.dark), ("over-exposed", self.bright), ("repeated", self.repeated)):
            if len(idx):
                shown = ", ".join(str(first + int(i)) for i in idx[:8]) + (", ..." if len(idx) > 8 else "")
                parts.append(f"{len(idx)} {name} (frame{'s' if len(idx) > 1 else ''} {shown})")
        share = 100 * self.n_bad / max(n_frames, 1)
        bad = (f"{self.n_bad} of {n_frames} frames ({share:.1f} %) were not usable — {'; '.join(parts)} — and were "
               "bridged by interpolating between their neighbours: check the lamp and the camera's frame drops")
        return f"{still}; also {bad}" if still else bad


def repair_frames(values: np.ndarray, *, max_jump: float = 0.3, window: int = 11,
                  top: float | None = None) -> tuple[np.ndarray, FrameRepair]:
    """Find dark, over-exposed and repeated frames in a diagram and bridge them.

    Parameters
    ----------
    values : ndarray, (n_frames, n_positions)
        The raw diagram (light along the tube, one row per frame).
    max_jump : float
        Relative departure of a frame's level from its neighbours' that makes it bad.
    window : int
        Frames around each one that give its reference level.
    top : float, optional
        The sensor's top value: a frame whose mean reaches 98 % of it is over-exposed
        whatever its neighbours.

    Returns
    -------
    values : ndarray
        The diagram with the bad frames replaced (a copy when any was; else the input).
    repair : FrameRepair
        Which frames, of which kind.
    """
    v = np.asarray(values)
    n = v.shape[0]
    if n < 5:
        return v, FrameRepair()
    level = np.mean(v, axis=1, dtype=np.float64)
    half = window // 2
    padded = np.pad(level, half, mode="edge")
    windows = np.lib.stride_tricks.sliding_window_view(padded, window)
    ref = np.median(windows, axis=1)
    scale = max(float(np.median(level)), 1e-9)
    rel = (level - ref) / np.maximum(ref, 1e-3 * scale)
    dark = rel < -max_jump
    bright = rel > max_jump
    if top is not None and top > 0:
        bright |= level >= 0.98 * top
    repeated = np.zeros(n, bool)
    repeated[1:] = np.all(v[1:] == v[:-1], axis=1) & (np.ptp(v[1:], axis=1) > 0)
    n_still = 0
    if repeated.mean() > 0.2:  # a still scene or a frozen camera, not dropped frames: said, not bridged
        n_still = int(repeated.sum())
        repeated[:] = False
    bad = dark | bright | repeated
    if not bad.any() or bad.all():
        return v, FrameRepair(n_still=n_still)
    good = np.flatnonzero(~bad)
    fixed = np.array(v, dtype=np.float32, copy=True)
    for k in np.flatnonzero(bad):
        after = good[np.searchsorted(good, k):]
        before = good[: np.searchsorted(good, k)]
        if len(before) and len(after):
            a, b = before[-1], after[0]
            w = (k - a) / (b - a)
            fixed[k] = (1 - w) * v[a] + w * v[b]
        else:
            fixed[k] = v[before[-1]] if len(before) else v[after[0]]
    repeated &= ~(dark | bright)
    return fixed, FrameRepair(np.flatnonzero(dark), np.flatnonzero(bright), np.flatnonzero(repeated))
