"""A reviewer's corrections to what an analysis detected, and the measures recomputed from them.

Notes
-----
A :class:`Corrections` is a list of edits, each with what was done and when, replayed
in order on the detected plug tracks:

- ``exclude`` / ``restore`` a track (a false detection, a plug cut by a splash);
- ``merge`` track ``b`` into track ``a`` (one plug the tracker cut in two; two tracks seen
  in the same frame are two plugs, and are not merged);
- ``split`` a track at a frame (two plugs the tracker joined: the part from that frame
  on becomes a new track);
- ``window``: keep the frames between two times (cut away a start-up transient); an edit
  that names one end moves that end only, so "start here" then "end here" keep the frames
  between the two (a window with neither end keeps the whole record again);
- ``no_plugs``: mark a time span as not plugs (a stretch where the flow is compact or
  the view blocked), and ``clear_no_plugs``;
- ``blind``: mark a stretch of the tube (``from_mm`` to ``to_mm`` along it) as blind (a clamp, a
  label the analysis did not find), and ``unblind``: remove the blind stretches overlapping one
  (found or added): a plug touching a blind stretch is cut there, and a bubble across it is not
  measured (:mod:`grainplug.measures.still`).

Track ids in an edit refer to the tracks as they are at that point of the replay (as a
reviewer sees them), so merges and splits compose. :func:`apply_corrections` replays
them on the *detected* runs and tracks (kept in the result, so corrections never
compound) and recomputes celerity, regime, frequency and lengths from the same
functions as the analysis, without reading the movie again.

The file ``corrections.json`` beside an analysis holds the edits (format
:data:`FORMAT_VERSION`); ``grainplug remeasure DIR`` reapplies it, and ``grainplug
batch`` honours it for every run.

An edit made on an analysis (``Corrections.add(..., on=result)``, as the review page
does) also keeps where each track it names was: the centre of the plug (mm along the
tube) at up to :data:`TRACE_POINTS` of its frames, evenly spread (and a split, the time
of its frame: another window numbers the frames otherwise). Replayed on another analysis of the
run (the movie or the parameters changed, and the tracker may have numbered the plugs
otherwise), the edit is applied only if, at each of those times inside the analysis, the
plug nearest to the kept centre (and within :data:`TRACE_TOLERANCE_MM`) belongs to the
track of that number; otherwise it is not applied and the result says so in a warning: a
reviewer's exclusion never falls on another plug. Edits without this trace (format 1, or
made without ``on``) are replayed as they are.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import TYPE_CHECKING

import numpy as np

from .checks import TRAIN_CODES, train_warnings
from .errors import ParameterError
from .measures.compactness import phase_compactness
from .measures.diagram import find_plugs, measure_train
from .measures.shake import shake_hz
from .measures.still import REVIEW, BlindStretch, blind_positions, shaken_margin, unmeasured_wander_mm
from .measures.view import unseen_mask
from .plugs import Runs, Tracks
from .warning_codes import code_of, coded

if TYPE_CHECKING:
    from .diagram import Diagram
    from .result import AnalysisResult

#: version of the format of ``corrections.json`` (2: where the tracks were; 1 is read too)
FORMAT_VERSION = 2
#: how far (mm along the tube) a plug may be from where an edit saw its track, and still be it
TRACE_TOLERANCE_MM = 10.0
#: how many of a track's frames an edit keeps its plug's place at
TRACE_POINTS = 16
#: the start of the warnings about edits not applied (replaced at each replay)
NOT_APPLIED = "a correction no longer fits this analysis"
#: the start of the warning about edits without traces replayed by number on a new analysis (recounted at each replay)
UNCHECKED = "corrections replayed by track number on a new analysis"
CORRECTIONS_FILE = "corrections.json"
ACTIONS = ("exclude", "restore", "merge", "split", "window", "no_plugs", "clear_no_plugs", "blind", "unblind")
#: the actions that mark or unmark blind stretches along the tube
BLIND_ACTIONS = ("blind", "unblind")
#: the actions that name tracks (by their number, checked against where they were when traced)
TRACK_ACTIONS = ("exclude", "restore", "merge", "split")


@dataclass(frozen=True)
class Edit:
    """One correction: ``action`` (see :data:`ACTIONS`), its arguments and when it was made (ISO 8601, UTC)."""

    action: str
    track: int = -1
    other: int = -1
    frame: int = -1
    start_s: float | None = None
    end_s: float | None = None
    track_trace: tuple[tuple[float, float], ...] | None = None
    other_trace: tuple[tuple[float, float], ...] | None = None
    frame_time_s: float | None = None
    from_mm: float | None = None
    to_mm: float | None = None
    at: str = ""

    def describe(self) -> str:
        a = self.action
        if a in ("exclude", "restore"):
            return f"{a}d track {self.track}"
        if a == "merge":
            return f"merged track {self.other} into track {self.track}"
        if a == "split":
            when = f" ({self.frame_time_s:g} s)" if self.frame_time_s is not None else ""
            return f"split track {self.track} at analysed frame {self.frame}{when}"
        if a == "window":
            if self.start_s is None and self.end_s is None:
                return "kept the whole record again"
            if self.end_s is None:
                return f"kept the frames from {self.start_s:g} s on"
            if self.start_s is None:
                return f"kept the frames up to {self.end_s:g} s"
            return f"kept the frames from {self.start_s:g} s to {self.end_s:g} s"
        if a == "no_plugs":
            return f"marked {self.start_s:g}–{self.end_s:g} s as not plugs"
        if a == "blind":
            return f"marked {self.from_mm:g}–{self.to_mm:g} mm along the tube as blind"
        if a == "unblind":
            return f"removed the blind stretches over {self.from_mm:g}–{self.to_mm:g} mm"
        return "cleared the spans marked as not plugs"

    def as_dict(self) -> dict[str, object]:
        out = {k: v for k, v in dataclasses.asdict(self).items() if v not in (-1, None) or k in ("action", "at")}
        for k in ("track_trace", "other_trace"):
            if k in out:
                out[k] = [[round(float(t), 6), round(float(x), 4)] for t, x in out[k]]  # type: ignore[union-attr]
        return out


@dataclass(frozen=True)
class Corrections:
    """The edits, in the order they were made."""

    edits: tuple[Edit, ...] = field(default=())

    def add(self, action: str, *, at: str | None = None, on: AnalysisResult | None = None,
            **args: object) -> Corrections:
        """A copy with one more edit (checked); ``at`` defaults to now.

        ``on``: the analysis the edit is made on (with these corrections applied or not):
        the edit then keeps where each track it names was, and is not applied to another
        analysis whose track of that number is another plug.
        """
        if on is not None:  # the places are computed here, never taken from the caller
            args = {k: v for k, v in args.items() if k not in ("track_trace", "other_trace", "frame_time_s")}
        edit = _edit(action, at=at or datetime.now(UTC).isoformat(timespec="seconds"), **args)
        if on is not None and action in TRACK_ACTIONS:
            runs, links, _ = detection(on, self)
            st = _replay(runs, links, self, on.diagram)
            centre = _centres(runs, on.diagram)
            extra: dict[str, object] = {}
            for name, tid in (("track_trace", edit.track), ("other_trace", edit.other)):
                if tid >= 0:
                    trace = _trace(runs, st.run_track, on.diagram.time_s, centre, tid)
                    if trace:
                        extra[name] = trace
                    elif action != "restore":  # a restore may name a track left without plugs
                        raise ParameterError(f"{action}: there is no track {tid}")
            if action == "merge":
                why = _both_seen(runs, st.run_track, on.diagram.time_s, edit.track, edit.other)
                if why is not None:
                    raise ParameterError(f"merge: {why} — merge tracks that follow one another")
            if action == "split":
                if not 0 <= edit.frame < len(on.diagram.time_s):
                    raise ParameterError(f"split: frame {edit.frame} is outside the analysis")
                extra["frame_time_s"] = round(float(on.diagram.time_s[edit.frame]), 6)
            edit = dataclasses.replace(edit, **extra)
        return Corrections((*self.edits, edit))

    def undo(self) -> Corrections:
        """A copy without the last edit."""
        return Corrections(self.edits[:-1])

    def describe(self) -> list[str]:
        return [e.describe() for e in self.edits]

    @property
    def excluded(self) -> frozenset[int]:
        """Tracks excluded once every edit is replayed (a merged track's exclusion goes with it).

        What the edits ask; :func:`excluded_tracks` gives what was applied to an analysis.
        """
        return _excluded(self.edits)

    def as_dict(self) -> dict[str, object]:
        return {"format": "grainplug-corrections", "format_version": FORMAT_VERSION,
                "edits": [e.as_dict() for e in self.edits]}

    @classmethod
    def from_dict(cls, data: object) -> Corrections:
        """Read the JSON form; raises ParameterError naming what is wrong."""
        if not isinstance(data, dict) or data.get("format") != "grainplug-corrections":
            raise ParameterError("not a grainplug corrections file (no \"format\": \"grainplug-corrections\")")
        version = data.get("format_version")
        if not _is_number(version) or not float(version).is_integer() or version < 1:  # type: ignore[arg-type, operator]
            raise ParameterError(f"\"format_version\" must be a whole number from 1 to {FORMAT_VERSION}, not "
                                 f"{json.dumps(version, default=repr)}")
        if version > FORMAT_VERSION:  # type: ignore[operator]
            raise ParameterError(f"corrections format {version} is newer than this grainplug reads "
                                 f"(up to {FORMAT_VERSION}): upgrade grainplug")
        edits = data.get("edits")
        if not isinstance(edits, list):
            raise ParameterError("the corrections' \"edits\" must be a list")
        out = []
        for k, e in enumerate(edits):
            if not isinstance(e, dict) or "action" not in e:
                raise ParameterError(f"edit {k + 1} has no \"action\"")
            args = {key: v for key, v in e.items() if key not in ("action", "at")}
            try:
                out.append(_edit(str(e["action"]), at=str(e.get("at", "")), **args))
            except ParameterError as exc:
                raise ParameterError(f"edit {k + 1}: {exc.message}") from None
        return cls(tuple(out))


def _edit(action: str, *, at: str, **args: object) -> Edit:
    if action not in ACTIONS:
        raise ParameterError(f"unknown correction {action!r}: use one of {', '.join(ACTIONS)}")
    known = {f.name for f in dataclasses.fields(Edit)} - {"action", "at"}
    unknown = set(args) - known
    if unknown:
        raise ParameterError(f"{action}: unknown argument {', '.join(sorted(unknown))}")
    need = {"exclude": ("track",), "restore": ("track",), "merge": ("track", "other"), "split": ("track", "frame"),
            "window": (), "no_plugs": ("start_s", "end_s"), "clear_no_plugs": (), "blind": ("from_mm", "to_mm"),
            "unblind": ("from_mm", "to_mm")}[action]
    for name in need:
        if args.get(name) is None:
            raise ParameterError(f"{action} needs {name}")
    ints = {k: _whole(action, k, args[k]) for k in ("track", "other", "frame") if args.get(k) is not None}
    for k, v in ints.items():
        if v < 0:
            raise ParameterError(f"{action}: {k} must be >= 0")
    places: dict[str, object] = {}  # where the edit's tracks were (made with ``on``)
    for k in ("track_trace", "other_trace"):
        v = args.get(k)
        if v is not None:
            try:
                pts = tuple((float(t), float(x)) for t, x in v  # type: ignore[union-attr, misc]
                            if _is_number(t) and _is_number(x))
            except (TypeError, ValueError):
                pts = None
            if pts is None or len(pts) != len(v):  # type: ignore[arg-type]
                raise ParameterError(f"{action}: {k} must be a list of [time_s, position_mm] pairs") from None
            if not pts or not all(math.isfinite(t) and math.isfinite(x) for t, x in pts):
                raise ParameterError(f"{action}: {k} must hold finite [time_s, position_mm] pairs")
            places[k] = pts
    if args.get("frame_time_s") is not None:
        places["frame_time_s"] = _seconds(action, "frame_time_s", args["frame_time_s"])
    times = {k: (None if args.get(k) is None else _seconds(action, k, args[k])) for k in ("start_s", "end_s")}
    along = {k: _millimetres(action, k, args[k]) for k in ("from_mm", "to_mm") if args.get(k) is not None}
    if len(along) == 2 and along["to_mm"] < along["from_mm"]:
        raise ParameterError(f"{action}: from_mm ({along['from_mm']:g}) must not be past to_mm "
                             f"({along['to_mm']:g})")
    if times["start_s"] is not None and times["end_s"] is not None and times["end_s"] <= times["start_s"]:
        raise ParameterError(f"{action}: the end ({times['end_s']:g} s) must come after the start "
                             f"({times['start_s']:g} s)")
    if action == "merge" and ints["track"] == ints["other"]:
        raise ParameterError("merge: a track cannot be merged into itself")
    return Edit(action, at=at, **ints, **times, **places, **along)


def _is_number(v: object) -> bool:
    """Whether ``v`` is a number as JSON writes one (an int or a float; a bool is not one, nor a string)."""
    return isinstance(v, int | float | np.integer | np.floating) and not isinstance(v, bool | np.bool_)


def _whole(action: str, name: str, v: object) -> int:
    """``v`` as a track or frame number; raises ParameterError for anything but a whole number.

    ``3.0`` is 3; ``3.7``, ``true``, ``"3"`` are refused (``int()`` would make them 3, 1 and 3: an
    edit on another track than the one written).
    """
    if _is_number(v) and math.isfinite(float(v)) and float(v).is_integer():  # type: ignore[arg-type]
        return int(v)  # type: ignore[call-overload]
    raise ParameterError(f"{action}: {name} must be a whole number (a track or frame number, e.g. 3), "
                         f"not {json.dumps(v, default=repr)}")


def _seconds(action: str, name: str, v: object) -> float:
    """``v`` as a finite time in seconds; raises ParameterError for anything else (``"0.5s"``, ``true``, NaN)."""
    if _is_number(v) and math.isfinite(float(v)):  # type: ignore[arg-type]
        return float(v)  # type: ignore[arg-type]
    raise ParameterError(f"{action}: {name} must be a finite time in seconds written as a number (e.g. 0.5), "
                         f"not {json.dumps(v, default=repr)}")


def _millimetres(action: str, name: str, v: object) -> float:
    """``v`` as a finite position along the tube in mm; raises ParameterError for anything else."""
    if _is_number(v) and math.isfinite(float(v)):  # type: ignore[arg-type]
        return float(v)  # type: ignore[arg-type]
    raise ParameterError(f"{action}: {name} must be a finite position along the tube in mm written as a number "
                         f"(e.g. 12.5), not {json.dumps(v, default=repr)}")


def _both_seen(runs: Runs, track: np.ndarray, time_s: np.ndarray, a: int, b: int) -> str | None:
    """Why tracks ``a`` and ``b`` cannot be one plug (None: they can): seen in the same frames."""
    both = np.intersect1d(runs.frame[track == a], runs.frame[track == b])
    if not both.size:
        return None
    return (f"tracks {a} and {b} are both seen in {both.size} frame{'s' if both.size > 1 else ''} "
            f"({time_s[both[0]]:.3f}–{time_s[both[-1]]:.3f} s): two plugs at once are not one plug")


def _excluded(edits: tuple[Edit, ...] | list[Edit]) -> frozenset[int]:
    out: set[int] = set()
    for e in edits:
        if e.action == "exclude":
            out.add(e.track)
        elif e.action in ("restore", "merge"):
            out.discard(e.track if e.action == "restore" else e.other)
    return frozenset(out)


def _centres(runs: Runs, diagram: Diagram) -> np.ndarray:
    """Centre of every run, mm along the tube."""
    pos = diagram.position_mm
    return 0.5 * (pos[runs.start] + pos[np.maximum(runs.stop - 1, runs.start)])


def _trace(runs: Runs, track: np.ndarray, time_s: np.ndarray, centre: np.ndarray,
           tid: int) -> tuple[tuple[float, float], ...]:
    """Where track ``tid`` was: (time, centre mm) at up to :data:`TRACE_POINTS` of its frames (empty: no such track)."""
    sel = np.flatnonzero(track == tid)
    if not sel.size:
        return ()
    order = sel[np.argsort(runs.frame[sel], kind="stable")]
    picks = order[np.unique(np.linspace(0, len(order) - 1, min(TRACE_POINTS, len(order))).round().astype(int))]
    # rounded as in the file, so that an edit read back equals the edit made
    return tuple((round(float(time_s[runs.frame[i]]), 6), round(float(centre[i]), 4)) for i in picks)


def _nearest_row(t: np.ndarray, when: float) -> int | None:
    """The row of ``t`` at time ``when`` (None when no row is within 1.5 frame periods of it)."""
    if not len(t):
        return None
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    k = int(np.clip(np.searchsorted(t, when), 0, len(t) - 1))
    k = min((k, max(k - 1, 0)), key=lambda j: abs(t[j] - when))
    return k if abs(t[k] - when) <= 1.5 * dt + 1e-6 else None


def _misfit(runs: Runs, track: np.ndarray, time_s: np.ndarray, centre: np.ndarray, tid: int,
            kept: tuple[tuple[float, float], ...] | None) -> str | None:
    """Why track ``tid`` is not the plug an edit saw at ``kept`` (None: it is, or nothing was kept)."""
    if kept is None:
        return None
    checked = 0
    for when, where in kept:
        k = _nearest_row(time_s, when)
        if k is None:
            continue  # outside this analysis (another window): nothing to compare
        here = np.flatnonzero(runs.frame == k)
        if not here.size:
            return f"track {tid}'s plug is not seen at {when:.3f} s now"
        near = here[np.argmin(np.abs(centre[here] - where))]
        if track[near] != tid or abs(centre[near] - where) > TRACE_TOLERANCE_MM:
            return f"track {tid} is another plug now"
        checked += 1
    return None if checked else f"track {tid}'s plug is outside this analysis"


@dataclass(frozen=True)
class Replay:
    """A result's corrections as replayed on its detected tracks: each run's track, the tracks excluded, the
    time window kept (None: that end of the record), the spans marked as not plugs, why edits were not applied
    (and which applied windows hold none of the record), the edits applied, and those of them that are windows
    holding none of the record (applied: what they cut away stays cut, and no plugs are left)."""

    run_track: np.ndarray
    excluded: frozenset[int]
    window: tuple[float | None, float | None]
    spans: tuple[tuple[float, float], ...]
    not_applied: tuple[str, ...] = ()
    applied: tuple[Edit, ...] = ()
    empty_windows: tuple[Edit, ...] = ()
    #: the tracks the edits were replayed on (:func:`detection`)
    links: Tracks | None = None


def _replay(runs: Runs, links: Tracks, corr: Corrections, diagram: Diagram) -> Replay:
    track = links.run_track.astype(np.int64).copy()
    window: tuple[float | None, float | None] = (None, None)
    spans: list[tuple[float, float]] = []
    applied: list[Edit] = []
    skipped: list[str] = []
    empty: list[Edit] = []
    centre = _centres(runs, diagram)
    for k, e in enumerate(corr.edits, 1):
        split_at = e.frame
        if e.action in TRACK_ACTIONS:
            why = _misfit(runs, track, diagram.time_s, centre, e.track, e.track_trace)
            if why is None and e.action == "merge":
                why = _misfit(runs, track, diagram.time_s, centre, e.other, e.other_trace)
            if why is None and e.action == "split" and e.frame_time_s is not None:
                row = _nearest_row(diagram.time_s, e.frame_time_s)  # the same time, whatever the window
                if row is None:
                    why = f"its time, {e.frame_time_s:.3f} s, is outside this analysis"
                else:
                    split_at = row
            if why is None:  # (edits written by hand name tracks and frames by number: they must exist)
                top = int(track.max()) if track.size else -1
                named = [t for t in (e.track, e.other) if t >= 0]
                # an exclude or a restore may name a track a merge or a split has emptied; the others need plugs
                missing = [t for t in named if t > top] if e.action in ("exclude", "restore") else [
                    t for t in named if not (track == t).any()]
                if missing:
                    why = (f"there is no track {missing[0]} (the largest is {top})" if missing[0] > top
                           else f"track {missing[0]} has no plugs left")
                elif e.action == "split" and not 0 <= split_at < len(diagram.time_s):
                    why = f"frame {split_at} is outside this analysis (0 to {len(diagram.time_s) - 1})"
                elif e.action == "merge":
                    why = _both_seen(runs, track, diagram.time_s, e.track, e.other)
            if why is not None:
                seen = " and ".join(f"{trace[0][0]:.3f}–{trace[-1][0]:.3f} s" for trace in
                                    filter(None, (e.track_trace, e.other_trace)))
                made = f" (made on plugs seen {seen})" if seen else ""
                skipped.append(f"edit {k}, {e.describe()}{made}, was not applied: {why}")
                continue
        if e.action in BLIND_ACTIONS:
            why = _blind_misfit(e, diagram)
            if why is not None:
                skipped.append(f"edit {k}, {e.describe()}, was not applied: {why}")
                continue
        if e.action == "window":  # the ends it names move; the other stays where an earlier window put it
            both = e.start_s is None and e.end_s is None
            start = None if both else e.start_s if e.start_s is not None else window[0]
            end = None if both else e.end_s if e.end_s is not None else window[1]
            if start is not None and end is not None and end <= start:
                skipped.append(f"edit {k}, {e.describe()}, was not applied: it would end the window ({end:g} s) "
                               f"before it starts ({start:g} s)")
                continue
            if len(diagram.time_s):  # applied all the same: what it cuts away stays cut
                t0, t1 = float(diagram.time_s[0]), float(diagram.time_s[-1])
                lo = t0 if start is None else start
                hi = t1 if end is None else end
                if lo > t1 or hi < t0:
                    skipped.append(f"edit {k}, {e.describe()}, was applied but holds none of this record ({t0:g} to "
                                   f"{t1:g} s): no plugs are left")
                    empty.append(e)
        applied.append(e)
        if e.action == "merge":
            track[track == e.other] = e.track
        elif e.action == "split":
            new = int(track.max()) + 1 if track.size else 0
            track[(track == e.track) & (runs.frame >= split_at)] = new
        elif e.action == "window":
            window = (start, end)
        elif e.action == "no_plugs":
            spans.append((float(e.start_s), float(e.end_s)))  # type: ignore[arg-type]
        elif e.action == "clear_no_plugs":
            spans.clear()
    return Replay(track, _excluded(applied), window, tuple(spans), tuple(skipped), tuple(applied), tuple(empty),
                  links)


def _blind_misfit(e: Edit, diagram: Diagram) -> str | None:
    """Why a ``blind`` or ``unblind`` edit does not fit the analysis' view (None when it does)."""
    if not len(diagram.position_mm):
        return None
    z0, z1 = sorted((float(diagram.position_mm[0]), float(diagram.position_mm[-1])))
    if e.to_mm < z0 or e.from_mm > z1:  # type: ignore[operator]
        return f"it is outside the view ({z0:g} to {z1:g} mm)"
    if e.action == "blind" and e.from_mm <= z0 and e.to_mm >= z1:  # type: ignore[operator]
        return f"it covers the whole view ({z0:g} to {z1:g} mm), and nothing would be left to measure"
    return None


def detection(res: AnalysisResult, corr: Corrections) -> tuple[Runs, Tracks, tuple[BlindStretch, ...]]:
    """The plugs and tracks the corrections' track edits apply to, and the blind stretches once they are replayed.

    The analysis' own detection, unless the ``blind`` and ``unblind`` edits change which stretches are blind:
    the plugs are then found again in the analysis' diagram with those stretches blind (as ``mask_mm=`` given
    to the analysis would), so that nothing of a clamp marked by hand is taken for a plug and a plug under a
    stretch unmarked is seen whole. Track edits keep where their tracks were, and are checked against it.
    """
    runs, links = res.detected if res.detected is not None else (res.runs, res.links)
    edits = tuple(e for e in corr.edits if e.action in BLIND_ACTIONS and _blind_misfit(e, res.diagram) is None)
    stretches = blind_after(res.blind, edits)

    def kept(bs: tuple[BlindStretch, ...]) -> list[tuple[float, float]]:
        return sorted((b.from_mm, b.to_mm) for b in bs if b.kept and b.blind)

    if kept(stretches) != kept(blind_after(res.blind, ())) and res.normalized is not None:
        blind = (blind_positions(res.diagram.position_mm, stretches, margin_samples=shaken_margin(res.shake))
                 if kept(stretches) else None)
        runs, links = find_plugs(res.normalized, res.diagram, res.params, blind=blind,
                                 unseen=unseen_mask(res.tube_unseen, res.diagram.n_frames))
    return runs, links, stretches


def replayed(res: AnalysisResult) -> Replay | None:
    """``res``'s corrections replayed on its detected tracks (None without corrections)."""
    if res.corrections is None:
        return None
    runs, links, _ = detection(res, res.corrections)
    return _replay(runs, links, res.corrections, res.diagram)


def applied_edits(res: AnalysisResult) -> tuple[Edit, ...]:
    """The edits of ``res``'s corrections that were applied to it (those that no longer fit it left out: its
    warnings say why)."""
    st = replayed(res)
    return () if st is None else st.applied


def excluded_tracks(res: AnalysisResult) -> frozenset[int]:
    """The tracks of ``res`` its corrections exclude (edits that no longer fit it left out)."""
    st = replayed(res)
    return frozenset() if st is None else st.excluded


def _first_last(track: np.ndarray, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tracks that have runs, and the index of each one's first and last run (by frame)."""
    order = np.lexsort((frame, track))
    t_sorted = track[order]
    starts = np.flatnonzero(np.r_[True, t_sorted[1:] != t_sorted[:-1]])
    ends = np.r_[starts[1:] - 1, len(t_sorted) - 1]
    return t_sorted[starts], order[starts], order[ends]


def _how_tracks_begin_and_end(track: np.ndarray, runs: Runs, detected: Tracks) -> tuple[list[str], list[str]]:
    """How each track of the replayed runs began and ended (before any run is left out by an exclusion, the
    window or a span): as the detected track its first (last) run belongs to, where that run was its first
    (last); else it was cut there by a reviewer's split: ``"cut"``. A part merged back into its track leaves
    it whole again; a part split off a track the tracker saw split keeps that ending (and is composite)."""
    n = int(track.max()) + 1 if track.size else 0
    started = [detected.started_by[i] if i < len(detected) else "cut" for i in range(n)]
    ended = [detected.ended_by[i] if i < len(detected) else "cut" for i in range(n)]
    if track.size:
        orig = detected.run_track
        for tid, i0, i1 in zip(*_first_last(track, runs.frame), strict=True):
            d0, d1 = orig[i0], orig[i1]
            started[tid] = detected.started_by[d0] if runs.frame[i0] == detected.first_frame[d0] else "cut"
            ended[tid] = detected.ended_by[d1] if runs.frame[i1] == detected.last_frame[d1] else "cut"
    return started, ended


def _tracks_of(track: np.ndarray, frame: np.ndarray, began_ended: tuple[list[str], list[str]]) -> Tracks:
    """Per-track first/last frames of the kept runs, and how each track began and ended."""
    started, ended = began_ended
    n = max(len(started), int(track.max()) + 1 if track.size else 0)
    first = np.full(n, -1, np.int64)
    last = np.full(n, -1, np.int64)
    if track.size:
        tids, i0, i1 = _first_last(track, frame)
        first[tids] = frame[i0]
        last[tids] = frame[i1]
    return Tracks(track, first, last, list(started) + ["cut"] * (n - len(started)),
                  list(ended) + ["cut"] * (n - len(ended)))


def _is(warning: str, code: str, legacy_prefix: str) -> bool:
    """Whether ``warning`` is of ``code`` (a warning of a result saved before codes: by the sentence it began
    with then)."""
    found = code_of(warning)
    return found == code or (found == "legacy.uncoded" and warning.startswith(legacy_prefix))


def apply_corrections(res: AnalysisResult, corr: Corrections, *, reanalysed: bool = False) -> AnalysisResult:
    """The result with ``corr`` applied to its detected tracks and every measure recomputed.

    Applying to an already corrected result starts again from what was detected, so
    ``apply_corrections(apply_corrections(r, a), b)`` is ``apply_corrections(r, b)``.

    Parameters
    ----------
    res : AnalysisResult
    corr : Corrections
    reanalysed : bool
        ``res`` is a new analysis of the run, not the one ``corr`` was made on (a batch after
        the movie or the parameters changed). Edits of tracks made without where the tracks
        were (format 1, or :meth:`Corrections.add` without ``on``) cannot be checked against
        it: a warning says how many were replayed by number. The warning stays on the result
        through later replays while such edits remain, and goes with them.
    """
    analysed = res.detected if res.detected is not None else (res.runs, res.links)
    runs, links, stretches = detection(res, corr)
    st = _replay(runs, links, corr, res.diagram)
    t = res.diagram.time_s[runs.frame]
    excluded = np.isin(st.run_track, np.fromiter(st.excluded, np.int64, len(st.excluded)))
    in_time = np.ones(len(runs), bool)
    lo, hi = st.window
    if lo is not None:
        in_time &= t >= lo
    if hi is not None:
        in_time &= t <= hi
    for a, b in st.spans:
        in_time &= ~((t >= a) & (t <= b))
    keep = in_time & ~excluded
    new_runs = _rows(runs, keep)
    walls = _rows(runs, in_time & excluded)  # excluded plugs are not air: the bubbles beside them are cut there
    new_links = _tracks_of(st.run_track[keep], runs.frame[keep], _how_tracks_begin_and_end(st.run_track, runs, links))
    # excluded and emptied tracks keep their ids (so edits and tables stay readable) but have no runs
    motion = lengths = None
    statement = res.statement
    # from the detection, not from ``res``: a result whose corrections left no plugs gets them back with
    # corrections that keep some (the detection finds runs only where the tube holds plugs and air)
    detected_plugs = len(runs) > 0
    has_plugs = detected_plugs and len(new_runs) > 0
    if has_plugs:  # the analysis' own measuring step, on the corrected tracks
        blind = (blind_positions(res.diagram.position_mm, stretches, margin_samples=shaken_margin(res.shake))
                 if any(b.kept and b.blind for b in stretches) else None)
        motion, lengths, statement = measure_train(res.diagram.time_s, new_runs, new_links, fps=res.info.fps,
                                                   mm_per_px=res.mm_per_px, scale_rel_sd=res.scale_rel_sd,
                                                   blind=blind, not_hz=shake_hz(res.shake),
                                                   frame_cadence=res.info.predicts_frames,
                                                   wander_mm=unmeasured_wander_mm(res.shake, res.mm_per_px),
                                                   walls=walls)
    elif detected_plugs:
        statement = "no plugs left after the corrections: no celerity, length or frequency is measured"
    unchecked = sum(e.action in TRACK_ACTIONS and e.track_trace is None for e in corr.edits)
    flagged = reanalysed or any(_is(w, "corrections.unchecked", UNCHECKED) for w in res.warnings)
    # those of an earlier replay go, and are said again if they still hold
    warnings = [w for w in res.warnings if not (_is(w, "corrections.not_applied", NOT_APPLIED)
                                                or _is(w, "corrections.unchecked", UNCHECKED))]
    # the plug train's own warnings are given again on what the corrections keep, where the analysis gave them
    # (a result saved before warnings had codes keeps its own: they cannot be told apart from the others)
    legacy = any(code_of(w) == "legacy.uncoded" for w in warnings)
    train = [i for i, w in enumerate(warnings) if code_of(w) in TRAIN_CODES]
    again = [] if legacy else train_warnings(new_runs, new_links, res.diagram.time_s, motion, mm_per_px=res.mm_per_px,
                           params=res.params, info=res.info, blind=stretches, shake=res.shake,
                           flow_source=res.flow_direction_source, falling_m_s=res.falling_grain_speed_m_s)
    if not legacy:
        at = train[0] if train else len(warnings)
        warnings = [w for w in warnings[:at] if code_of(w) not in TRAIN_CODES] + again + [
            w for w in warnings[at:] if code_of(w) not in TRAIN_CODES]
    warnings += [coded("corrections.not_applied", f"{NOT_APPLIED}: {note} — review the run again")
                 for note in st.not_applied]
    if unchecked and flagged:
        warnings.append(coded(
            "corrections.unchecked",
            f"{UNCHECKED}: {unchecked} edit(s) in corrections.json name tracks of an earlier analysis "
            "of this run without where those tracks were, and the movie or the parameters have "
            "changed since — check them in `grainplug review` (edits made there again keep their "
            "tracks' place)"))
    compactness = (phase_compactness(res.compactness_field, new_runs, new_links)
                   if res.compactness_field is not None else res.compactness)
    return dataclasses.replace(res, runs=new_runs, links=new_links, motion=motion, lengths=lengths,
                               compactness=compactness,
                               has_plugs=has_plugs, statement=statement, detected=analysed,
                               corrections=corr, warnings=warnings, blind=stretches)


def _rows(runs: Runs, sel: np.ndarray) -> Runs:
    return Runs(runs.frame[sel], runs.start[sel], runs.stop[sel], runs.top_mm[sel], runs.bottom_mm[sel])


def blind_after(found: tuple[BlindStretch, ...], edits: tuple[Edit, ...]) -> tuple[BlindStretch, ...]:
    """The blind stretches once the ``blind`` and ``unblind`` edits are replayed on those the analysis found or was
    given (``found``; those a previous replay added or removed are taken back first, so replays never compound).

    A removed stretch stays in the list with ``kept=False`` (the result says what was removed); one added then
    removed goes."""
    out = [dataclasses.replace(b, kept=True) for b in found if b.found_by != REVIEW]
    for e in edits:
        lo, hi = float(e.from_mm), float(e.to_mm)  # type: ignore[arg-type]
        if e.action == "blind":
            out.append(BlindStretch(lo, hi, REVIEW))
        else:
            over = [b.kept and b.blind and b.from_mm <= hi and b.to_mm >= lo for b in out]  # not those seen through
            out = [dataclasses.replace(b, kept=False) if o else b for b, o in zip(out, over, strict=True)
                   if not (o and b.found_by == REVIEW)]
    return tuple(sorted(out, key=lambda b: (b.from_mm, b.to_mm)))
