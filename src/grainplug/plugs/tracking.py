"""Follow plugs from frame to frame.

Notes
-----
Plugs move by a small part of their length between frames, so a plug of frame
``k+1`` is the continuation of the plug of frame ``k`` it overlaps. When one
plug of frame ``k`` overlaps exactly one plug of frame ``k+1`` and the other
way round, the track goes on. Otherwise tracks end and start: two plugs that
overlap one are a *merge*, one plug that overlaps two is a *split*; a plug with
no predecessor *entered* the view (or the movie began), one with no successor
*left* it (or the movie ended). Merged plugs are composites of several plugs
and are kept apart when plug lengths are averaged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .segment import Runs


@dataclass(frozen=True)
class Tracks:
    """Plug tracks.

    Attributes
    ----------
    run_track : ndarray of int
        Track id of every run (same order as :class:`Runs`).
    first_frame, last_frame : ndarray of int
        Per track.
    started_by, ended_by : list of str
        ``"start"``, ``"entered"``, ``"merge"``, ``"split"`` / ``"end"``, ``"left"``,
        ``"merge"``, ``"split"``; ``"cut"`` either way where a reviewer split a track
        (:mod:`grainplug.corrections`).
    """

    run_track: np.ndarray
    first_frame: np.ndarray
    last_frame: np.ndarray
    started_by: list[str]
    ended_by: list[str]

    def __len__(self) -> int:
        return len(self.first_frame)

    def composite(self, tid: int) -> bool:
        """Whether track ``tid`` is several plugs joined (born of a merge, or ends splitting)."""
        return self.started_by[tid] == "merge" or self.ended_by[tid] == "split"


def _overlapping(frame: np.ndarray, start: np.ndarray, stop: np.ndarray,
                 step: int) -> tuple[np.ndarray, np.ndarray]:
    """For every run, the index range ``[lo, hi)`` of the runs of frame ``frame + step``
    that overlap it (empty when ``hi <= lo``).

    Runs are sorted by frame then start and do not overlap within a frame, so the
    runs of another frame that overlap a run are contiguous: the first whose stop
    lies beyond its start up to the first whose start lies at or beyond its stop.
    """
    span = int(max(stop.max(initial=0), 1)) + 1
    key_stop = frame * span + stop  # sorted: stops increase within a frame
    key_start = frame * span + start
    base = (frame + step) * span
    lo = np.searchsorted(key_stop, base + start, side="right")
    hi = np.searchsorted(key_start, base + stop, side="left")
    return lo, hi


def link(runs: Runs, n_frames: int, *, blind: np.ndarray | None = None) -> Tracks:
    """Link the runs of consecutive frames into tracks; runs of a frame parted only by ``blind`` positions (a
    clamp: a boolean per sample along the tube) are one plug passing under it, linked as one (one track).

    Notes
    -----
    Computed for all frames at once: each run's successors (in the next frame) and
    predecessors (in the previous one) are index ranges found by binary search; a
    run continues the track of its only predecessor when it is that run's only
    successor, and tracks are the chains of such links, numbered in the order they
    start (frame, then position), as a frame-by-frame pass would number them.
    """
    if blind is not None and np.any(blind) and len(runs) > 1:
        hidden = np.concatenate([[0], np.cumsum(np.asarray(blind, bool), dtype=np.int64)])
        frame = np.asarray(runs.frame, np.int64)
        gap = runs.start[1:] - runs.stop[:-1]
        across = (frame[1:] == frame[:-1]) & (gap > 0) & (hidden[runs.start[1:]] - hidden[runs.stop[:-1]] == gap)
        if across.any():
            unit = np.concatenate([[0], np.cumsum(~across)])  # the runs' plug, counted over the record
            first = np.nonzero(np.concatenate([[True], ~across]))[0]
            last = np.concatenate([first[1:] - 1, [len(runs) - 1]])
            units = Runs(frame[first], runs.start[first], runs.stop[last], runs.top_mm[first], runs.bottom_mm[last])
            joined = link(units, n_frames)
            return Tracks(joined.run_track[unit], joined.first_frame, joined.last_frame, joined.started_by,
                          joined.ended_by)
    n = len(runs)
    frame = np.asarray(runs.frame, np.int64)
    start = np.asarray(runs.start, np.int64)
    stop = np.asarray(runs.stop, np.int64)
    if n == 0:
        return Tracks(np.zeros(0, int), np.zeros(0, int), np.zeros(0, int), [], [])
    s_lo, s_hi = _overlapping(frame, start, stop, +1)
    p_lo, p_hi = _overlapping(frame, start, stop, -1)
    n_succ = np.maximum(s_hi - s_lo, 0)
    n_pred = np.maximum(p_hi - p_lo, 0)
    pred = np.where(n_pred == 1, p_lo, 0)
    cont = (n_pred == 1) & (n_succ[np.minimum(pred, n - 1)] == 1) & (frame > 0)
    # follow each chain back to the run that started it (pointer jumping)
    root = np.where(cont, pred, np.arange(n))
    while True:
        nxt = root[root]
        if np.array_equal(nxt, root):
            break
        root = nxt
    head = ~cont
    track_of_head = np.cumsum(head) - 1
    track = track_of_head[root]
    heads = np.nonzero(head)[0]
    first = frame[heads]
    last = np.zeros(len(heads), np.int64)
    np.maximum.at(last, track, frame)
    started = ["start" if frame[h] == 0 else "entered" if n_pred[h] == 0 else
               "merge" if n_pred[h] > 1 else "split" for h in heads.tolist()]
    # each track's last run: how it ended
    succ = np.where(n_succ == 1, s_lo, 0)
    tail = ~((n_succ == 1) & cont[np.minimum(succ, n - 1)])
    ended = ["end"] * len(heads)
    for i in np.nonzero(tail)[0].tolist():
        t = int(track[i])
        if frame[i] >= n_frames - 1:
            continue
        if n_succ[i] == 0:
            ended[t] = "left"
        elif n_succ[i] > 1:
            ended[t] = "split"
        else:
            ended[t] = "merge" if n_pred[succ[i]] > 1 else "split"
    return Tracks(track.astype(int), first.astype(int), last.astype(int), started, ended)
