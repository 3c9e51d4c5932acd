"""From a spatiotemporal diagram to the plugs' measures: normalise, find the plugs, link them into tracks,
measure the train (celerity, oscillation, regime, lengths); or say why there is nothing to measure.

One path for a movie's diagram (:func:`grainplug.analyze`), a simulation's
(:mod:`grainplug.simulation.measure`) and a reviewer's corrected tracks
(:func:`measure_train`, from :func:`grainplug.corrections.apply_corrections`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from ..diagram import Diagram, Normalized, normalize
from ..diagram.normalize import CONFIRMED_ETA, LOW_SEPARATION_ETA, MIN_CLASS_FRACTION, MIN_SEPARATION_ETA
from ..errors import ParameterError
from ..params import AnalysisParams
from ..plugs import Runs, Tracks, find_runs, link, plug_mask
from .lengths import Lengths, measure_lengths
from .motion import NO_FOLLOWED_EDGE, Motion, measure_motion
from .still import (
    GIVEN,
    STILL_CONTENTS,
    BlindStretch,
    blind_positions,
    column_levels,
    merged,
    seen_through,
    still_edges,
    still_stretches,
    still_tracks,
    travelled_enough,
)

#: what to do when plugs and bubbles are too close in grey level to tell apart (a movie's advice; a diagram made
#: otherwise, a simulation's, replaces it)
CONTRAST_ADVICE = "raise the contrast between grains and air (lighting, exposure, a less compressed file)"

def find_plugs(norm: Normalized, diagram: Diagram, params: AnalysisParams, *,
               blind: np.ndarray | None = None, unseen: np.ndarray | None = None) -> tuple[Runs, Tracks]:
    """Plugs in every frame (runs of grains along the tube), linked into tracks over time; ``blind``: the
    positions whose contents are hidden (:func:`grainplug.measures.still.blind_positions`); ``unseen``: the frames
    in which the tube is not in view (:func:`grainplug.measures.view.tube_view`), where no plug is found."""
    ds = float(diagram.position_mm[1] - diagram.position_mm[0])
    mask = plug_mask(norm.z, mm_per_sample=ds, min_plug_mm=params.min_plug_mm, min_gap_mm=params.min_gap_mm,
                     blind=blind)
    if not norm.two_phase:  # one material only: no plug to find
        mask[:] = False
    if unseen is not None and unseen.any():
        mask[np.asarray(unseen, bool)] = False
    runs = find_runs(norm.z, mask, diagram.position_mm, blind=blind)
    return runs, link(runs, diagram.n_frames, blind=blind)

def measure_plugs(norm: Normalized, diagram: Diagram, runs: Runs, links: Tracks, background_level: float, *, fps: float,
              mm_per_px: float, scale_rel_sd: float,
              params: AnalysisParams, blind: np.ndarray | None = None,
              not_hz: tuple[float, ...] = (),
              frame_cadence: bool = False, wander_mm: float = 0.0) -> tuple[Motion | None, Lengths | None, str]:
    """Celerity and oscillation of the plug train, plug and bubble lengths; or why there are none."""
    if not norm.two_phase and weakly_two(norm):
        averaged = ("" if norm.averaged_eta is None else
                    f"; {norm.averaged_eta:.2f} averaged along the tube, {CONFIRMED_ETA:g} needed")
        return None, None, (f"no plugs: the tube seems to hold a single phase ({single_phase(norm, background_level)})"
                            f", but its grey levels hint at two, too close to tell apart (separation "
                            f"{norm.separation_eta:.2f}, {MIN_SEPARATION_ETA:g} needed{averaged}): if there are plugs, "
                            f"{CONTRAST_ADVICE}; "
                            "no celerity, length or frequency is measured")
    if not norm.two_phase:
        return None, None, (f"no plugs: the tube holds a single phase over the whole record "
                            f"({single_phase(norm, background_level)}); "
                            "no celerity, length or frequency is measured")
    if len(runs) == 0:
        view = float(diagram.position_mm[-1] - diagram.position_mm[0]) if len(diagram.position_mm) > 1 else 0.0
        longer = f", longer than the {view:.0f} mm in view" if params.min_plug_mm >= view else ""
        return None, None, (f"no plugs: grains and air are both seen, but no run of grains is at least "
                            f"{params.min_plug_mm:g} mm long{longer} — lower min_plug_mm= "
                            "(or min_gap_mm=), or check the scale; no celerity, length or frequency is measured")
    return measure_train(diagram.time_s, runs, links, fps=fps, mm_per_px=mm_per_px, scale_rel_sd=scale_rel_sd,
                         blind=blind, not_hz=not_hz, frame_cadence=frame_cadence, wander_mm=wander_mm)


def measure_train(time_s: np.ndarray, runs: Runs, links: Tracks, *, fps: float, mm_per_px: float,
                  scale_rel_sd: float, blind: np.ndarray | None = None,
                  not_hz: tuple[float, ...] = (),
                  frame_cadence: bool = False, wander_mm: float = 0.0,
                  walls: Runs | None = None) -> tuple[Motion | None, Lengths | None, str]:
    """Celerity, oscillation and regime of a train of tracked plugs, their lengths and their bubbles' (the step
    that :func:`measure_plugs` ends with and :func:`grainplug.corrections.apply_corrections` repeats on the
    corrected tracks); the statement says why there is no motion, if so. ``walls``: plugs left out of the train
    (excluded by a reviewer) that cut the bubbles beside them (:func:`~grainplug.measures.lengths.measure_lengths`)."""
    # small least-squares problems: a BLAS thread pool would only add wake-up latency
    with threadpool_limits(limits=1, user_api="blas"):
        motion = measure_motion(time_s, runs.top_mm, links.run_track, runs.frame, fps=fps,
                                mm_per_px=mm_per_px, scale_rel_sd=scale_rel_sd, not_hz=not_hz,
                                frame_cadence=frame_cadence, wander_mm=wander_mm)
        # a track that stays put while the train moves is a still object taken for a plug: not a plug's length
        still = still_tracks(runs, links, time_s, motion, mm_per_px)
        lengths = measure_lengths(runs, links, scale_rel_sd=scale_rel_sd, blind=blind, walls=walls,
                                  not_plugs=frozenset(still))
    statement = "" if motion is not None else NO_FOLLOWED_EDGE
    return motion, lengths, statement

@dataclass(frozen=True)
class DiagramMeasures:
    """What :func:`measure_diagram` finds in a spatiotemporal diagram."""

    normalized: Normalized
    runs: Runs
    links: Tracks
    motion: Motion | None
    lengths: Lengths | None
    statement: str
    #: the stretches whose contents are hidden (given or found), left out of the plugs and bubbles
    blind: tuple[BlindStretch, ...] = ()

def measure_diagram(diagram: Diagram, params: AnalysisParams | None = None, *, fps: float,
                    background_level: float = 0.0, normalized: Normalized | None = None,
                    scale_rel_sd: float = 0.0, not_hz: tuple[float, ...] = (),
                    blind_margin_px: int = 1, frame_cadence: bool = False,
                    unseen: np.ndarray | None = None, wander_mm: float = 0.0) -> DiagramMeasures:
    """The analysis from the diagram on: plugs, tracks, celerity, regime, plug and bubble lengths.

    The stages :func:`analyze` runs after streaming the movie, for a diagram from
    elsewhere (a simulation, :mod:`grainplug.simulation.measure`). ``diagram.values``
    are grey levels with grains dark, rows in time, positions increasing downstream.

    ``normalized``: the diagram's contrast when it is already known (:func:`grainplug.analyze` normalises
    before it decides the flow's direction); ``scale_rel_sd``: the scale's relative uncertainty, carried
    into the intervals; ``not_hz``: frequencies that are not the plugs' (the camera's shake);
    ``blind_margin_px``: how far beside a blind stretch a plug's edge is cut too (its blurred edge, and the swing of
    a camera shaking along the tube that the diagram was not held still against: :func:`blind_margin`);
    ``frame_cadence``: the movie's codec predicts frames from others
    (:func:`grainplug.measures.motion.measure_motion`); ``unseen``: the frames in which the tube is not in view;
    ``wander_mm``: the rms of a motion of the view along the tube that could not be measured (the celerity's
    interval carries it).
    """
    params = params or AnalysisParams()
    if normalized is None:
        normalized = normalize(diagram.values, background_level=background_level or None,
                               confirm_px=confirm_px(params.min_plug_mm, diagram.mm_per_px))
    given = _given_stretches(diagram, params.mask_mm)

    def measured(stretches: tuple[BlindStretch, ...], norm: Normalized) -> DiagramMeasures:
        blind = (blind_positions(diagram.position_mm, stretches, margin_samples=blind_margin_px)
                 if any(b.blind for b in stretches) else None)
        runs, links = find_plugs(norm, diagram, params, blind=blind, unseen=unseen)
        motion, lengths, statement = measure_plugs(norm, diagram, runs, links, background_level, fps=fps,
                                                   mm_per_px=diagram.mm_per_px, scale_rel_sd=scale_rel_sd,
                                                   params=params, blind=blind, not_hz=not_hz,
                                                   frame_cadence=frame_cadence, wander_mm=wander_mm)
        return DiagramMeasures(norm, runs, links, motion, lengths, statement, stretches)

    first = measured(given, normalized)
    if not normalized.two_phase:
        return first
    if not travelled_enough(diagram, first.motion, first.lengths):
        # a short record: a place may see only one phase, so the levels are not judged place by place; a still
        # stretch longer than a long plug or bubble could cover throughout, and an edge that stays put while the
        # train moves, are still objects, blind (their plugs cut there)
        found = merged([*still_stretches(diagram, first.motion, first.lengths),
                        *still_edges(diagram, first.runs, first.motion)])
        edges = [BlindStretch(a, b, STILL_CONTENTS) for a, b in found
                 if not any(g.from_mm <= a and b <= g.to_mm for g in given)]
        if not edges:
            return first
        return measured(tuple(sorted([*given, *edges], key=lambda b: b.from_mm)), normalized)
    # every place saw plugs and bubbles: where nothing changed over the record, something hides the tube (blind);
    # where the two levels are not the open tube's, a still object dims or lights it (divided out, or blind where
    # the levels cannot be told apart); measured again
    found = [BlindStretch(a, b, STILL_CONTENTS) for a, b in still_stretches(diagram, first.motion, first.lengths)
             if not any(g.from_mm <= a and b <= g.to_mm for g in given)]
    opaque = blind_positions(diagram.position_mm, [*given, *found], margin_samples=0)
    z, through, hidden = seen_through(normalized.z, diagram, column_levels(normalized.z), blind=opaque)
    found += [BlindStretch(a, b, STILL_CONTENTS) for a, b in hidden]
    found += [BlindStretch(a, b, STILL_CONTENTS, seen_through=left) for a, b, left in through]
    if not found and z is normalized.z:
        return first
    norm = normalized if z is normalized.z else dataclasses.replace(normalized, z=z)
    return measured(tuple(sorted([*given, *found], key=lambda b: b.from_mm)), norm)

def _given_stretches(diagram: Diagram, mask_mm: tuple[tuple[float, float], ...]) -> tuple[BlindStretch, ...]:
    """The user's blind stretches, checked against the view: one outside it, or all of them covering it, is
    refused (naming ``mask_mm=``)."""
    if not mask_mm:
        return ()
    half = 0.5 * diagram.mm_per_px
    lo, hi = float(diagram.position_mm[0] - half), float(diagram.position_mm[-1] + half)
    for a, b in mask_mm:
        if b <= lo or a >= hi:
            raise ParameterError(f"the stretch {a:g}-{b:g} mm is outside the view ({lo:.1f}-{hi:.1f} mm from its "
                                 "upstream end) — give stretches inside it", param="mask_mm")
    stretches = tuple(BlindStretch(max(a, lo), min(b, hi), GIVEN) for a, b in mask_mm)
    if blind_positions(diagram.position_mm, stretches, margin_samples=0).all():
        raise ParameterError(f"the stretches cover the whole view ({lo:.1f}-{hi:.1f} mm): nothing would be left to "
                             "measure — give only the stretches something hides", param="mask_mm")
    return stretches

#: a separation that averaging along the tube lowers by more than this is of short things (falling grains), not plugs
AVERAGED_LOSS = 0.05

def weakly_two(norm: Normalized) -> bool:
    """Whether the diagram's two grey levels, too close to be called plugs and bubbles, are still more than one
    level with noise (a separation of 2/pi = 0.64), each hold a fair share of it, and do not part less once
    averaged along the tube."""
    return (norm.separation_eta >= LOW_SEPARATION_ETA
            and MIN_CLASS_FRACTION <= norm.plug_fraction <= 1 - MIN_CLASS_FRACTION
            and not (norm.averaged_eta is not None and norm.averaged_eta < norm.separation_eta - AVERAGED_LOSS))

def confirm_px(min_plug_mm: float, mm_per_px: float) -> int:
    """Positions along the tube over which a weak plug/bubble separation is looked for again: a third of the
    shortest plug (:func:`grainplug.diagram.normalize`)."""
    return max(1, int(round(min_plug_mm / 3 / mm_per_px)))

def single_phase(norm: Normalized, background: float) -> str:
    """What a single phase is, by the grey level of most of the diagram (the larger of its two classes: a few
    dense specks in rain are not a compact flow) against the background's."""
    level = float(norm.plug_level if norm.plug_fraction >= 0.5 else norm.bubble_level)
    if background <= 0:
        return "compact flow or empty tube"
    if 0.75 <= level / background <= 1.35:
        return "empty tube or dilute flow"
    return "compact flow by its grey level: grains fill the tube"
