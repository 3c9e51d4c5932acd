"""What an analysis checks about itself: each function returns the warnings (sentences with the fix) that one
doubt gives, or refuses what cannot be measured at all. Arrays and frozen dataclasses in, sentences out.

The pipeline (:func:`grainplug.analyze`) calls them at the stage where what they judge is known; nothing
here changes a measure.
"""

from __future__ import annotations

import numpy as np

from .band import Band
from .calibration.scale import CUT_SIDE_SHARE
from .calibration.tube import TubeGeometry
from .diagram.light import MovingLight
from .errors import ParameterError, non_finite_frames
from .measures import Motion
from .measures.flow import assumed_down
from .measures.grains import GrainMotion
from .measures.shake import SHAKE_MIN_RMS_PX, Shake
from .measures.still import STILL_CONTENTS, BlindStretch, still_tracks
from .params import AnalysisParams
from .plugs import Runs, Tracks
from .readers import MovieInfo
from .warning_codes import coded

#: speeds no plug or falling grain reaches in a gravity-driven pipe flow (m/s): free fall from
#: rest over 2 m gives 6.3 m/s; the paper's plugs move at 0.04-0.1 m/s, its grains fall at 0.8 m/s
IMPLAUSIBLE_SPEED_M_S = 10.0

#: share of the tube's pixels at the sensor's top value above which a warning is given
SATURATION_WARN = 0.01

def check_movie(info: MovieInfo) -> None:
    if not info.fps:
        raise ParameterError(f"{info.path}: the frame rate is unknown (image folders, arrays and some TIFFs "
                             "hold none) — give the camera's frame rate", param="fps")
    if info.n_frames < 8:
        raise ParameterError(f"{info.path} holds {info.n_frames} frame{'' if info.n_frames == 1 else 's'}; at least 8 "
                             "are needed", param="source")

#: another region whose frame-to-frame variation reaches this share of the tube's is reported
OTHER_REGION_SHARE = 0.5

def other_moving_regions(frames: list[np.ndarray], tube: TubeGeometry) -> list[str]:
    """A warning when the sampled frames move as much somewhere else across the tube as in it (a second
    tube in view): the analysis follows one tube only, and says which, and how to choose."""
    if len(frames) < 4:
        return []
    vertical = tube.orientation == "vertical"
    h = tube.canonical_shape[0]
    step = max(1, h // 32)  # 32 lines along the tube are plenty for a profile across it
    lines = [np.asarray(f)[::step] if vertical else np.asarray(f)[:, ::step] for f in frames]
    # one channel (green, most of the luminance) is enough to see where the frames change
    grey = np.stack([g[..., min(1, g.shape[2] - 1)] if g.ndim == 3 else g for g in lines]).astype(np.float32)
    if not vertical:
        grey = grey.transpose(0, 2, 1)
    across = grey.std(axis=0).mean(axis=0)  # temporal variation per column across the tube
    axis = tube.axis_x(np.array([0.0, h - 1.0]))
    half = 1.5 * tube.inner_diameter_px + 3
    cols = np.arange(across.size)
    inside = (cols >= axis.min() - half) & (cols <= axis.max() + half)
    if not inside.any() or inside.all():
        return []
    level = float(np.median(across[(cols >= axis.min() - 0.4 * tube.inner_diameter_px)
                                   & (cols <= axis.max() + 0.4 * tube.inner_diameter_px)]))
    # the still background's variation (noise, flicker): a tube whose frames change no more than it (plugs
    # that hardly move in a very short record) gives nothing to compare with
    floor = float(np.percentile(across[~inside], 10))
    if level <= 2.0 * floor:
        return []
    hot = ~inside & (across > max(OTHER_REGION_SHARE * level, 2.0 * floor))
    if level <= 0 or hot.sum() < max(3, 0.3 * tube.inner_diameter_px):
        return []
    where = cols[hot]
    name = "x" if tube.orientation == "vertical" else "y"
    return [coded("tube.second_region",
        f"the frames change as much around {name} = {int(where.min())}-{int(where.max())} px as in the tube "
        f"analysed (at {name} = {float(axis.mean()):.0f} px): a second tube? Only this one is analysed — "
        "give roi=(x0, y0, x1, y1) to choose")]

def cut_by_the_frame(tube: TubeGeometry, params: AnalysisParams) -> list[str]:
    """A warning when the tube's moving contents run up to a side of the frame: the tube is cut there."""
    if tube.side_variation <= CUT_SIDE_SHARE:
        return []
    fix = ("widen roi= to hold the whole tube and its walls" if params.roi else
           "frame the whole tube and its walls (or give roi= around a tube that is whole in view)")
    return [coded("tube.cut_by_frame",
        f"the tube's contents change at a side of the frame {100 * tube.side_variation:.0f} % as much as "
        "anywhere: the tube is cut by the frame's edge, so the tube found, its width, the scale from it and "
        f"every measure may be wrong — {fix}")]

#: the width over which a tube's contents are seen, against its bore: a back-lit tube looks up to 35 % narrower
#: (by the lamp's size), never much wider
SEEN_OVER_BORE = (0.6, 1.15)

#: grains and air seen but no plug (or nothing moving): the tube is seen where the contents or the mean image's
#: edges show it, inside the bore (0.59-0.99 of it in the synthetic and an independent renderer's cases); narrower
#: than this share, the given scale is the doubt (a scale 10 times too fine makes every plug "shorter than
#: min_plug_mm"). With one material only (sparse falling grains) the tube can be seen over a few pixels: no doubt.
SEEN_OVER_BORE_NO_PLUGS = 0.3

def given_scale_doubts(tube: TubeGeometry, params: AnalysisParams, *, has_plugs: bool,
                        two_phase: bool = True) -> list[str]:
    """A warning when the tube seen is far wider or narrower than a given scale makes its bore (a wrong
    ``mm_per_px`` or tube diameter, or something in view that is not the tube)."""
    if not params.mm_per_px:
        return []
    expected_px = params.tube_diameter_mm / float(params.mm_per_px)
    ratio = tube.inner_diameter_px / expected_px
    # nothing moved (back_lit None): the tube is seen by the mean image's edges, not its bore's contents; one
    # material only (an empty tube with a few grains falling): seen over a few pixels, nothing to doubt by
    low = (SEEN_OVER_BORE[0] if has_plugs and tube.back_lit is not None else
           SEEN_OVER_BORE_NO_PLUGS if two_phase else 0.0)
    # (a camera that shakes across the tube does not widen it: the sampled frames are registered before it is found)
    if low <= ratio <= SEEN_OVER_BORE[1]:
        return []
    return [coded("scale.given_vs_tube",
        f"the tube's contents are seen over {tube.inner_diameter_px:.1f} px, but the given scale makes its "
        f"{params.tube_diameter_mm:g} mm bore {expected_px:.1f} px ({ratio:.2g} times): check mm_per_px= "
        "and tube_diameter_mm=, and that what was found is the tube")]

def check_background(params: AnalysisParams, info: MovieInfo) -> None:
    """Refuse a background or packed picture of another size than the movie's frames."""
    for name, what, bg in (("background", "background", params.background),
                            ("packed", "packed picture", params.packed)):
        if bg is not None and tuple(bg.image.shape[:2]) != (info.height, info.width):
            raise ParameterError(f"the {what} is {bg.image.shape[1]} x {bg.image.shape[0]} px but the "
                                 f"movie's frames are {info.width} x {info.height}: take it with the movie's camera "
                                 "and settings", param=name)

def check_finite(values: np.ndarray, info: MovieInfo) -> None:
    """Float frames with NaN or infinite pixels in the tube (beyond the sampled frames, checked with the tube) are
    refused: their band averages would read as a change of light."""
    if np.dtype(info.dtype).kind != "f":
        return
    bad = np.flatnonzero(~np.isfinite(values).all(axis=1))
    if bad.size:
        shown = ", ".join(str(k) for k in bad[:5]) + (", ..." if bad.size > 5 else "")
        raise non_finite_frames(f"{bad.size} of the {len(values)} frames (frame{'s' if bad.size > 1 else ''} "
                                f"{shown} of the analysis)")

def saturated_share(frames: list[np.ndarray], band: Band, info: MovieInfo) -> float:
    """Share of the tube's pixels (the band's, in the frames kept from the sample) at the top
    value the camera can give (``2**bit_depth - 1``, any channel)."""
    if not frames or np.dtype(info.dtype).kind == "f":  # float frames have no top value a camera clips at
        return 0.0
    top = (1 << min(info.bit_depth, 8 * np.dtype(info.dtype).itemsize)) - 1
    hits = [np.asarray(f)[band.rows, band.cols] >= top for f in frames]
    return float(np.mean([h.any(axis=-1).mean() if h.ndim == 3 else h.mean() for h in hits]))

def implausible(motion: Motion | None, grains: GrainMotion | None, saturation: float) -> list[str]:
    """Warnings for numbers that cannot be right, each with what to check."""
    out = implausible_speeds(None if motion is None else motion.celerity_m_s,
                             None if grains is None else grains.speed_m_s)
    if saturation > SATURATION_WARN:
        out.append(coded("light.saturated",
            f"{100 * saturation:.1f} % of the tube's pixels are at the camera's top value (saturated): plug "
            "and bubble contrast is lost there — lower the exposure or the light"))
    return out

def implausible_speeds(celerity_m_s: float | None, falling_m_s: float | None) -> list[str]:
    """Warnings for a plug celerity or a falling grains' speed no gravity-driven pipe flow reaches."""
    out = []
    if celerity_m_s is not None and abs(celerity_m_s) > IMPLAUSIBLE_SPEED_M_S:
        out.append(coded("plugs.implausible_speed",
            f"the plugs move at {celerity_m_s:.3g} m/s, faster than grains can fall in a pipe: check "
            "the frame rate (fps=) and the scale (calibration= or mm_per_px=)"))
    if falling_m_s is not None and abs(falling_m_s) > IMPLAUSIBLE_SPEED_M_S:
        out.append(coded("plugs.implausible_speed",
            f"the grains fall through the bubbles at {falling_m_s:.3g} m/s, faster than free fall "
            "allows: check the frame rate (fps=) and the scale"))
    return out

def still_regions(blind: tuple[BlindStretch, ...]) -> list[str]:
    """A warning naming the stretches of the tube (1 mm or more) where nothing changed over the record while the
    rest of it did (an opaque object over the tube: a clamp, a fitting, the tube's end), which the measures took
    as blind (:func:`grainplug.measures.diagram.measure_diagram`)."""
    spans = [(b.from_mm, b.to_mm) for b in blind if b.found_by == STILL_CONTENTS and b.blind and b.kept]
    if not spans:
        return []
    where = ", ".join(f"{lo:.1f}-{hi:.1f} mm" for lo, hi in spans[:4]) + (", ..." if len(spans) > 4 else "")
    return [coded("still.region",
        f"nothing changes at {where} (from the upstream end of the view) over the whole record while the rest "
        "of the tube does: an object over the tube there (a clamp, a fitting, the tube's end)? It was taken as a "
        "blind stretch: plugs touching it are measured as cut there, and bubbles across it not at all — if it is "
        "not, or to name others, remove or add blind stretches in grainplug review, or give mask_mm=")]


def still_objects(runs: Runs, links: Tracks, time_s: np.ndarray, motion: Motion | None,
                  mm_per_px: float) -> list[str]:
    """A warning for the tracks that stay put while the plug train moves
    (:func:`grainplug.measures.still.still_tracks`): a still object over the tube (a clamp, a label, a fitting, the
    tube's end) taken for a plug, left out of the plug lengths."""
    still = [f"plug {tid} at {a:.0f}-{b:.0f} mm for {span:.2g} s"
             for tid, (a, b, span) in still_tracks(runs, links, time_s, motion, mm_per_px).items()]
    if not still or motion is None or motion.celerity_m_s is None:
        return []
    return [coded("still.track",
        f"{'; '.join(still[:5])}{' and more' if len(still) > 5 else ''} (from the upstream end of the view): "
        f"{'it stays' if len(still) == 1 else 'they stay'} put while the plugs move at "
        f"{motion.celerity_m_s:+.3g} m/s — a still object over the tube (a clamp, a label, a fitting, the tube's "
        "end)? Left out of the plug lengths — to keep such a thing out of the analysis, give mask_mm= or roi=; a "
        "plug that stays put while the others move is no plug of this train")]

#: plugs just over ``min_plug_mm``: this share of the whole plugs seen within :data:`NEAR_THRESHOLD` of it ...
NEAR_SHARE = 0.1

#: ... above it (relative) is a train whose shorter plugs are dropped
NEAR_THRESHOLD = 0.2

def near_the_threshold(runs: Runs, motion: Motion | None, params: AnalysisParams) -> list[str]:
    """A warning when many plugs of a measured train are just over ``min_plug_mm``: those just under it are
    dropped (the bubbles about them merge across) and those at it come and go (their tracks split). Without a
    train (clumps of falling grains cut at the threshold) lowering it would make plugs of the clumps: nothing said."""
    if motion is None:
        return []
    whole = np.isfinite(runs.top_mm) & np.isfinite(runs.bottom_mm)
    lengths = (runs.bottom_mm - runs.top_mm)[whole]
    if lengths.size < 10:
        return []
    near = float(np.mean(lengths <= params.min_plug_mm * (1 + NEAR_THRESHOLD)))
    if near < NEAR_SHARE:
        return []
    return [coded("plugs.near_min_length",
        f"{100 * near:.0f} % of the plugs seen are within {100 * NEAR_THRESHOLD:.0f} % of min_plug_mm = "
        f"{params.min_plug_mm:g} mm: shorter plugs are likely there, dropped (the bubbles about them are "
        "measured as one) and plugs at the threshold come and go (their tracks split) — lower min_plug_mm=")]

def frame_cadence(motion: Motion | None, info: MovieInfo) -> list[str]:
    """A warning when the plug edges move back and forth with a period of a few whole frames (the recording's
    cadence): left out of the oscillation search in a movie compressed between frames, else reported in doubt."""
    if motion is None or not motion.frame_locked_hz or not info.fps:
        return []
    f, amp = motion.frame_locked_hz, motion.frame_locked_mm
    frames = f"a period of {info.fps / f:.3g} frames"
    if motion.oscillation_frequency_hz is not None and abs(motion.oscillation_frequency_hz - f) < 1e-9:
        return [coded("plugs.frame_cadence",
            f"the oscillation found ({f:.4g} Hz, {amp:.2g} mm) has {frames}: a pattern locked to the camera's "
            "frame clock is more likely the recording's (a movie compressed and saved again, alternate exposures, "
            "a lamp's ripple locked to the frame rate) than the plugs' — check the movie was never compressed")]
    return [coded("plugs.frame_cadence",
        f"the plug edges move back and forth by {amp:.2g} mm at {f:.4g} Hz ({frames}): the cadence of the "
        f"movie's compression ({info.format.partition(':')[2] or info.format}: its group of pictures holds the "
        "edges still in some frames and moves them in others), not an oscillation of the plugs, and not reported "
        "as one — record losslessly or at a higher quality (lower crf)")]


def guessed_sign(flow_source: str, motion: Motion | None) -> list[str]:
    """A warning when a celerity was measured along a flow direction only assumed (``flow_source`` is
    gravity's: down a vertical tube): its sign rests on the camera having been upright."""
    why = assumed_down(flow_source)
    if why is None or motion is None or motion.celerity_m_s is None:
        return []
    return [coded("flow.sign_assumed",
        f"the grains falling through the bubbles give no direction ({why or 'none seen'}), so the flow is "
        "assumed to run down the image (gravity down) and the celerity's sign rests on that: if the camera was "
        "not upright, give the flow direction (flow_direction=)")]


def shaken(shake: Shake | None, motion: Motion | None) -> list[str]:
    """A warning when the camera shook (the tube moved in the image): how much, at what frequency, what was
    corrected, and that a plug motion at that frequency is not reported as the plugs'."""
    if shake is None:
        return []
    if shake.too_large:
        return [coded("shake.too_large",
            f"the camera moved the tube across by up to {shake.reach_across_px:.2g} px, more than the "
            f"{shake.band_margin_px:.2g} px it may before the diagram's band takes in the tube's walls: the plug "
            "edges, lengths and motion may be wrong (a plug motion at the camera's frequency is not reported as "
            "the plugs') — steady the camera (a heavier stand, away from the pump)")]
    if not shake.shaking:
        return []
    f = f" at {shake.frequency_hz:.3g} Hz" if shake.frequency_hz else ""
    parts = [f"{v:.2g} px rms {name}" for v, name in ((shake.rms_across_px, "across the tube"),
                                                     (shake.rms_along_px, "along it")) if v is not None]
    if shake.along_px is not None:
        if shake.held_along:
            fix = ("the diagram was held still against the tube (its motion along the tube measured on "
                   f"{shake.along_source}), and a plug motion at that frequency is not reported as the plugs'")
        else:  # measured, and too small to move the diagram for
            fix = (f"its motion along the tube, measured on {shake.along_source}, stays within its noise or "
                   f"{SHAKE_MIN_RMS_PX:g} px rms, so the diagram was left as read; a plug motion at that frequency is "
                   "not reported as the plugs'")
        return [coded("shake.corrected", f"the camera shook{f} ({', '.join(parts)}): {fix}")]
    osc = "" if motion is None or motion.regime != "oscillating" else " (the oscillation reported is at another)"
    drift = ""
    if motion is not None and shake.mm_per_px and len(motion.time_s) > 1:
        # what the camera's unmeasured drift along the tube does to the drift of the plugs
        per_px = shake.mm_per_px / max(float(motion.time_s[-1] - motion.time_s[0]), 1e-9) / 1000.0
        share = (f", {100.0 * per_px / abs(motion.celerity_m_s):.2g} % of it" if motion.celerity_m_s else "")
        drift = (f"; and a drift of the camera along the tube moves the celerity by {per_px:.2g} m/s per pixel over "
                 f"the record{share}, beyond its interval, which assumes the camera drifted along as it did across")
    return [coded("shake.along_unmeasured",
        f"the camera shook{f} ({', '.join(parts)}, measured on the tube's walls); its motion along the tube could "
        f"not be measured ({shake.along_source}), so the plug edges carry it: a plug motion at that frequency is "
        f"taken for the camera's and not reported{osc}{drift} — steady the camera, or put a mark beside the tube "
        "(a clamp, a label, a ruler) to measure it on")]


def tube_out_of_view(stretches: tuple[tuple[int, int], ...], time_s: np.ndarray, *, first: int = 0) -> list[str]:
    """A warning naming the stretches of frames in which the tube's walls were not seen (``first``: the movie's
    number of the first analysed frame), which were not measured."""
    if not stretches:
        return []
    n = sum(b - a + 1 for a, b in stretches)
    where = ", ".join(f"{first + a}-{first + b} ({time_s[a]:.3f}-{time_s[b]:.3f} s)" for a, b in stretches[:4])
    more = ", ..." if len(stretches) > 4 else ""
    return [coded("frames.tube_unseen",
        f"the tube is not in view in {n} of {len(time_s)} frames ({where}{more}): its walls are not seen there "
        "(something in front of it, the camera knocked off it, the lamp out) — those frames are doubtful and were "
        "not measured; check them in the movie")]


#: the codes of the warnings :func:`train_warnings` gives: those a reviewer's corrections change, recomputed at
#: each replay (:func:`grainplug.corrections.apply_corrections`)
TRAIN_CODES = frozenset({"flow.sign_assumed", "plugs.frame_cadence", "plugs.oscillation_no_interval",
                         "still.region", "shake.too_large",
                         "shake.corrected", "shake.along_unmeasured", "still.track", "plugs.near_min_length",
                         "plugs.implausible_speed"})


def train_warnings(runs: Runs, links: Tracks, time_s: np.ndarray, motion: Motion | None, *, mm_per_px: float,
                   params: AnalysisParams, info: MovieInfo, blind: tuple[BlindStretch, ...], shake: Shake | None,
                   flow_source: str, falling_m_s: float | None) -> list[str]:
    """The warnings that judge the plug train (its tracks, motion and blind stretches), in the order a report
    gives them: the analysis gives them on what it detected, and a reviewer's corrections give them again on
    what they keep (a plug excluded takes its warnings with it). Their codes are :data:`TRAIN_CODES`."""
    return [*guessed_sign(flow_source, motion), *frame_cadence(motion, info), *no_interval(motion),
            *still_regions(blind),
            *shaken(shake, motion), *still_objects(runs, links, time_s, motion, mm_per_px),
            *near_the_threshold(runs, motion, params),
            *implausible_speeds(None if motion is None else motion.celerity_m_s, falling_m_s)]


def no_interval(motion: Motion | None) -> list[str]:
    """A warning when an oscillation is reported without its intervals and kind: its frequency, refined by the fit
    of the period-averaged motion, left the spectrum's peak (few periods, or two peaks close together), so the
    fit's intervals are not the peak's (:func:`grainplug.measures.motion.measure_motion`)."""
    if motion is None or motion.oscillation_frequency_hz is None or motion.oscillation is not None:
        return []
    return [coded("plugs.oscillation_no_interval",
        f"the oscillation at {motion.oscillation_frequency_hz:.3g} Hz is given without its 95 % intervals and its "
        "kind: fitted, its frequency moved off the spectrum's peak (too few periods, or two peaks close together) "
        "— film more periods")]


def passing_shadow(shadow: MovingLight | None) -> list[str]:
    """A warning when a light moving along the tube (a passing shadow) was read on the contents and divided out."""
    if shadow is None or shadow.log_gain is None:
        return []
    return [coded("light.moving_shadow",
        f"a light that moves along the tube (a passing shadow, up to {100 * shadow.depth:.0f} % darker, over "
        f"{100 * shadow.share:.0f} % of the diagram) was read on the plugs and bubbles themselves and divided out "
        "(no lamp beside the tube to read it on) — keep people and things from passing between the lamp and the "
        "tube, or film in back light")]


#: the statement of an analysis that saw neither a tube's wall nor a plug followed
NO_TUBE = ("no tube: no wall was seen beside the moving contents and no plug was followed or seen whole — nothing "
           "is measured (a droplet, a jet or a beam is not a tube in view)")


def nothing_whole_without_walls(tube: TubeGeometry, n_whole_plugs: int) -> bool:
    """Whether a back-lit "tube" showed no wall and no plug was seen whole: what was followed is then the ends of
    something else cut by the view (a vibrating beam, a jet), not plugs; nothing is measured on it."""
    return _no_wall_seen(tube) and n_whole_plugs == 0


def _no_wall_seen(tube: TubeGeometry) -> bool:
    """A back-lit "tube" whose walls showed neither the outer silhouette nor the bright stripes."""
    w = tube.walls
    return bool(tube.back_lit and w is not None and not np.isfinite(w.outer_half_px)
                and not np.isfinite(w.stripe_half_px))


def walls_unseen(tube: TubeGeometry, *, has_plugs: bool) -> list[str]:
    """A warning when a back-lit "tube" shows no wall: neither the outer silhouette nor the walls' bright stripes
    beside the moving contents (a droplet, a jet, a moving object that is not in a tube)."""
    if not _no_wall_seen(tube):
        return []
    plugs = ("; no plug was followed or seen whole either, so this is likely no tube" if not has_plugs else
             "; the plugs measured may be something else's")
    return [coded("tube.walls_unseen",
        f"in back light, no tube wall was seen beside the moving contents ({tube.inner_diameter_px:.0f} px wide){plugs}"
        " — check that a tube is in view (a droplet or a jet is not one), or give roi= around it")]
