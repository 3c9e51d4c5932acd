"""Plug and bubble lengths from the tracked edges.

Notes
-----
A plug's length is measured only in frames where both of its edges are in view.
Each track gives one length, the median over its frames (robust to a frame's
poor edge); tracks that are several plugs joined (born of a merge, or ending in
a split) are left out, and so are tracks seen whole in fewer than
``min_frames`` frames. The reported length is the mean over tracks, as the
paper's mean plug length; its 95% interval is Student's over tracks, with the
scale's relative uncertainty added in quadrature.

A bubble is the gap between the lower edge of one plug and the upper edge of
the next in the same frame; bubbles are grouped by the pair of tracks that
bound them and averaged the same way. A pair seen one after the other in fewer
than half of the frames that show both is two plugs with a third between them,
missed in those frames (a shadow, a splash): its gap is no bubble. A plug a reviewer excluded (``walls``) is
not air: the gaps either side of it are cut there, as the view's end cuts a
plug, and are not measured.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from ..plugs import Runs, Tracks


@dataclass(frozen=True)
class Lengths:
    """Mean plug and bubble lengths with their spread."""

    plug_length_mm: float | None
    plug_length_ci95_mm: tuple[float, float] | None
    plug_length_sd_mm: float | None
    per_track_mm: dict[int, float]
    n_plugs_measured: int
    bubble_length_mm: float | None
    bubble_length_ci95_mm: tuple[float, float] | None
    n_bubbles_measured: int
    #: track ids (upstream, downstream) of the plugs either side of each bubble measured
    bubble_tracks: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))
    #: median length of each of those bubbles
    per_bubble_mm: np.ndarray = field(default_factory=lambda: np.zeros(0))


def _mean_ci(values: np.ndarray, scale_rel_sd: float) -> tuple[float, tuple[float, float] | None, float | None]:
    from .._filters import t_quantile_975
    m = float(np.mean(values))
    if len(values) < 2:
        return m, None, None
    sd = float(np.std(values, ddof=1))
    se = np.hypot(sd / np.sqrt(len(values)), m * scale_rel_sd)
    tq = t_quantile_975(len(values) - 1)
    return m, (max(m - tq * se, 0.0), m + tq * se), sd  # a length is never negative: few values, a clipped interval


def _bubble_medians(runs: Runs, tracks: Tracks, min_frames: int, blind: np.ndarray | None = None,
                    walls: Runs | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Median gap between each pair of tracks seen one after the other in a frame
    (the bubble between them), for pairs seen in at least ``min_frames`` frames,
    and the pairs ``(upstream track, downstream track)``; a gap with one of ``walls`` in it is none."""
    track = tracks.run_track
    if walls is not None and len(walls):  # the walls among the runs, by frame then position, with no track
        both = Runs(*(np.concatenate([getattr(runs, f), getattr(walls, f)])
                      for f in ("frame", "start", "stop", "top_mm", "bottom_mm")))
        order = np.lexsort((both.start, both.frame))
        runs = Runs(*(getattr(both, f)[order] for f in ("frame", "start", "stop", "top_mm", "bottom_mm")))
        track = np.concatenate([track, np.full(len(walls), -1, track.dtype)])[order]
    u = np.nonzero(runs.frame[1:] == runs.frame[:-1])[0]  # runs sorted by frame, then position
    d = u + 1
    # how often each pair of tracks is seen one after the other, measurable or not (for the check below)
    adjacent = Counter(zip(track[u].tolist(), track[d].tolist(), strict=True))
    ok = np.isfinite(runs.bottom_mm[u]) & np.isfinite(runs.top_mm[d]) & (track[u] >= 0) & (track[d] >= 0)
    if blind is not None and np.any(blind):  # a gap across a blind stretch may hide a plug: not a bubble
        hidden = np.concatenate([[0], np.cumsum(np.asarray(blind, bool), dtype=np.int64)])
        ok &= hidden[runs.start[d]] == hidden[runs.stop[u]]
    u, d = u[ok], d[ok]
    if not u.size:
        return np.zeros(0), np.zeros((0, 2), np.int64)
    gap = runs.top_mm[d] - runs.bottom_mm[u]
    ku, kd = track[u], track[d]
    order = np.lexsort((kd, ku))
    ku, kd, gap = ku[order], kd[order], gap[order]
    starts = np.flatnonzero(np.r_[True, (ku[1:] != ku[:-1]) | (kd[1:] != kd[:-1])])
    groups = np.split(gap, starts[1:])
    kept = np.asarray([len(g) >= min_frames for g in groups], bool)
    # a gap whose two plugs are mostly seen with another between them spans that plug where it was missed (a
    # shadow, a splash): not a bubble
    frames_of = {int(k): np.unique(runs.frame[track == k]) for k in np.unique(np.concatenate([ku, kd]))}
    for i, (a, b) in enumerate(zip(ku[starts], kd[starts], strict=True)):
        if kept[i]:
            both = np.intersect1d(frames_of[int(a)], frames_of[int(b)], assume_unique=True).size
            kept[i] = 2 * adjacent[(int(a), int(b))] >= both
    medians = np.asarray([np.median(g) for g in groups], float).reshape(-1)
    pairs = np.stack([ku[starts], kd[starts]], axis=1).astype(np.int64)
    return medians[kept], pairs[kept]


def measure_lengths(runs: Runs, tracks: Tracks, *, scale_rel_sd: float = 0.0,
                    min_frames: int = 3, blind: np.ndarray | None = None, walls: Runs | None = None,
                    not_plugs: frozenset[int] | set[int] = frozenset()) -> Lengths:
    """Mean plug and bubble lengths (see module notes); ``blind``: positions whose contents are hidden (a
    bubble across them is not measured; a plug against them is cut, as :func:`grainplug.plugs.find_runs`
    marks it); ``walls``: runs left out of the train (plugs a reviewer excluded) that still bound the gaps
    beside them: a gap between a plug and one of them is not a bubble measured; ``not_plugs``: tracks whose
    length is not a plug's (a still object taken for one: :func:`grainplug.measures.still.still_tracks`)."""
    both = np.isfinite(runs.top_mm) & np.isfinite(runs.bottom_mm)
    per_track: dict[int, float] = {}
    for tid in range(len(tracks)):
        if tracks.composite(tid) or tid in not_plugs:
            continue
        sel = both & (tracks.run_track == tid)
        if sel.sum() >= min_frames:
            per_track[tid] = float(np.median(runs.bottom_mm[sel] - runs.top_mm[sel]))
    if per_track:
        vals = np.asarray(list(per_track.values()))
        plug, plug_ci, plug_sd = _mean_ci(vals, scale_rel_sd)
    else:
        plug, plug_ci, plug_sd = None, None, None
    bub_vals, bub_pairs = _bubble_medians(runs, tracks, min_frames, blind, walls)
    if bub_vals.size:
        bub, bub_ci, _ = _mean_ci(bub_vals, scale_rel_sd)
    else:
        bub, bub_ci = None, None
    return Lengths(plug, plug_ci, plug_sd, per_track, len(per_track), bub, bub_ci, int(bub_vals.size),
                   bub_pairs, bub_vals)
