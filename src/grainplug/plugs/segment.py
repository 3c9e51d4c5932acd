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
samples; a run touching either end of the view has that edge missing (NaN), and so has a run
touching a blind stretch (a clamp, a label: positions whose contents are hidden).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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


def _runs_2d(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every run of True along the rows of ``mask``: row, start, stop (``[start, stop)``)."""
    n, m = mask.shape
    padded = np.zeros((n, m + 2), np.int8)
    padded[:, 1:-1] = mask
    d = np.diff(padded, axis=1)
    rows, starts = np.nonzero(d == 1)  # row-major order: the k-th start pairs with the k-th stop
    _, stops = np.nonzero(d == -1)
    return rows, starts, stops


def close_rows(mask: np.ndarray, length: int) -> np.ndarray:
    """Binary closing along the rows by a flat segment of ``length`` samples.

    The same as ``ndimage.binary_closing(mask, structure=np.ones((1, length)),
    border_value=0)`` (tested), computed as a running maximum then minimum over
    8-bit rows, about four times faster.
    """
    from .._filters import maximum_filter1d, minimum_filter1d
    m = np.ascontiguousarray(mask, dtype=bool).view(np.uint8)
    grown = maximum_filter1d(m, length, axis=1, origin=-1 if length % 2 == 0 else 0)
    return minimum_filter1d(grown, length, axis=1).view(bool)


def plug_mask(z: np.ndarray, *, mm_per_sample: float, min_plug_mm: float = 3.0,
              min_gap_mm: float = 0.6, blind: np.ndarray | None = None) -> np.ndarray:
    """Boolean plug mask of the diagram (frames x positions).

    ``blind``: positions (a boolean per sample along the tube) whose contents are hidden (a clamp, a
    label): no plug there, and what is left of a plug beside them is kept only if it is ``min_plug_mm``
    long (as a plug cut by the end of the view).
    """
    from .._filters import gaussian_filter
    zs = gaussian_filter(np.asarray(z, np.float32), (0.7, 0.7), mode="nearest")
    mask = zs > 0.5
    gap = max(1, int(round(min_gap_mm / mm_per_sample)))
    mask = close_rows(mask, gap + 1) | mask
    if blind is not None and np.any(blind):
        mask[:, np.asarray(blind, bool)] = False
    min_len = max(1, int(round(min_plug_mm / mm_per_sample)))
    rows, starts, stops = _runs_2d(mask)
    short = stops - starts < min_len
    # clear the short runs, pixel by pixel (they are short: few pixels, no full-size temporaries)
    lengths = (stops - starts)[short]
    first = rows[short] * mask.shape[1] + starts[short]
    within = np.arange(int(lengths.sum())) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    out = np.ascontiguousarray(mask)
    out.reshape(-1)[np.repeat(first, lengths) + within] = False
    return out


def _crossings(zs: np.ndarray, rows: np.ndarray, i_out: np.ndarray, i_in: np.ndarray) -> np.ndarray:
    """Sub-sample positions of the 0.5 crossings of ``zs[rows]`` between samples ``i_out`` and ``i_in``."""
    a = zs[rows, i_out].astype(np.float64)
    b = zs[rows, i_in].astype(np.float64)
    d = b - a
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where(d == 0, 0.5, np.clip((0.5 - a) / np.where(d == 0, 1.0, d), 0.0, 1.0))
    return i_out + f * (i_in - i_out)


def find_runs(z: np.ndarray, mask: np.ndarray, position_mm: np.ndarray, *, blind: np.ndarray | None = None) -> Runs:
    """Runs of the mask with sub-pixel edges measured on ``z``; an edge against a ``blind`` position (as at an
    end of the view) is missing (NaN): the plug is cut there."""
    from .._filters import gaussian_filter1d
    zs = gaussian_filter1d(np.asarray(z, np.float32), 0.7, axis=1, mode="nearest")
    n_s = z.shape[1]
    ds = float(position_mm[1] - position_mm[0]) if n_s > 1 else 1.0
    s0 = float(position_mm[0])
    rows, starts, stops = _runs_2d(mask)
    tops = np.full(len(rows), np.nan)
    bots = np.full(len(rows), np.nan)
    inner = starts > 0
    tops[inner] = s0 + ds * _crossings(zs, rows[inner], starts[inner] - 1, starts[inner])
    inner = stops < n_s
    bots[inner] = s0 + ds * _crossings(zs, rows[inner], stops[inner], stops[inner] - 1)
    if blind is not None and np.any(blind):
        b = np.asarray(blind, bool)
        tops[(starts > 0) & b[np.maximum(starts - 1, 0)]] = np.nan
        bots[(stops < n_s) & b[np.minimum(stops, n_s - 1)]] = np.nan
    return Runs(rows.astype(int), starts.astype(int), stops.astype(int), tops, bots)
