"""The scale of an analysis (mm per pixel along the tube), decided once, with where it came from and how sure it is.

Three sources, in this order: a scale the user gives, a calibration image of a pattern
(:mod:`grainplug.calibration.pattern`) along the tube's axis, or the tube itself through its
optical model (:mod:`grainplug.calibration.tube_model`). :func:`decide_scale` returns a frozen
:class:`Scale`; the warnings say what is doubtful about it, each with the fix. Arrays and frozen
dataclasses in, the same out: no file is read here.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..warning_codes import all_coded, coded
from .pattern import Calibration
from .tube import TubeGeometry
from .tube_model import AGREEMENT, BACK_LIT_CONTENTS_SD, BACK_LIT_NARROWING, BoreEstimate, WallMeasure, bore_from_model

log = logging.getLogger(__name__)


class TubeFacts(Protocol):
    """What the user knows of the tube (an :class:`~grainplug.params.AnalysisParams` is one)."""

    tube_diameter_mm: float
    tube_outer_diameter_mm: float | None
    glass_index: float


@dataclass(frozen=True)
class Scale:
    """The scale of the frames along the tube.

    Attributes
    ----------
    mm_per_px : float
        mm spanned by one pixel along the tube's axis.
    source : str
        Where it came from, in words (``"user"``, a calibration image, the tube model...).
    rel_sd : float
        Its relative standard uncertainty (0 for a scale given).
    warnings : tuple of str
        What is doubtful about it, each with what to do.
    bore : BoreEstimate or None
        The tube model's estimates of the bore (None when the scale was given).
    map_through : Calibration or None
        A calibration of the movie's frame whose scale varies along the tube by more than
        ``ALONG_TUBE_VARIATION_WARN`` (the lens's distortion, perspective): the samples along the tube are to be
        placed through it (:func:`uniform_samples`) so that they are ``mm_per_px`` apart on the tube. None: one
        scale holds over the view.
    """

    mm_per_px: float
    source: str
    rel_sd: float
    warnings: tuple[str, ...] = ()
    bore: BoreEstimate | None = None
    map_through: Calibration | None = None


def decide_scale(tube: TubeGeometry, facts: TubeFacts, *, mm_per_px: float | None = None,
                 calibration: Calibration | None = None, frame_shape: tuple[int, int]) -> Scale:
    """The scale along the tube: ``mm_per_px`` when given, else the calibration's along the tube's axis,
    else the tube's bore (:func:`grainplug.calibration.tube_model.bore_from_model`) over its diameter.

    Parameters
    ----------
    tube : TubeGeometry
        The tube found in the frames.
    facts : TubeFacts
        The tube's inner (and outer) diameter and its glass' refractive index.
    mm_per_px : float, optional
        A scale the user gives (checked against the tube once plugs are found).
    calibration : Calibration, optional
        A calibration image's scale.
    frame_shape : (int, int)
        The frames' ``(height, width)`` (a calibration of another size is doubted).
    """
    if mm_per_px:
        return Scale(float(mm_per_px), "user", 0.0)
    bore = bore_of(tube, facts)
    from_tube = facts.tube_diameter_mm / bore.diameter_px
    if calibration is None:
        return Scale(from_tube, bore_source(bore, facts), bore.rel_sd, tuple(tube_scale_doubts(tube, bore, facts)),
                     bore)
    value, source, rel_sd, warnings = calibrated_scale(calibration, tube, frame_shape, from_tube,
                                                       facts.tube_diameter_mm, bore)
    return Scale(value, source, rel_sd, tuple(warnings), bore,
                 calibration if maps_along_tube(calibration, tube, frame_shape) else None)


def maps_along_tube(cal: Calibration, tube: TubeGeometry, frame_shape: tuple[int, int]) -> bool:
    """Whether positions along the tube are mapped through the calibration: it is of the movie's frame and its
    scale varies along the tube by more than ``ALONG_TUBE_VARIATION_WARN``."""
    return tuple(cal.image_shape) == tuple(frame_shape) and along_tube(cal, tube)[1] > ALONG_TUBE_VARIATION_WARN


def uniform_samples(cal: Calibration, tube: TubeGeometry, axis_px: np.ndarray, mm_per_px: float) -> np.ndarray:
    """Where to read the samples along the tube so that they lie ``mm_per_px`` apart on it.

    The band's samples are evenly spaced in pixels along the axis (``axis_px``), which a lens's distortion or a
    perspective makes unevenly spaced in mm. This gives, for each sample ``k``, the fractional sample index at
    which the tube is at ``axis_px[k] * mm_per_px`` mm from the view's top (left) edge, through
    :func:`axis_mm`: reading the band there (:func:`grainplug.diagram.extract.resample_positions`) makes every
    position of the analysis (``axis_px * mm_per_px``) right to the calibration's accuracy. Targets beyond the
    ends are read at the ends.

    Returns
    -------
    ndarray
        Fractional indices into ``axis_px``, increasing, one per sample.
    """
    axis = np.asarray(axis_px, float)
    mm = axis_mm(cal, tube, axis)
    return np.interp(axis * mm_per_px, mm, np.arange(len(axis), dtype=float))


#: the contents' change at a side of the frame the tube reaches, as a share of the most they change, above which the
#: tube is cut by the frame (a whole tube: 0; the sample cut by a region of interest: 0.93)
CUT_SIDE_SHARE = 0.3

def bore_of(tube: TubeGeometry, facts: TubeFacts) -> BoreEstimate:
    """The bore's width in pixels from the tube model (the walls' features and what the user knows)."""
    nan = float("nan")
    walls = tube.walls or WallMeasure(nan, nan, (nan, nan), (nan, nan))
    bore = bore_from_model(walls, visible_diameter_px=tube.inner_diameter_px, back_lit=bool(tube.back_lit),
                           inner_diameter_mm=facts.tube_diameter_mm,
                           outer_diameter_mm=facts.tube_outer_diameter_mm, n_glass=facts.glass_index)
    if tube.back_lit is None:  # nothing moved: the edges of the mean image, nothing to model
        bore = BoreEstimate(tube.inner_diameter_px, "edges", {"edges": tube.inner_diameter_px}, rel_sd=0.1)
    log.info("tube model: bore %.2f px by %s; estimates %s", bore.diameter_px, bore.method,
             {k: round(v, 2) for k, v in bore.estimates_px.items()})
    return bore

def bore_source(bore: BoreEstimate, facts: TubeFacts) -> str:
    """Where a scale from the tube came from, in words."""
    d = f"bore {facts.tube_diameter_mm:g} mm = {bore.diameter_px:.2f} px"
    glass = f"glass n = {facts.glass_index:g}"
    if bore.method == "outer":
        return (f"tube model: outer silhouette ({facts.tube_outer_diameter_mm:g} mm = "
                f"{bore.diameter_px * facts.tube_outer_diameter_mm / facts.tube_diameter_mm:.2f} px), {d}")
    if bore.method == "outer and stripe":
        return (f"tube model: outer silhouette ({facts.tube_outer_diameter_mm:g} mm) and refraction stripes "
                f"({glass}) combined, {d}")
    if bore.method == "stripe + outer":
        return f"tube model: refraction stripes and outer silhouette ({glass}), {d}"
    if bore.method == "stripe":
        shape = (f"outer diameter {facts.tube_outer_diameter_mm:g} mm" if facts.tube_outer_diameter_mm
                 else "outer/inner diameter assumed 1.83")
        return f"tube model: refraction stripes ({glass}, {shape}), {d}"
    if bore.method == "contents":
        return f"tube inner width seen through its contents ({d})"
    return f"tube edges in the mean image ({d})"

def shaken_rel_sd(scale: Scale, shake_rms_across_px: float) -> float:
    """The scale's relative uncertainty once a camera's shake across the tube is known.

    A bore read from its contents' width (``method == "contents"``) is widened by the camera's swing across
    the tube over the sampled frames: about ``2 sqrt(2)`` times its rms for a sine (as
    :func:`grainplug.checks.given_scale_doubts` allows), up to twice that for a random shake over a few hundred
    frames. That swing over the bore is added (one standard deviation) in quadrature. The walls' features
    (stripes, silhouette) are found on the mean image, whose symmetric blur by a shake does not move them, and a
    scale given or calibrated is not read from the tube: unchanged.

    Parameters
    ----------
    scale : Scale
        The scale decided.
    shake_rms_across_px : float
        The camera's rms motion across the tube (0 when it did not shake).
    """
    bore = scale.bore
    from_contents = bore is not None and bore.method == "contents" and scale.source.startswith("tube inner width")
    if not (from_contents and shake_rms_across_px > 0 and bore.diameter_px > 0):
        return scale.rel_sd
    return math.hypot(scale.rel_sd, 2.0 * math.sqrt(2.0) * shake_rms_across_px / bore.diameter_px)


def shaken_scale(scale: Scale, tube: TubeGeometry, facts: TubeFacts, shake_rms_across_px: float) -> Scale:
    """``scale`` once a camera's shake across the tube is known: its uncertainty widened
    (:func:`shaken_rel_sd`) and, when it was, the tube's doubts said again with it (a warning that gives the
    scale's uncertainty gives the one the intervals carry)."""
    rel_sd = shaken_rel_sd(scale, shake_rms_across_px)
    if rel_sd == scale.rel_sd or scale.bore is None:
        return scale
    bore = dataclasses.replace(scale.bore, rel_sd=rel_sd)
    return dataclasses.replace(scale, rel_sd=rel_sd, bore=bore, warnings=tuple(tube_scale_doubts(tube, bore, facts)))


#: a bore narrower than this (px) is too few pixels for a scale within a few per cent
NARROW_TUBE_PX = 15.0

#: a bore wider than this share of the frame across the tube leaves no wall to see
WIDE_TUBE_SHARE = 0.8

def tube_scale_doubts(tube: TubeGeometry, bore: BoreEstimate, facts: TubeFacts) -> list[str]:
    """Why a scale from the tube may be off, with the fix (issue 16, item 4).

    Silent only when two independent estimates of the bore (the outer silhouette and the
    refraction stripes) agree within 3 %.
    """
    fix = "take a calibration image (grainplug calibrate) or give mm_per_px="
    across = tube.canonical_shape[1]
    out = all_coded("scale.tube_model", bore.warnings)
    est = bore.estimates_px
    if tube.back_lit is None:
        why = ("the tube is cut by the frame's edge" if tube.side_variation > CUT_SIDE_SHARE else
               "its contents were not seen to change")
        out.append(coded("scale.edges_only",
            f"the scale comes from the tube's edges in the mean image ({bore.diameter_px:.1f} px): {why}, so "
            "neither the bore nor the walls' optics could be measured and the scale may be off by any amount "
            "(by +67 % on a sweep of an independent renderer, where a front-lit 60 px tube in MJPEG was misfound), "
            "which "
            f"the intervals do not carry — {fix}"))
    elif bore.method == "contents" and tube.back_lit:
        out.append(coded("scale.contents_back_lit",
            f"the scale comes from the width over which the tube's contents are seen ({bore.diameter_px:.1f} "
            "px) and the walls showed neither refraction stripes nor an outer silhouette to correct it: a "
            f"back-lit glass tube looks up to {100 * BACK_LIT_NARROWING:.0f} % narrower than its bore (by the "
            "lamp's angular size; 24 % with a 15 deg lamp on a sweep of an independent renderer), which inflates "
            f"every length and celerity by as much: their intervals carry it (±{196 * bore.rel_sd:.2g} % at 95 %) "
            f"— {fix}"))
    elif bore.method == "contents":
        out.append(coded("scale.contents_unchecked",
            f"the scale comes from the tube's inner width seen through its contents ({bore.diameter_px:.1f} px)"
            f", not cross-checked: ±{196 * bore.rel_sd:.2g} % at 95 % (on a sweep of an independent renderer in "
            "front light it read up to 9 % wide at 15 px, 3 % from 20 px) — give tube_outer_diameter_mm= to "
            f"check it against the tube's outer silhouette, or {fix}"))
    elif not math.isfinite(bore.agreement):
        out.append(coded("scale.model_alone",
            f"the scale comes from the tube model alone ({bore.method}: bore {bore.diameter_px:.1f} px, "
            f"±{196 * bore.rel_sd:.2g} % at 95 %, glass index {facts.glass_index:g} assumed), not cross-checked "
            "— give tube_outer_diameter_mm= (the tube's outer diameter: its silhouette then gives the bore by "
            "itself, a second estimate to check this one against), or " + fix))
    elif bore.agreement > AGREEMENT:
        parts = ", ".join(f"{m} {v:.1f} px" for m, v in est.items() if m != "contents")
        out.append(coded("scale.model_disagrees",
            f"the tube model's estimates of the bore disagree by {100 * bore.agreement:.0f} % ({parts}): "
            "check tube_diameter_mm=, tube_outer_diameter_mm= and glass_index= — or " + fix))
    if bore.diameter_px < NARROW_TUBE_PX:
        out.append(coded("scale.tube_narrow",
            f"the tube is only {bore.diameter_px:.1f} px wide: a scale from its width is uncertain by "
            f"{100 * bore.rel_sd:.2g} % (one standard deviation), and every length and celerity with it — "
            f"{fix}"))
    if bore.diameter_px > WIDE_TUBE_SHARE * across:
        out.append(coded("scale.tube_wide",
            f"the tube fills {100 * bore.diameter_px / across:.0f} % of the frame's width: its walls may "
            f"be out of view and the scale from its width wrong — {fix}"))
    return out

#: the calibration's scale may vary by this share along the tube before a warning (lengths near the ends are then off
#: by up to half of it)
ALONG_TUBE_VARIATION_WARN = 0.003


def axis_points_px(tube: TubeGeometry, axis_px: np.ndarray) -> np.ndarray:
    """Frame coordinates ``(x, y)`` (px) of the points on the tube's axis at distances ``axis_px`` along it from the top
    (left) edge of the view, as :func:`grainplug.diagram.extract.band_along_tube` places its samples."""
    s = np.asarray(axis_px, float)
    rows = s * math.cos(math.radians(tube.tilt_deg)) - 0.5
    cols = tube.axis_x(rows)
    pts = np.column_stack([cols, rows])
    return pts[:, ::-1].copy() if tube.orientation == "horizontal" else pts


def axis_mm(cal: Calibration, tube: TubeGeometry, axis_px: np.ndarray) -> np.ndarray:
    """Positions along the tube (mm from the top or left edge of the view) of the points at ``axis_px`` px along its
    axis, through the calibration's lens distortion and perspective (:meth:`Calibration.plane_mm`).

    The analysis takes positions as ``axis_px * mm_per_px``; where the scale varies along the tube by more than
    ``ALONG_TUBE_VARIATION_WARN`` (warned), these are the positions to use instead: lengths and celerities near
    the ends are then right to the calibration's accuracy rather than off by up to half the variation. Valid
    only when the movie's frames are the calibration image's frame (same size, no region of interest).

    Parameters
    ----------
    cal : Calibration
        A calibration of an image of the movie's frame size.
    tube : TubeGeometry
        The tube found in the frames.
    axis_px : ndarray
        Increasing distances along the axis (px), e.g. the second output of
        :func:`grainplug.diagram.extract.band_along_tube`.

    Returns
    -------
    ndarray
        The same positions in mm along the tube (arc length on the pattern's plane from ``axis_px = 0``).
    """
    s = np.concatenate([[0.0], np.asarray(axis_px, float)])
    plane = cal.plane_mm(axis_points_px(tube, s))
    steps = np.hypot(*np.diff(plane, axis=0).T)
    return np.cumsum(steps)


def along_tube(cal: Calibration, tube: TubeGeometry, *, samples: int = 64) -> tuple[float, float]:
    """The calibration's mean scale along the tube's axis over the view, and its relative variation there.

    Returns
    -------
    (mm_per_px, variation)
        The mean of :meth:`Calibration.scale_at` along the axis (so that the length of the tube in view is
        right) and (max - min) / mean of it.
    """
    h = tube.canonical_shape[0]
    cos_t = math.cos(math.radians(tube.tilt_deg))
    s = (np.linspace(0, h - 1, samples) + 0.5) / cos_t
    pts = axis_points_px(tube, s)
    slope = math.tan(math.radians(tube.tilt_deg))
    axis = (slope, 1.0) if tube.orientation == "vertical" else (1.0, slope)
    local = np.asarray(cal.scale_at(pts[:, 0], pts[:, 1], axis), float)
    mean = float(np.mean(local))
    return mean, float((local.max() - local.min()) / mean)


#: ratios of scales that a pattern read at another level of its lines, or in other units, gives
LEVEL_RATIOS = {2.0: "2", 2.5: "2.5", 4.0: "4", 5.0: "5", 10.0: "10", 25.4: "25.4 (mm against inches)",
                2.54: "2.54 (mm against tenths of an inch)"}


#: a calibration is never doubted for disagreeing with the tube by less than this (the tube model's estimates from the
#: walls have been within 2 % on the optical renderer's sweep (benchmarks/intervals.py) but for one at 10 %, 3 % on the
#: synthetic one)
DOUBT_AT_LEAST = 0.05


def optics_allow(bore: BoreEstimate, *, back_lit: bool, cal_rel_sd: float) -> tuple[float, float]:
    """The range of ``scale_from_tube / calibrated_scale - 1`` that the tube's optics and the two estimates'
    uncertainties allow: three standard deviations (at least ``DOUBT_AT_LEAST``) either way, and in back light,
    when the bore comes from the contents' width alone, up to ``BACK_LIT_NARROWING`` narrower."""
    sd = bore.rel_sd if math.isfinite(bore.rel_sd) else 0.1
    narrowed = back_lit and bore.method == "contents"
    if narrowed:  # the lamp's narrowing is in the bore's rel_sd: it is allowed one-sided below, not both ways
        sd = math.sqrt(max(sd * sd - BACK_LIT_CONTENTS_SD**2, 0.0))
    k = max(DOUBT_AT_LEAST, 3 * math.hypot(sd, cal_rel_sd))
    hi = k
    if narrowed:
        hi = 1 / (1 - BACK_LIT_NARROWING) - 1 + k
    return -k, hi


def doubt_sentence(cal: Calibration, bore: BoreEstimate, mm_per_px: float, diameter_mm: float, disagree: float,
                   allowed: tuple[float, float]) -> str:
    """Why a calibration that the tube contradicts is doubted, and which figure to check first."""
    ratio = 1 + disagree
    r = max(ratio, 1 / ratio)
    near = next((words for level, words in LEVEL_RATIOS.items() if abs(r / level - 1) < 0.04), None)
    bore_mm = bore.diameter_px * mm_per_px
    first = (f"check the pattern's pitch first: the scales differ by a factor {r:.2f}, close to {near}, as when a "
             f"pattern is read at another level of its lines (graph paper's 1 mm lines against its 5 mm ones, a "
             f"ruler's mm against its cm) or in other units — the calibration took the {cal.pattern}'s points to be "
             f"{cal.pitch_mm:g} mm apart (pitch_mm= of grainplug calibrate)" if near else
             f"check the calibration's pitch ({cal.pitch_mm:g} mm, {cal.pattern}) and that the image is of this "
             f"camera, lens and distance, then tube_diameter_mm= ({diameter_mm:g} mm)")
    return (f"the calibration and the tube disagree by {100 * disagree:+.0f} % in scale, more than the tube's "
            f"optics allow ({100 * allowed[0]:+.0f} % to {100 * allowed[1]:+.0f} %): at the calibration's "
            f"{mm_per_px:.4g} mm/px the bore ({bore.diameter_px:.1f} px) would be {bore_mm:.2f} mm, not "
            f"{diameter_mm:g} mm — {first}; the calibration's scale is used, with this disagreement in its "
            "intervals")


def calibrated_scale(cal: Calibration, tube: TubeGeometry, frame_shape: tuple[int, int], from_tube: float,
                      diameter_mm: float, bore: BoreEstimate) -> tuple[float, str, float, list[str]]:
    """The calibration's scale along the tube's axis, its uncertainty, and what is doubtful.

    When the movie's frames are the calibration image's size, the scale is taken where the tube is: the mean
    of :meth:`Calibration.scale_at` along its axis over the view (the lens's distortion and perspective make it
    vary over the field); a variation above ``ALONG_TUBE_VARIATION_WARN`` is taken out by mapping the positions
    through the calibration (:func:`uniform_samples`, said in the source) and the uncertainty is the fit's, else
    the uncertainty combines the fit's with the variation (``variation / sqrt(12)``). Otherwise (another size: a
    crop, a region of interest) the scale at the pattern's centre along the tube's axis is taken, with the
    variation over the whole pattern in the uncertainty (the tube may lie anywhere in it).
    """
    slope = math.tan(math.radians(tube.tilt_deg))
    axis = (slope, 1.0) if tube.orientation == "vertical" else (1.0, slope)
    name = cal.image.get("name")
    warnings = all_coded("scale.calibration", cal.warnings)
    same_frame = tuple(cal.image_shape) == tuple(frame_shape)
    if same_frame:
        mm_per_px, variation = along_tube(cal, tube)
        where = "along the tube's axis where the tube is"
        if variation > ALONG_TUBE_VARIATION_WARN:  # positions are mapped through it: the variation is taken out
            rel_sd = cal.rel_sd
            where += (f"; its scale varies by {100 * variation:.2g} % along the tube, so positions are mapped "
                      "through it")
        else:
            rel_sd = math.hypot(cal.rel_sd, variation / math.sqrt(12.0))
    else:
        mm_per_px = cal.mm_per_px_along(axis)
        rel_sd = math.hypot(cal.rel_sd, cal.scale_variation / math.sqrt(12.0))
        where = "along the tube's axis"
    log.info("calibrated scale %.6g mm/px (%s)", mm_per_px, where)
    source = (f"calibration image{' ' + name if name else ''} ({cal.pattern}, {cal.n_points} points "
              f"{cal.pitch_mm:g} mm apart, {where})")
    if not same_frame:
        warnings.append(coded("scale.calibration_size",
            f"the calibration image is {cal.image_shape[1]} x {cal.image_shape[0]} px but the movie's "
            f"frames are {frame_shape[1]} x {frame_shape[0]}: its scale holds only if the camera, lens, "
            "focus and distance did not change (a crop is fine)"))
    disagree = from_tube / mm_per_px - 1
    lo, hi = optics_allow(bore, back_lit=bool(tube.back_lit), cal_rel_sd=rel_sd)
    if not lo <= disagree <= hi:
        warnings.insert(0, coded("scale.calibration_doubted", doubt_sentence(cal, bore, mm_per_px, diameter_mm,
                                                                             disagree, (lo, hi))))
        # one of the two is wrong and which cannot be told from the movie: the intervals carry it
        rel_sd = math.hypot(rel_sd, abs(math.log1p(disagree)) / 2)
    elif abs(disagree) > 0.03:
        if disagree > 0:  # the bore reads narrower than the calibration says
            advice = ("back-lit tubes look narrower than their bore — trust the calibration if the pattern was at "
                      "the tube's plane, else check tube_diameter_mm= (and tube_outer_diameter_mm=)")
        else:  # the bore reads wider: refraction does not do that
            advice = ("the tube reads wider than the calibration implies, which refraction does not do — check "
                      "that the pattern was at the tube's plane (not behind it), its pitch (pitch_mm=), and "
                      "tube_diameter_mm=")
        warnings.append(coded("scale.calibration_vs_tube",
            f"the tube's bore reads {bore.diameter_px:.1f} px ({bore.method}), {diameter_mm:g} mm by the "
            f"calibration being {diameter_mm / mm_per_px:.1f} px ({100 * disagree:+.0f} % in scale): "
            + advice))
    return mm_per_px, source, rel_sd, warnings
