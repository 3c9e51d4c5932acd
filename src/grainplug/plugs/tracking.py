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
        ``"merge"``, ``"split"``.
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


def link(runs: Runs, n_frames: int) -> Tracks:
    """Link the runs of consecutive frames into tracks."""
    n = len(runs)
    track = -np.ones(n, int)
    first: list[int] = []
    last: list[int] = []
    started: list[str] = []
    ended: list[str] = []

    def new_track(i: int, how: str) -> None:
        track[i] = len(first)
        first.append(int(runs.frame[i]))
        last.append(int(runs.frame[i]))
        started.append(how)
        ended.append("end")

    prev = runs.in_frame(0)
    for i in prev:
        new_track(i, "start")
    for k in range(1, n_frames):
        cur = runs.in_frame(k)
        if len(prev) == 0:
            for i in cur:
                new_track(i, "entered")
            prev = cur
            continue
        # overlap matrix of the runs of the two frames
        ps, pe = runs.start[prev], runs.stop[prev]
        cs, ce = runs.start[cur], runs.stop[cur]
        ov = (np.minimum(pe[:, None], ce[None, :]) - np.maximum(ps[:, None], cs[None, :])) > 0
        n_succ = ov.sum(axis=1)
        n_pred = ov.sum(axis=0)
        for j, i in enumerate(cur):
            preds = np.nonzero(ov[:, j])[0]
            if len(preds) == 1 and n_succ[preds[0]] == 1:
                t = track[prev[preds[0]]]
                track[i] = t
                last[t] = k
            elif len(preds) == 0:
                new_track(i, "entered")
            elif len(preds) > 1:
                new_track(i, "merge")
            else:
                new_track(i, "split")
        for m, i in enumerate(prev):
            t = track[i]
            if last[t] == k:
                continue
            if n_succ[m] == 0:
                ended[t] = "left"
            elif n_succ[m] > 1:
                ended[t] = "split"
            else:
                j = int(np.nonzero(ov[m])[0][0])
                ended[t] = "merge" if n_pred[j] > 1 else "split"
        prev = cur
    # a track that stopped at the last frame ended with the movie; one cut earlier left the view
    for t in range(len(first)):
        if ended[t] == "end" and last[t] < n_frames - 1:
            ended[t] = "left"
    return Tracks(track, np.asarray(first, int), np.asarray(last, int), started, ended)
