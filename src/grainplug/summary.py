"""``summary.json`` and the run's tables: what they hold, column by column, and how they are made.

Below :mod:`grainplug.result`: these functions read an :class:`~grainplug.result.AnalysisResult`
(imported here only for type checking) and return plain JSON-ready values.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ._format import rounded
from ._version import __version__
from .measures.tracks import edge_speed_mm_s
from .params import runs_backwards
from .warning_codes import codes_of

if TYPE_CHECKING:
    from .calibration.tube import TubeGeometry
    from .result import AnalysisResult

CONVENTIONS = ("positions in mm along the tube from the upstream end of the view, increasing "
               "with the flow; celerity in m/s, positive downstream (negative: plugs climb)")


#: version of the run's tables (``plug_edges.csv``, ``tracks.csv``; in ``summary.json``): it changes
#: whenever a column changes meaning or type
TABLES_SCHEMA_VERSION = 2  # 2: movie_frame, first_movie_frame, last_movie_frame

#: ``plug_edges.csv``: column -> (type as ``pandas.read_csv`` reads it, meaning)
EDGE_SCHEMA: dict[str, tuple[str, str]] = {
    "frame": ("int64", "index among the analysed frames (0 = the first)"),
    "movie_frame": ("int64", "the frame's number in the movie (frame plus the first frame of a --start window)"),
    "time_s": ("float64", "time of the frame on the movie's clock, s"),
    "plug_id": ("int64", "the plug's track (tracks.csv)"),
    "top_mm": ("float64", "upstream edge, mm from the upstream end of the view; empty where cut by the view"),
    "bottom_mm": ("float64", "downstream edge, mm; empty where cut by the view"),
}

#: the columns of ``edges_long.csv``: one row per plug edge per frame, in trackpy's long layout (``frame``,
#: ``particle``), for tools that read tracks that way
EDGE_LONG_SCHEMA: dict[str, tuple[str, str]] = {
    "frame": ("int64", "index among the analysed frames (0 = the first)"),
    "time_s": ("float64", "time of the frame on the movie's clock, s"),
    "particle": ("int64", "the plug's track (tracks.csv's plug_id), as trackpy names a track"),
    "edge": ("str", "upstream or downstream"),
    "position_mm": ("float64", "the edge, mm from the upstream end of the view"),
    "velocity_m_s": ("float64", "the edge's velocity, m/s, positive downstream: central difference over the frames "
                                "before and after (one-sided at a track's ends); empty when the edge is not seen "
                                "in a neighbouring frame"),
}

#: ``tracks.csv``: column -> (type as ``pandas.read_csv`` reads it: int64, float64, bool or string; meaning)
TRACK_SCHEMA: dict[str, tuple[str, str]] = {
    "plug_id": ("int64", "the track's id (plug_edges.csv)"),
    "first_frame": ("int64", "first frame it is seen in (an index among the analysed frames, as in plug_edges.csv)"),
    "last_frame": ("int64", "last frame it is seen in (the same index)"),
    "first_movie_frame": ("int64", "the number of its first frame in the movie"),
    "last_movie_frame": ("int64", "the number of its last frame in the movie"),
    "first_time_s": ("float64", "time of its first frame, s"),
    "last_time_s": ("float64", "time of its last frame, s"),
    "n_frames": ("int64", "frames it is seen in"),
    "n_frames_whole": ("int64", "frames where both its edges are in view"),
    "celerity_m_s": ("float64", "slope of a straight line through its upstream edge (downstream edge if fewer than "
                                "two seen), m/s, positive downstream, the train's common oscillation (the celerity "
                                "fit's periodic part) taken out first as the headline's fit does, so that a track seen "
                                "over part of a period is not tilted by the swing; empty with fewer than two edges"),
    "mean_length_mm": ("float64", "mean length over the frames where it is whole, mm; empty if never whole"),
    "median_length_mm": ("float64", "median of the same, mm"),
    "started_by": ("string", "start (first frame), entered (the view), merge, split or cut (a reviewer's split)"),
    "ended_by": ("string", "end (last frame), left (the view), merge, split or cut (a reviewer's split)"),
    "composite": ("bool", "True when born of a merge or ended by a split (left out of length averages)"),
}

#: columns of :attr:`AnalysisResult.tracks` and ``tracks.csv``
TRACK_COLUMNS = tuple(TRACK_SCHEMA)


def track_rows(res: AnalysisResult) -> list[dict[str, Any]]:
    """One dict per plug track (:data:`TRACK_COLUMNS`; NaN where a figure cannot be had).

    Notes
    -----
    A track's celerity is the slope of a straight line fitted to its upper edges (its lower
    edges when fewer than two upper ones are in view), in m/s, less the train's common oscillation
    (:meth:`grainplug.measures.motion.Motion.periodic_mm`, the periodic part of the headline's fit): a track seen
    over a part of a period is not tilted by where in the swing it starts and ends. Its lengths are over the
    frames where both edges are in view. Tracks left without a plug by a reviewer's
    corrections (excluded, or merged into another) have no row.
    """
    r, tr, t = res.runs, res.links, res.diagram.time_s
    off = res.first_movie_frame
    rows = []
    for tid in range(len(tr)):
        sel = tr.run_track == tid
        if not sel.any() and tr.first_frame[tid] < 0:
            continue
        frames = r.frame[sel]
        top, bot = r.top_mm[sel], r.bottom_mm[sel]
        whole = np.isfinite(top) & np.isfinite(bot)
        swing = res.motion.periodic_mm(t[frames]) if res.motion is not None else 0.0
        cel = edge_speed_mm_s(t[frames], top - swing, bot - swing) / 1000
        lengths = (bot - top)[whole]
        rows.append({
            "plug_id": tid, "first_frame": int(tr.first_frame[tid]), "last_frame": int(tr.last_frame[tid]),
            "first_movie_frame": int(tr.first_frame[tid]) + off, "last_movie_frame": int(tr.last_frame[tid]) + off,
            "first_time_s": float(t[tr.first_frame[tid]]), "last_time_s": float(t[tr.last_frame[tid]]),
            "n_frames": int(sel.sum()), "n_frames_whole": int(whole.sum()), "celerity_m_s": cel,
            "mean_length_mm": float(lengths.mean()) if lengths.size else np.nan,
            "median_length_mm": float(np.median(lengths)) if lengths.size else np.nan,
            "started_by": tr.started_by[tid], "ended_by": tr.ended_by[tid], "composite": bool(tr.composite(tid)),
        })
    return rows


_r = rounded


def _tube_model(res: AnalysisResult) -> dict[str, object] | None:
    """The tube model's estimates for summary.json (None when the scale was given)."""
    b = res.bore
    if b is None:
        return None
    walls = res.tube.walls
    return {
        "method": b.method, "bore_px": {k: _r(v, 3) for k, v in b.estimates_px.items()},
        "agreement": _r(b.agreement, 4), "visible_fraction": _r(b.visible_fraction, 4),
        "lamp_half_angle_deg": _r(b.lamp_half_angle_deg, 2), "back_lit": res.tube.back_lit,
        "outer_width_px": _r(2 * walls.outer_half_px, 3) if walls else None,
        "stripe_separation_px": _r(2 * walls.stripe_half_px, 3) if walls else None,
        "glass_index": res.params.glass_index, "outer_diameter_mm": res.params.tube_outer_diameter_mm,
    }


def uncertainty(res: AnalysisResult) -> dict[str, object] | None:
    """The celerity's and the plug length's standard errors by source — the tracks' scatter, the scale and, for the
    celerity, the camera's unmeasured wander along the tube when there is one — and which dominates their
    intervals (for summary.json)."""
    m, ln, k = res.motion, res.lengths, res.scale_rel_sd
    if m is None:
        return None

    def split(terms: dict[str, float | None], unit: str, nd: int) -> dict[str, object] | None:
        if not all(v is not None and np.isfinite(v) for v in terms.values()):
            return None
        return {**{f"{name}_se_{unit}": _r(v, nd) for name, v in terms.items()},
                "dominant": max(terms, key=lambda name: terms[name])}  # type: ignore[arg-type, return-value]

    camera = float(m.celerity_se_camera_m_s or 0.0)
    out: dict[str, object] = {"celerity": split({"tracks": m.celerity_se_tracks_m_s, "scale": abs(m.celerity_m_s) * k,
                                                 **({"camera": camera} if camera > 0 else {})}, "m_s", 8)}
    if ln is not None and ln.plug_length_mm is not None and ln.plug_length_sd_mm is not None and ln.n_plugs_measured:
        out["plug_length"] = split({"tracks": ln.plug_length_sd_mm / np.sqrt(ln.n_plugs_measured),
                                    "scale": ln.plug_length_mm * k}, "mm", 4)
    return out


def flow_angle_deg(tube: TubeGeometry, direction: str) -> float:
    """Direction of the flow in the image, degrees from +x towards +y (y down)."""
    a = np.radians(tube.tilt_deg)
    ex, ey = np.sin(a), np.cos(a)
    if runs_backwards(direction):
        ex, ey = -ex, -ey
    if tube.orientation == "horizontal":
        ex, ey = ey, ex
    return float(np.degrees(np.arctan2(ey, ex)))


def _grain_velocity(res: AnalysisResult) -> dict[str, Any]:
    """The packed grains' mean velocity inside the plugs (downstream positive) with its 95 % interval, and the
    lag and number of windows it was measured with; null when not measured (:mod:`grainplug.measures.creep`)."""
    g = res.grain_velocity
    ci = None if g is None or g.ci95_m_s is None else [_r(g.ci95_m_s[0], 6), _r(g.ci95_m_s[1], 6)]
    return {"grain_velocity_in_plugs_m_s": None if g is None else _r(g.mean_m_s, 6),
            "grain_velocity_in_plugs_ci95_m_s": ci if g is not None and g.mean_m_s is not None else None,
            "grain_velocity_in_plugs_lag_frames": None if g is None or g.mean_m_s is None else int(g.lag_frames),
            "grain_velocity_in_plugs_windows": 0 if g is None else len(g.velocity_m_s)}


def _compactness(res: AnalysisResult) -> dict[str, Any]:
    """The plugs' and the bubbles' compactness with their intervals, or why it was not measured."""
    c = res.compactness
    if c is None:
        return {"plugs": None, "bubbles": None, "note": res.compactness_note or None}

    def ci(v: tuple[float, float] | None) -> list[float | None] | None:
        return [_r(x, 4) for x in v] if v else None

    return {"plugs": _r(c.plug, 4), "plugs_ci95": ci(c.plug_ci95), "n_plugs": c.n_plugs,
            "bubbles": _r(c.bubble, 4), "bubbles_ci95": ci(c.bubble_ci95), "n_bubbles": c.n_bubbles,
            "packed_reference": res.params.packed_compactness, "note": None}


def _mass_flow(res: AnalysisResult) -> dict[str, Any]:
    """The grains' mass flow rate from the movie with its interval, formula and terms, or why it is not given
    (:mod:`grainplug.measures.mass_flow`)."""
    from .measures.mass_flow import FORMULA

    q = res.mass_flow
    ci = None if q.ci95_g_s is None else [_r(q.ci95_g_s[0], 5), _r(q.ci95_g_s[1], 5)]
    return {"mass_flow_rate_g_s": _r(q.rate_g_s, 5), "mass_flow_rate_ci95_g_s": ci,
            "mass_flow_rate_formula": FORMULA,
            "mass_flow_rate_terms_g_s": None if q.rate_g_s is None else {"creep": _r(q.creep_g_s, 5),
                                                                         "pattern": _r(q.pattern_g_s, 5)},
            "mean_compactness": _r(q.mean_compactness, 4),
            "mean_compactness_ci95": None if q.mean_compactness_ci95 is None else [
                _r(x, 4) for x in q.mean_compactness_ci95],
            "mass_flow_rate_note": q.note or None}


def build_summary(res: AnalysisResult) -> dict[str, Any]:
    """JSON-ready summary with provenance (see ``summary.json`` in the docs)."""
    m, ln, tube = res.motion, res.lengths, res.tube
    D = res.params.tube_diameter_mm
    plug_len = ln.plug_length_mm if ln else None
    return {
        "grainplug_version": __version__,
        "tables_schema_version": TABLES_SCHEMA_VERSION,
        "input": res.input,
        "movie": res.info.as_dict(),
        "parameters": res.params.as_record(),
        "has_plugs": res.has_plugs,
        "statement": res.statement or None,
        "celerity_m_s": _r(m.celerity_m_s) if m else None,
        "celerity_ci95_m_s": [_r(x) for x in m.celerity_ci95_m_s] if m else None,
        "uncertainty": uncertainty(res),
        "plug_length_mm": _r(plug_len, 4),
        "plug_length_ci95_mm": [_r(x, 4) for x in ln.plug_length_ci95_mm] if ln and ln.plug_length_ci95_mm else None,
        "plug_length_sd_mm": _r(ln.plug_length_sd_mm, 4) if ln else None,
        "plug_length_over_diameter": _r(plug_len / D, 4) if plug_len else None,
        "bubble_length_mm": _r(ln.bubble_length_mm, 4) if ln else None,
        "bubble_length_ci95_mm": (
            [_r(x, 4) for x in ln.bubble_length_ci95_mm] if ln and ln.bubble_length_ci95_mm else None
        ),
        "oscillation_frequency_hz": _r(m.oscillation_frequency_hz, 4) if m and m.oscillation_frequency_hz else None,
        # absent, not 0, without an oscillation
        "oscillation_amplitude_mm": (_r(m.oscillation_amplitude_mm, 4) if m and m.oscillation_frequency_hz
                                     else None),
        "oscillation_frequency_ci95_hz": ([_r(v) for v in m.oscillation.frequency_ci95_hz]
                                          if m and m.oscillation_frequency_hz and m.oscillation else None),
        "oscillation_amplitude_ci95_mm": ([_r(v, 4) for v in m.oscillation.amplitude_ci95_mm]
                                          if m and m.oscillation_frequency_hz and m.oscillation else None),
        "oscillation_kind": m.oscillation.kind if m and m.oscillation_frequency_hz and m.oscillation else None,
        "oscillation_stick_fraction": (_r(m.oscillation.stick_fraction, 3)
                                       if m and m.oscillation_frequency_hz and m.oscillation else None),
        "oscillation_explained_fraction": _r(m.explained_fraction, 4) if m else None,
        "regime": m.regime if m else "none",
        "n_plugs": int(ln.n_plugs_measured) if ln else 0,
        "n_tracks": len(res.links),
        "n_bubbles": int(ln.n_bubbles_measured) if ln else 0,
        "n_edges_used": m.n_edges if m else 0,
        "n_frames": int(res.diagram.n_frames),
        "fps": res.info.fps,
        "duration_s": _r(res.diagram.n_frames / res.info.fps, 6),
        "mm_per_px": _r(res.mm_per_px, 6),
        "scale_source": res.scale_source,
        "scale_rel_sd": _r(res.scale_rel_sd, 6),
        "tube_diameter_mm": D,
        "tube_diameter_px": _r(res.bore.diameter_px if res.bore else res.params.tube_diameter_mm / res.mm_per_px, 4),
        "tube_visible_width_px": _r(tube.inner_diameter_px, 4),
        "tube_model": _tube_model(res),
        "tube_axis_angle_deg": _r(flow_angle_deg(tube, res.flow_direction), 4),
        "tube_tilt_deg": _r(tube.tilt_deg, 4),
        "tube_orientation": tube.orientation,
        "tube_detection": tube.method,
        "flow_direction": res.flow_direction,
        "flow_direction_source": res.flow_direction_source,
        "falling_grain_speed_m_s": _r(res.falling_grain_speed_m_s, 4),
        "compactness": _compactness(res),
        **_grain_velocity(res),
        **_mass_flow(res),
        "blind_stretches": [b.as_dict() for b in res.blind],
        "tube_unseen_frames": [[int(a), int(b)] for a, b in res.tube_unseen],
        "shake": res.shake.as_dict() if res.shake is not None else None,
        "light": res.lamp.as_dict() if res.lamp is not None else None,
        "warnings": list(res.warnings),
        "warning_codes": codes_of(res.warnings),
        **_corrections_fields(res),
        "corrections_applied": res.corrections.as_dict()["edits"] if res.corrections is not None else [],
        "view_length_mm": _r(float(res.diagram.position_mm[-1] + 0.5 * res.mm_per_px), 4),
        "illumination": {
            "plugs_darker_than_bubbles": res.normalized.plugs_darker,
            "plug_bubble_separation_eta": _r(res.normalized.separation_eta, 4),
            # where the separation alone was short: the same along the tube averaged over a third of the shortest plug
            "plug_bubble_separation_eta_averaged": (None if res.normalized.averaged_eta is None
                                                    else _r(res.normalized.averaged_eta, 4)),
            "flicker_sd": _r(float(np.std(res.normalized.frame_gain)), 5),
            "gradient_along_view": _r(float(res.normalized.position_gain[-1] / res.normalized.position_gain[0] - 1), 4),
        },
        "timings_s": dict(res.timings),
        "conventions": CONVENTIONS,
    }


def _corrections_fields(res: AnalysisResult) -> dict[str, object]:
    """The edits applied, in words, and the times the measures use: the record, or what its corrections keep
    of it (``kept_window_s``, ``not_plugs_s``); the corrections replayed once."""
    t0, t1 = float(res.diagram.time_s[0]), float(res.diagram.time_s[-1])
    if res.corrections is None:
        return {"corrections": [], "kept_window_s": [_r(t0, 6), _r(t1, 6)], "not_plugs_s": []}
    from .corrections import replayed  # imported here: only a corrected result needs the replay

    st = replayed(res)
    lo, hi = st.window
    lo = t0 if lo is None else max(lo, t0)
    hi = t1 if hi is None else min(hi, t1)
    window = [_r(lo, 6), _r(hi, 6)] if lo <= hi else None  # None: the window holds none of the record
    merged: list[list[float]] = []  # the spans within the record, overlaps joined
    for a, b in sorted((max(a, t0), min(b, t1)) for a, b in st.spans):
        if a > b:
            continue
        if merged and a <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], b)
        else:
            merged.append([a, b])
    return {"corrections": [e.describe() for e in st.applied], "kept_window_s": window,
            "not_plugs_s": [[_r(a, 6), _r(b, 6)] for a, b in merged]}
