"""Per-track numbers: the speed of one plug's edge over its life.

One function, used by the tracks table (:func:`grainplug.summary.track_rows`) and by the check
for still objects over the tube (:func:`grainplug.checks.still_objects`), so both read a track's
motion alike.
"""

from __future__ import annotations

import numpy as np


def followed_edge(top_mm: np.ndarray, bottom_mm: np.ndarray) -> np.ndarray:
    """The edge a track's speed is read on: its upstream edges, or its downstream ones when fewer than
    two upstream edges are in view (NaN where the edge is cut by the view)."""
    return top_mm if np.isfinite(top_mm).sum() >= 2 else bottom_mm


def edge_speed_mm_s(time_s: np.ndarray, top_mm: np.ndarray, bottom_mm: np.ndarray) -> float:
    """Slope (mm/s, positive downstream) of a straight line fitted to one track's :func:`followed_edge`
    against time; NaN with fewer than two edges in view or no time between them.

    Parameters
    ----------
    time_s : ndarray
        Time of each of the track's frames.
    top_mm, bottom_mm : ndarray
        Its upstream and downstream edges in those frames (NaN where cut by the view).
    """
    edge = followed_edge(top_mm, bottom_mm)
    ok = np.isfinite(edge)
    if ok.sum() < 2 or np.ptp(time_s[ok]) <= 0:
        return float("nan")
    return float(np.polyfit(time_s[ok], edge[ok], 1)[0])
