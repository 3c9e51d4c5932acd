"""Still objects over the tube: blind stretches, whose contents cannot be seen (a clamp, a fitting, the tube's
end), given by the user or found where nothing changes over the record while the train moves; and stretches
seen through a still object that dims or lights the tube by a constant factor (a translucent label, its
printed marks), whose plugs and bubbles are still measured once that factor is divided out.

A plug touching a blind stretch is cut there (its edge there is missing, as at an end of the view; its
other edge still times the train), and a bubble across one is not measured (a plug may hide in it):
lengths come only from plugs and bubbles seen whole elsewhere.

Notes
-----
*Seen through.* At each position along the tube, every frame shows either a plug or a bubble, so over a
record in which the train moved by more than its longest plug and bubble the contrast ``z`` at that position
takes two levels. In the open tube they are 1 (plug) and 0 (bubble); under a still object that passes a share
``k`` of the light and adds light of its own ``o``, the position sees ``k I + o`` instead of ``I``, and since
``z`` is linear in the light its two levels become ``B`` and ``B + K`` (an affine map of the true contrast,
whatever the object's own light). The levels are found position by position (two-means on the frames), and
where they differ from (0, 1) the map is undone, ``z' = (z - B) / K``. Where the two levels do not stand four
times their spread apart (an opaque clamp, a dense printed mark), nothing is seen there: the stretch is blind.
"""


from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._filters import true_runs
from ..diagram import Diagram
from ..plugs import Runs, Tracks
from .lengths import Lengths
from .motion import Motion
from .shake import Shake
from .tracks import edge_speed_mm_s

#: positions whose grey level varies over the record less than this share of the tube's typical variation are still
STILL_REGION_SHARE = 0.1
#: a still stretch shorter than this (mm) is not taken as blind (a speck of dust)
STILL_MIN_MM = 1.0
#: how a blind stretch was found: given, still over the record, or added on the review page (a correction)
GIVEN, STILL_CONTENTS, REVIEW = "mask_mm", "still contents", "review"
#: the plugs' and bubbles' length that the train must travel over the record for every place to see both: this
#: quantile of those measured (not the longest: a plug merged with a clamp it passes is no plug)
LONG_QUANTILE = 90.0
#: a position whose two contrast levels are off (0, 1) by more than this is seen through something (and corrected)
SEEN_THROUGH_OFF = 0.05
#: ... a stretch of them off by more than this over at least STILL_MIN_MM is reported as a still object seen through
SEEN_THROUGH_REPORTED = 0.15
#: the two levels must stand this many times their spread apart to be told apart (as ``eta >= 0.8`` asks of the
#: whole diagram, :mod:`grainplug.diagram.normalize`)
SEPARATION_SD = 4.0
#: a still object's edge is a step in the levels between samples this far either side (its blur)
EDGE_GAP = 2
#: each level must hold this share of the frames at a position to be measured there
MIN_LEVEL_SHARE = 0.05


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
    #: the share of the plug/bubble contrast left there when the contents are seen through a still object (a
    #: translucent label), divided out; None when blind
    seen_through: float | None = None
    kept: bool = True

    @property
    def blind(self) -> bool:
        """Whether its contents are hidden (else they are seen through it, corrected)."""
        return self.seen_through is None

    def as_dict(self) -> dict[str, object]:
        return {"from_mm": round(self.from_mm, 3), "to_mm": round(self.to_mm, 3), "found_by": self.found_by,
                "treated": "blind" if self.blind else "seen through",
                "contrast_left": None if self.blind else round(float(self.seen_through), 3), "kept": self.kept}


@dataclass(frozen=True)
class ColumnLevels:
    """The contrast's two levels at every position along the tube, over the record.

    Attributes
    ----------
    plug, bubble : ndarray
        The upper and lower level of ``z`` at each position (1 and 0 in the open tube).
    spread : ndarray
        The levels' robust spread (pooled median absolute deviation, as a standard deviation).
    measured : ndarray of bool
        Where both levels hold at least :data:`MIN_LEVEL_SHARE` of the frames.
    """

    plug: np.ndarray
    bubble: np.ndarray
    spread: np.ndarray
    measured: np.ndarray

    @property
    def contrast(self) -> np.ndarray:
        return self.plug - self.bubble

    @property
    def separated(self) -> np.ndarray:
        """Where the two levels are measured and stand :data:`SEPARATION_SD` spreads apart."""
        return self.measured & (self.contrast >= SEPARATION_SD * self.spread)

    @property
    def off(self) -> np.ndarray:
        """How far each position's levels are from the open tube's (0, 1): the larger of the two offsets."""
        return np.maximum(np.abs(self.plug - 1.0), np.abs(self.bubble))


def column_levels(z: np.ndarray, *, max_frames: int = 500, n_iter: int = 4) -> ColumnLevels:
    """The two levels of the contrast ``z`` (frames x positions) at each position, by two-means over the frames
    (on at most ``max_frames`` spread over the record, each position's values sorted once): started between the
    2nd and 98th percentiles, each level the median of its class; the spread is the classes' pooled interquartile
    range (as a standard deviation)."""
    zs = np.sort(np.asarray(z[:: max(1, z.shape[0] // max_frames)], np.float32), axis=0)
    n, cols = zs.shape[0], np.arange(zs.shape[1])

    def at(q: np.ndarray) -> np.ndarray:  # the sorted values at (fractional) ranks q, per position
        q = np.clip(q, 0, n - 1)
        lo = np.floor(q).astype(np.int64)
        hi = np.minimum(lo + 1, n - 1)
        f = (q - lo).astype(np.float32)
        return zs[lo, cols] * (1 - f) + zs[hi, cols] * f

    thr = 0.5 * (at(np.full(len(cols), 0.02 * (n - 1))) + at(np.full(len(cols), 0.98 * (n - 1))))
    k = np.zeros(len(cols), np.int64)
    for _ in range(n_iter):
        k = (zs <= thr[None, :]).sum(axis=0)  # the lower class: ranks [0, k)
        bubble = at(np.maximum(k - 1, 0) / 2.0)
        plug = at(k + (n - 1 - k) / 2.0)
        thr = 0.5 * (plug + bubble)
    share = (n - k) / n
    iqr_b = at(0.75 * np.maximum(k - 1, 0)) - at(0.25 * np.maximum(k - 1, 0))
    iqr_p = at(k + 0.75 * (n - 1 - k)) - at(k + 0.25 * (n - 1 - k))
    spread = (k * iqr_b + (n - k) * iqr_p) / n / 1.349
    measured = (share >= MIN_LEVEL_SHARE) & (share <= 1 - MIN_LEVEL_SHARE)
    return ColumnLevels(plug.astype(float), bubble.astype(float), spread.astype(float), measured)


def unswept_mm(diagram: Diagram, motion: Motion | None, lengths: Lengths | None) -> float | None:
    """How much longer (mm) the train's long plugs and bubbles (:data:`LONG_QUANTILE`) are than the train's travel
    over the record: the longest stretch one of them may cover throughout, so that it looks still (0 when the train
    travelled farther; None when it is not known to move: a static train, no plugs)."""
    if (motion is None or motion.regime == "static" or motion.celerity_m_s is None or lengths is None
            or lengths.plug_length_mm is None):
        return None
    # the train's reach over the record: the span of its displacement (a drift and an oscillation partly cancel)
    x = np.asarray(motion.displacement_mm, float)
    x = x[np.isfinite(x)]
    if x.size:
        travel_mm = float(np.ptp(x))
    else:
        duration = float(diagram.time_s[-1] - diagram.time_s[0])
        travel_mm = abs(motion.celerity_m_s) * 1000.0 * duration + 2.0 * motion.oscillation_amplitude_mm
    plugs = np.asarray(list(lengths.per_track_mm.values()) or [lengths.plug_length_mm], float)
    bubbles = np.asarray(lengths.per_bubble_mm, float)
    longest = max(float(np.percentile(plugs, LONG_QUANTILE)),
                  float(np.percentile(bubbles, LONG_QUANTILE)) if bubbles.size else 0.0)
    return max(longest - travel_mm, 0.0)


def travelled_enough(diagram: Diagram, motion: Motion | None, lengths: Lengths | None) -> bool:
    """Whether the train moved over the record by more than its long plugs and bubbles (:data:`LONG_QUANTILE`), so
    that every place along the tube saw both (a place covered throughout by a longer one must still be a
    :data:`STILL_MIN_MM` stretch to be taken as still); a still train never does."""
    return unswept_mm(diagram, motion, lengths) == 0.0


def seen_through(z: np.ndarray, diagram: Diagram, levels: ColumnLevels, *,
                 blind: np.ndarray | None = None) -> tuple[np.ndarray, list[tuple[float, float, float]],
                                                           list[tuple[float, float]]]:
    """Undo a still object's constant change of the light where the contents are seen through it.

    Returns the corrected contrast (a copy when anything was corrected, ``z`` itself otherwise), the stretches
    reported as seen through (from, to in mm, and the contrast left there) and those where the two levels cannot
    be told apart within such a stretch (blind: a dense printed mark). ``blind``: positions already blind, left
    as they are.
    """
    fix = levels.separated & (levels.off > SEEN_THROUGH_OFF)
    if blind is not None:
        fix &= ~np.asarray(blind, bool)
    pos, half, ds = diagram.position_mm, 0.5 * diagram.mm_per_px, diagram.mm_per_px
    # reported: the stretches clearly off, from their first to their last step in level (a still object has
    # edges; the normalisation's smooth gain along the tube, pulled by a dark clamp or a label, leaves a halo that
    # fades: it is corrected, not reported)
    hide = np.zeros(len(pos), bool) if blind is None else np.asarray(blind, bool)
    clear = levels.measured & (levels.off > SEEN_THROUGH_REPORTED) & ~hide
    g = EDGE_GAP
    jump = np.zeros(len(pos))
    if len(pos) > 2 * g:
        jump[g:-g] = np.maximum(np.abs(levels.plug[2 * g:] - levels.plug[:-2 * g]),
                                np.abs(levels.bubble[2 * g:] - levels.bubble[:-2 * g]))
    if hide.any():  # a blind stretch's own blurred edge (and its steep halo) is not another object's
        from .._filters import maximum_filter1d

        jump[maximum_filter1d(hide.astype(np.uint8), 2 * (2 * g + 3) + 1).astype(bool)] = 0.0
    reported, hidden = [], []
    for a, b in true_runs(clear, max(1, int(np.ceil(STILL_MIN_MM / ds - 1e-9)))):
        # the edges inside the run, or at an end of the view or a blind stretch
        lo, hi = max(a - g, 0), min(b + g, len(pos))
        edges = np.nonzero(jump[lo:hi] > SEEN_THROUGH_REPORTED)[0] + lo
        if not edges.size:
            continue
        open_lo = a == 0 or hide[a - 1]
        open_hi = b == len(pos) or hide[b]
        # a step between samples i - 1 and i shows from i - g to i + g - 1: the stretch, and a sample of blur
        a = a if open_lo else max(int(edges[0]) + g - 1, 0)
        b = b if open_hi else min(int(edges[-1]) - g + 2, len(pos))
        if (b - a) * ds < STILL_MIN_MM:
            continue
        inside = levels.separated[a:b]
        left = float(np.median(levels.contrast[a:b][inside])) if inside.any() else 0.0
        reported.append((float(pos[a] - half), float(pos[b - 1] + half), left))
        for c, d in true_runs(~inside):  # every run, however short: no plug is read there
            hidden.append((float(pos[a + c] - half), float(pos[a + d - 1] + half)))
    if not fix.any():
        return z, reported, hidden
    out = np.array(z, np.float32, copy=True)
    cols = np.nonzero(fix)[0]
    out[:, cols] -= levels.bubble[cols].astype(np.float32)
    out[:, cols] /= levels.contrast[cols].astype(np.float32)
    return out, reported, hidden


def still_stretches(diagram: Diagram, motion: Motion | None, lengths: Lengths | None) -> list[tuple[float, float]]:
    """The stretches (1 mm or more) where nothing changes over the record while the rest of the tube does.

    Where the plug train travelled farther than its long plugs and bubbles over the record
    (:func:`travelled_enough`), every place should have seen both. In a shorter record a long plug or bubble may
    cover a place throughout, over at most the stretch by which it is longer than the travel (:func:`unswept_mm`):
    only a still stretch longer than that, by :data:`STILL_MIN_MM`, is a still object. None in a still train.
    """
    unswept = unswept_mm(diagram, motion, lengths)
    if unswept is None:
        return []
    shortest = STILL_MIN_MM + unswept
    values = diagram.values
    d = np.asarray(values[:: max(1, values.shape[0] // 1000)], np.float32)
    # in grey levels, not their logarithm: a dark clamp's noise is small in grey levels and large in logarithm
    sd = d.std(axis=0)
    typical = float(np.median(sd))
    if not typical > 0.01 * max(float(np.median(np.abs(d))), 1e-6):  # nothing moves anywhere (a jammed or empty
        return []  # record): no contrast to judge by
    pos, half = diagram.position_mm, 0.5 * diagram.mm_per_px
    return [(float(pos[a] - half), float(pos[b - 1] + half)) for a, b in true_runs(sd < STILL_REGION_SHARE * typical)
            if (b - a) * diagram.mm_per_px >= shortest]


#: a place where a plug edge is found in at least this share of the record's frames (twice the most a moving edge
#: dwells within a sample of one place: about a sixth of the frames, at an oscillation's turning point; a still
#: object's boundary is an edge whenever a bubble lies beside it, a third of the frames or more) ...
STILL_EDGE_SEEN = 0.3
#: ... while the train travels at least this many samples over the record is a still object's boundary
STILL_EDGE_MIN_TRAVEL = 10.0


def still_edges(diagram: Diagram, runs: Runs, motion: Motion | None) -> list[tuple[float, float]]:
    """Stretches where a plug edge is found, at the same place, in most of the record's frames while the train
    moves (by its drift or its oscillation): the boundary of a still object (a clamp, a label) that the contents'
    detection took for a plug's edge. For records too short for :func:`still_stretches` (the train travels less
    than its long plugs and bubbles, so a place may see only one of them): there the edges, not the places,
    tell a still object. A moving edge dwells at one place for a share of the frames of about the place's width
    over its travel (a sixth, within a sample of an oscillation's turning point 10 samples away); a still
    object's boundary is there in every frame the train leaves it at.

    Each stretch is the place (3 samples wide) and a sample either side.
    """
    if motion is None or motion.celerity_m_s is None or motion.regime == "static" or not len(runs.frame):
        return []
    if motion.oscillation is not None and motion.oscillation.kind == "stick-slip":
        return []  # a train that sticks dwells at its places: its own edges would look still
    duration = float(diagram.time_s[-1] - diagram.time_s[0])
    travel_mm = abs(motion.celerity_m_s) * 1000.0 * duration + 2.0 * (motion.oscillation_amplitude_mm or 0.0)
    ds = diagram.mm_per_px
    pos = diagram.position_mm
    if travel_mm < STILL_EDGE_MIN_TRAVEL * ds or len(pos) < 3:
        return []
    n_frames, n_pos = diagram.n_frames, len(pos)
    at = np.zeros((n_frames, n_pos), bool)  # frames x positions: an edge within a sample of the place
    for edge in (runs.top_mm, runs.bottom_mm):
        ok = np.isfinite(edge)
        k = np.clip(np.searchsorted(pos, edge[ok]), 0, n_pos - 1)
        for d in (-1, 0, 1):
            at[runs.frame[ok], np.clip(k + d, 0, n_pos - 1)] = True
    share = at.mean(axis=0)
    out: list[tuple[float, float]] = []
    for a, b in true_runs(share >= STILL_EDGE_SEEN, 1):
        centre = a + int(np.argmax(share[a:b]))
        out.append((float(pos[max(centre - 2, 0)]), float(pos[min(centre + 2, n_pos - 1)])))
    return out


#: a track that moves less than this share of what the plug train moves over its life stays put ...
STILL_TRACK_SHARE = 0.2
#: ... judged only where the train moves at least this many pixels over the track's life
STILL_TRACK_MIN_TRAIN_PX = 5.0


def still_tracks(runs: Runs, links: Tracks, time_s: np.ndarray, motion: Motion | None,
                 mm_per_px: float) -> dict[int, tuple[float, float, float]]:
    """The tracks that stay put while a propagative train moves (their edges' speed under :data:`STILL_TRACK_SHARE`
    of the train's, over a life in which the train moves :data:`STILL_TRACK_MIN_TRAIN_PX` or more): a still object
    over the tube (a clamp's shadow, a label's edge, a fitting) taken for a plug. Their lengths are not the plugs'.

    Returns each one's ``(from_mm, to_mm, life_s)``.
    """
    if motion is None or motion.regime != "propagative" or motion.celerity_m_s is None:
        return {}
    speed = abs(motion.celerity_m_s) * 1000.0  # mm/s
    out = {}
    for tid in range(len(links)):
        sel = links.run_track == tid
        if np.count_nonzero(sel) < 3:
            continue
        t = time_s[runs.frame[sel]]
        span = float(t.max() - t.min())
        top, bottom = runs.top_mm[sel], runs.bottom_mm[sel]
        if speed * span < STILL_TRACK_MIN_TRAIN_PX * mm_per_px:
            continue
        slope = edge_speed_mm_s(t, top, bottom)  # as the tracks table reads it
        if np.isfinite(slope) and abs(slope) <= STILL_TRACK_SHARE * speed:
            seen = np.concatenate([top[np.isfinite(top)], bottom[np.isfinite(bottom)]])
            out[tid] = (float(seen.min()), float(seen.max()), span)
    return out


def merged(stretches: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """``(from, to)`` stretches with those that overlap or touch joined, in order."""
    out: list[tuple[float, float]] = []
    for a, b in sorted(stretches):
        if out and a <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return out


def blind_margin(swing_px: float = 0.0) -> int:
    """Samples beside a blind stretch that are blind too: one for its blurred edge, and the camera's swing (peak,
    px) when it shook along the tube and the diagram could not be held still against it (the stretch moves in the
    diagram by as much)."""
    return 1 + int(np.ceil(max(float(swing_px), 0.0) - 1e-9))


def _standing_in_along(shake: Shake | None) -> np.ndarray | None:
    """The camera's motion across the tube (px), when it shook and its motion along could not be measured (the
    diagram not held still against it): the motion across then stands for the motion along; None otherwise."""
    if (shake is None or not shake.shaking or shake.along_px is not None or shake.across_px is None
            or not len(shake.across_px)):
        return None
    return np.asarray(shake.across_px, float)


def shaken_margin(shake: Shake | None) -> int:
    """How far beside a blind stretch plugs are cut (:func:`blind_margin`): a camera that shook along the tube, when
    the diagram could not be held still against it, moves a clamp in the diagram by as much as it moved across."""
    across = _standing_in_along(shake)
    return blind_margin() if across is None else blind_margin(float(np.nanmax(np.abs(across - np.nanmedian(across)))))


def unmeasured_wander_mm(shake: Shake | None, mm_per_px: float) -> float:
    """The rms (mm) of the camera's motion along the tube when it shook but that motion could not be measured: its
    motion across, measured on the walls, stands for it; 0 otherwise."""
    across = _standing_in_along(shake)
    return 0.0 if across is None else float(np.nanstd(across)) * mm_per_px


def blind_positions(position_mm: np.ndarray, stretches: tuple[BlindStretch, ...] | list[BlindStretch], *,
                    margin_samples: int = 1) -> np.ndarray:
    """Which positions along the tube (samples of the diagram) are blind: inside a kept stretch, or within
    ``margin_samples`` of it (its edge is blurred into its neighbours)."""
    pos = np.asarray(position_mm, float)
    out = np.zeros(pos.shape, bool)
    for b in stretches:
        if b.kept and b.blind:
            out |= (pos >= b.from_mm) & (pos <= b.to_mm)
    if margin_samples > 0 and out.any():
        grown = out.copy()
        for k in range(1, margin_samples + 1):
            grown[k:] |= out[:-k]
            grown[:-k] |= out[k:]
        out = grown
    return out
