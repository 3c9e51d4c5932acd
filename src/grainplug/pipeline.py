"""The analysis, top to bottom: movie -> tube -> band -> diagram -> plugs -> tracks -> measures.

:func:`analyze` is the whole pipeline; read it first. Each stage is a function of
arrays and frozen dataclasses from the science packages (:mod:`grainplug.calibration`,
:mod:`grainplug.diagram`, :mod:`grainplug.plugs`, :mod:`grainplug.measures`); the
movie is touched in three places only, all through the
:class:`~grainplug.readers.Movie` protocol: a sample of frames, the band of the
tube for every frame (:meth:`~grainplug.readers.Movie.read_band`), and the frame
times. Nothing here draws, prints or writes a file (see :mod:`grainplug.outputs`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import logging
import math
import numbers
import os
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from .band import Band
from .calibration import TubeGeometry, find_tube
from .calibration.background import flat_field
from .calibration.pattern import Calibration
from .calibration.tube_model import AGREEMENT, BoreEstimate, WallMeasure, bore_from_model
from .diagram import Diagram, Normalized, band_along_tube, normalize
from .diagram.frames import repair_frames
from .diagram.normalize import CONFIRMED_ETA, LOW_SEPARATION_ETA, MIN_CLASS_FRACTION, MIN_SEPARATION_ETA
from .errors import ParameterError, non_finite_frames
from .measures import Lengths, Motion, measure_lengths, measure_motion
from .measures.grains import GrainMotion, falling_grains
from .measures.motion import NO_FOLLOWED_EDGE
from .params import AnalysisParams, opposite, runs_backwards, tube_orientation
from .plugs import Runs, Tracks, find_runs, link, plug_mask
from .readers import Movie, MovieInfo, as_movie
from .readers.window import first_movie_frame
from .result import AnalysisResult

log = logging.getLogger(__name__)

#: assumed standard uncertainty of the tube's measured inner width, in px
TUBE_WIDTH_SD_PX = 0.25
#: the annotated figure's frame is chosen among this many of the sampled frames
KEPT_SAMPLE_FRAMES = 6


def analyze(source: object, params: AnalysisParams | None = None, *,
            progress: Callable[[int, int], None] | None = None, threads: int | None = None,
            **overrides: object) -> AnalysisResult:
    """Analyse one movie of plug flow.

    Parameters
    ----------
    source : path, Movie or array
        A movie file or image folder (anything :func:`grainplug.open_movie` reads),
        a movie already open (it is left open), or frames in memory: a numpy or
        dask array ``T x H x W`` or ``T x H x W x 3`` (pass ``fps=``).
    params : AnalysisParams, optional
        Tunables; the defaults need no hand tuning.
    progress : callable, optional
        ``progress(done, total)`` called while frames are streamed.
    threads : int, optional
        Threads that read uncompressed frames (memory-mapped); default one per
        core. Results do not depend on it.
    **overrides
        Fields of :class:`AnalysisParams` to set, e.g. ``fps=1000, mm_per_px=0.1875``.

    Returns
    -------
    AnalysisResult

    Examples
    --------
    >>> import grainplug as gp
    >>> res = gp.analyze(gp.datasets.sample_movie())              # doctest: +SKIP
    >>> res = gp.analyze(frames, fps=1000, mm_per_px=0.1875)      # doctest: +SKIP
    """
    if isinstance(params, Mapping):  # the fields as a dict: as good as keywords
        overrides = {**params, **overrides}
        params = None
    elif params is not None and not isinstance(params, AnalysisParams):
        raise ParameterError(f"must be an AnalysisParams (or its fields as keywords), got a {type(params).__name__}",
                             param="params")
    for key, read in (("calibration", _load_calibration), ("background", _read_background)):
        if isinstance(overrides.get(key), (str, os.PathLike)):  # a file, as the command line takes it
            overrides[key] = read(overrides[key])
    params = (params or AnalysisParams()).replace(**overrides)
    if threads is not None and (isinstance(threads, bool) or not isinstance(threads, numbers.Integral) or threads < 1):
        raise ParameterError(f"give a whole number, at least 1 (or None for one per core), got {threads!r}",
                             param="threads")
    laps = _Laps()
    with _opened(source, params) as movie:
        movie = _roi(_window(movie, params), params)
        info = _movie_info(movie, params)
        _check_movie(info)
        laps("open_s")
        sample_idx, sample = movie.sample(params.sample_frames)
        movie.prefetch()  # the rest of the movie is read while the tube is found
        laps("sample_s")
        wanted = tube_orientation(params.flow_direction) if params.flow_direction else None
        tube = find_tube(sample, orientation=wanted)
        other_tubes = _other_moving_regions(sample, tube)
        sample_idx, sample = _keep_for_figure(sample_idx, sample)  # free the rest before streaming
        laps("tube_s")
        band, axis_px = band_along_tube(tube)
        saturation = _saturated_share(sample, band, info)
        mm_per_px, scale_source, scale_rel_sd, scale_warnings, bore = _scale(tube, params, info)
        _check_background(params, info)
        laps("setup_s")
        values = movie.read_band(band, threads=threads,
                                 progress=(lambda k: progress(k, info.n_frames)) if progress else None)
        _check_finite(values, info)
        light_warnings: list[str] = []
        if params.background is not None:
            values, light_warnings = flat_field(values, band, params.background)
        laps("stream_s")
        time_s, time_warnings = _frame_times(movie, info, len(values))
        identity = _identity(movie)
        laps("fingerprint_s")
    values, repair = repair_frames(values, top=_top_value(info))
    diagram = Diagram(values, time_s, axis_px * mm_per_px, mm_per_px)
    norm = normalize(diagram.values, background_level=tube.background_level,
                     confirm_px=_confirm_px(params.min_plug_mm, mm_per_px))
    laps("normalize_s")
    grains = _falling(norm, diagram, info.fps)
    flow = _resolve_flow(params.flow_direction, tube, grains)
    diagram, norm, grains = _orient(diagram, norm, grains, tube, flow.direction)
    runs, links = _plugs(norm, diagram, params)
    laps("plugs_s")
    motion, lengths, statement = _measures(norm, diagram, runs, links, tube.background_level, fps=info.fps,
                                           mm_per_px=mm_per_px, scale_rel_sd=scale_rel_sd, params=params)
    laps("measures_s")
    best = _most_edges(runs, sample_idx)
    timings = dict(laps.timings, stream_fps=round(diagram.n_frames / max(laps.timings["stream_s"], 1e-9), 1))
    has_plugs = bool(norm.two_phase and len(runs) > 0)
    return AnalysisResult(
        params=params, input=identity, info=info, tube=tube, mm_per_px=mm_per_px, scale_source=scale_source,
        flow_direction=flow.direction, flow_direction_source=flow.source, diagram=diagram, normalized=norm,
        runs=runs, links=links, motion=motion, lengths=lengths, has_plugs=has_plugs,
        statement=statement,
        sample_frame=sample[best], sample_frame_index=int(sample_idx[best]), timings=timings,
        falling_grain_speed_m_s=None if grains is None else grains.speed_m_s,
        warnings=[*info.warnings, *_cut_by_the_frame(tube, params), *scale_warnings,
                  *_given_scale_doubts(tube, params, has_plugs=has_plugs, two_phase=norm.two_phase), *light_warnings,
                  *filter(None, [repair.describe(diagram.n_frames, first=first_movie_frame(info))]), *time_warnings,
                  *flow.warnings, *_guessed_sign(flow, motion), *other_tubes,
                  *_still_regions(diagram, motion, lengths),
                  *_still_objects(runs, links, diagram.time_s, motion, mm_per_px),
                  *_near_the_threshold(runs, motion, params),
                  *_implausible(motion, grains, saturation)], scale_rel_sd=scale_rel_sd, bore=bore,
    )


# -- the stages ----------------------------------------------------------------------
#: speeds no plug or falling grain reaches in a gravity-driven pipe flow (m/s): free fall from
#: rest over 2 m gives 6.3 m/s; the paper's plugs move at 0.04-0.1 m/s, its grains fall at 0.8 m/s
IMPLAUSIBLE_SPEED_M_S = 10.0
#: share of the tube's pixels at the sensor's top value above which a warning is given
SATURATION_WARN = 0.01
class _Laps:
    """Seconds spent in each stage, in the order they ran."""

    def __init__(self) -> None:
        self.timings: dict[str, float] = {}
        self._t = time.perf_counter()

    def __call__(self, name: str) -> None:
        now = time.perf_counter()
        self.timings[name] = round(now - self._t, 4)
        self._t = now


@contextlib.contextmanager
def _opened(source: object, params: AnalysisParams) -> Iterator[Movie]:
    """The source as a movie; closed at the end if opened here (a Movie passed in is left open)."""
    if isinstance(source, Movie):
        yield source
        return
    with as_movie(source, fps=params.fps, glob=params.glob, allow_truncated=params.allow_truncated) as movie:
        yield movie


def _keep_for_figure(indices: np.ndarray, frames: list[np.ndarray]) -> tuple[np.ndarray, list[np.ndarray]]:
    """A few of the sampled frames, spread over the movie, for the annotated figure (the
    others are let go: 32 full frames of a 1280 x 1024 RGB movie are 126 MB)."""
    keep = np.unique(np.linspace(0, len(frames) - 1, min(len(frames), KEPT_SAMPLE_FRAMES)).round().astype(int))
    return np.asarray(indices)[keep], [frames[k] for k in keep]


def _window(movie: Movie, params: AnalysisParams) -> Movie:
    """The frames to analyse: the movie, or the window ``params`` asks for (:class:`FrameWindow`)."""
    if all(v is None for v in (params.start_frame, params.end_frame, params.start_s, params.end_s)):
        return movie
    from .readers.window import FrameWindow

    n = movie.info.n_frames
    fps = params.fps or movie.info.fps
    if (params.start_s is not None or params.end_s is not None) and not fps:
        raise ParameterError("a window in seconds needs the frame rate — give fps, or the window in frames",
                             param="start_s" if params.start_s is not None else "end_s")
    start = window_start(movie, params)
    stop = params.end_frame if params.end_frame is not None else (
        math.ceil(params.end_s * fps - 1e-6) if params.end_s is not None else n)
    notes = ()
    # an end past the movie is said, not clamped silently (an end in the wrong unit would go unnoticed); in
    # seconds, up to one frame past it is the movie's own duration rounded
    if params.end_frame is not None and stop > n:
        notes = (f"the window's end, frame {stop}, is past the movie's {n} frames: it was analysed to the movie's "
                 "end — check the end and its unit (frames or seconds)",)
    elif params.end_s is not None and stop > n + 1:
        notes = (f"the window's end, {params.end_s:g} s, is past the movie's {n / fps:.4g} s: it was analysed to "
                 "the movie's end — check the end and its unit (frames or seconds)",)
    stop = min(stop, n)
    if stop - start < 8:
        raise ParameterError(f"the window holds {max(stop - start, 0)} of the movie's {n} frames (frames {start} to "
                             f"{stop}); at least 8 are needed — move its start or its end",
                             param="start_frame" if params.end_frame is None and params.end_s is None else "end_frame")
    return movie if (start, stop) == (0, n) and not notes else FrameWindow(movie, start, stop, notes=notes)


#: another region whose frame-to-frame variation reaches this share of the tube's is reported
OTHER_REGION_SHARE = 0.5


def _other_moving_regions(frames: list[np.ndarray], tube: TubeGeometry) -> list[str]:
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
    return [f"the frames change as much around {name} = {int(where.min())}-{int(where.max())} px as in the tube "
            f"analysed (at {name} = {float(axis.mean()):.0f} px): a second tube? Only this one is analysed — "
            "give roi=(x0, y0, x1, y1) to choose"]


def window_start(movie: Movie, params: AnalysisParams) -> int:
    """The movie frame that is frame 0 of an analysis made with ``params`` (its ``--start``; 0 without one)."""
    if params.start_frame is not None:
        return int(params.start_frame)
    if params.start_s is not None:
        return math.ceil(params.start_s * (params.fps or movie.info.fps) - 1e-6)
    return 0


def _roi(movie: Movie, params: AnalysisParams) -> Movie:
    """The region of interest ``params.roi`` of the movie (:class:`RegionOfInterest`), or the movie."""
    if params.roi is None:
        return movie
    from .readers.roi import RegionOfInterest

    try:
        return RegionOfInterest(movie, params.roi)
    except ValueError as exc:
        raise ParameterError(f"{exc} — give x0,y0,x1,y1 inside the frame", param="roi") from None


def _movie_info(movie: Movie, params: AnalysisParams) -> MovieInfo:
    """The movie's description, with the frame rate the user gave (the movie itself is not changed)."""
    if params.fps and movie.info.fps != params.fps:
        return dataclasses.replace(movie.info, fps=float(params.fps), fps_source="user")
    return movie.info


def _check_movie(info: MovieInfo) -> None:
    if not info.fps:
        raise ParameterError(f"{info.path}: the frame rate is unknown (image folders, arrays and some TIFFs "
                             "hold none) — give the camera's frame rate", param="fps")
    if info.n_frames < 8:
        raise ParameterError(f"{info.path} holds {info.n_frames} frame{'' if info.n_frames == 1 else 's'}; at least 8 "
                             "are needed", param="source")


def _scale(tube: TubeGeometry, params: AnalysisParams,
           info: MovieInfo) -> tuple[float, str, float, list[str], BoreEstimate | None]:
    """``(mm_per_px, where it came from, its relative standard uncertainty, warnings, the tube model's bore)``."""
    if params.mm_per_px:
        return float(params.mm_per_px), "user", 0.0, [], None  # checked against the tube once plugs are found
    bore = _bore(tube, params)
    from_tube = params.tube_diameter_mm / bore.diameter_px
    cal = params.calibration
    if cal is None:
        return from_tube, _bore_source(bore, params), bore.rel_sd, _tube_scale_doubts(tube, bore, params), bore
    return (*_calibrated_scale(cal, tube, info, from_tube, params.tube_diameter_mm, bore), bore)


#: the contents' change at a side of the frame the tube reaches, as a share of the most they change, above which the
#: tube is cut by the frame (a whole tube: 0; the sample cut by a region of interest: 0.93)
CUT_SIDE_SHARE = 0.3


def _cut_by_the_frame(tube: TubeGeometry, params: AnalysisParams) -> list[str]:
    """A warning when the tube's moving contents run up to a side of the frame: the tube is cut there."""
    if tube.side_variation <= CUT_SIDE_SHARE:
        return []
    fix = ("widen roi= to hold the whole tube and its walls" if params.roi else
           "frame the whole tube and its walls (or give roi= around a tube that is whole in view)")
    return [f"the tube's contents change at a side of the frame {100 * tube.side_variation:.0f} % as much as "
            "anywhere: the tube is cut by the frame's edge, so the tube found, its width, the scale from it and "
            f"every measure may be wrong — {fix}"]


#: the width over which a tube's contents are seen, against its bore: a back-lit tube looks up to 35 % narrower
#: (by the lamp's size), never much wider
SEEN_OVER_BORE = (0.6, 1.15)
#: grains and air seen but no plug (or nothing moving): the tube is seen where the contents or the mean image's
#: edges show it, inside the bore (0.59-0.99 of it in the synthetic and an independent renderer's cases); narrower
#: than this share, the given scale is the doubt (a scale 10 times too fine makes every plug "shorter than
#: min_plug_mm"). With one material only (sparse falling grains) the tube can be seen over a few pixels: no doubt.
SEEN_OVER_BORE_NO_PLUGS = 0.3


def _load_calibration(path: str | os.PathLike) -> object:
    from .calibration.files import load_calibration

    return load_calibration(path)


def _read_background(path: str | os.PathLike) -> object:
    from .calibration.files import read_background

    return read_background(path)


def _given_scale_doubts(tube: TubeGeometry, params: AnalysisParams, *, has_plugs: bool,
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
    if low <= ratio <= SEEN_OVER_BORE[1]:
        return []
    return [f"the tube's contents are seen over {tube.inner_diameter_px:.1f} px, but the given scale makes its "
            f"{params.tube_diameter_mm:g} mm bore {expected_px:.1f} px ({ratio:.2g} times): check mm_per_px= "
            "and tube_diameter_mm=, and that what was found is the tube"]


def _bore(tube: TubeGeometry, params: AnalysisParams) -> BoreEstimate:
    """The bore's width in pixels from the tube model (the walls' features and what the user knows)."""
    nan = float("nan")
    walls = tube.walls or WallMeasure(nan, nan, (nan, nan), (nan, nan))
    bore = bore_from_model(walls, visible_diameter_px=tube.inner_diameter_px, back_lit=bool(tube.back_lit),
                           inner_diameter_mm=params.tube_diameter_mm,
                           outer_diameter_mm=params.tube_outer_diameter_mm, n_glass=params.glass_index)
    if tube.back_lit is None:  # nothing moved: the edges of the mean image, nothing to model
        bore = BoreEstimate(tube.inner_diameter_px, "edges", {"edges": tube.inner_diameter_px}, rel_sd=0.1)
    log.info("tube model: bore %.2f px by %s; estimates %s", bore.diameter_px, bore.method,
             {k: round(v, 2) for k, v in bore.estimates_px.items()})
    return bore


def _bore_source(bore: BoreEstimate, params: AnalysisParams) -> str:
    """Where a scale from the tube came from, in words."""
    d = f"bore {params.tube_diameter_mm:g} mm = {bore.diameter_px:.2f} px"
    glass = f"glass n = {params.glass_index:g}"
    if bore.method == "outer":
        return (f"tube model: outer silhouette ({params.tube_outer_diameter_mm:g} mm = "
                f"{bore.diameter_px * params.tube_outer_diameter_mm / params.tube_diameter_mm:.2f} px), {d}")
    if bore.method == "stripe + outer":
        return f"tube model: refraction stripes and outer silhouette ({glass}), {d}"
    if bore.method == "stripe":
        shape = (f"outer diameter {params.tube_outer_diameter_mm:g} mm" if params.tube_outer_diameter_mm
                 else "outer/inner diameter assumed 1.83")
        return f"tube model: refraction stripes ({glass}, {shape}), {d}"
    if bore.method == "contents":
        return f"tube inner width seen through its contents ({d})"
    return f"tube edges in the mean image ({d})"


#: a bore narrower than this (px) is too few pixels for a scale within a few per cent
NARROW_TUBE_PX = 15.0
#: a bore wider than this share of the frame across the tube leaves no wall to see
WIDE_TUBE_SHARE = 0.8


def _tube_scale_doubts(tube: TubeGeometry, bore: BoreEstimate, params: AnalysisParams) -> list[str]:
    """Why a scale from the tube may be off, with the fix (issue 16, item 4).

    Silent only when two independent estimates of the bore (the outer silhouette and the
    refraction stripes) agree within 3 %.
    """
    fix = "take a calibration image (grainplug calibrate) or give mm_per_px="
    across = tube.canonical_shape[1]
    out = list(bore.warnings)
    est = bore.estimates_px
    if tube.back_lit is None:
        why = ("the tube is cut by the frame's edge" if tube.side_variation > CUT_SIDE_SHARE else
               "its contents were not seen to change")
        out.append(f"the scale comes from the tube's edges in the mean image ({bore.diameter_px:.1f} px): {why}, so "
                   "neither the bore nor the walls' optics could be measured and the scale may be off by 10 % or "
                   f"more — {fix}")
    elif bore.method == "contents" and tube.back_lit:
        out.append(f"the scale comes from the width over which the tube's contents are seen ({bore.diameter_px:.1f} "
                   "px) and the walls showed neither refraction stripes nor an outer silhouette to correct it: a "
                   "back-lit glass tube looks up to 35 % narrower than its bore (by the lamp's angular size), which "
                   f"inflates every length and celerity by as much — {fix}")
    elif bore.method == "contents":
        out.append(f"the scale comes from the tube's inner width seen through its contents ({bore.diameter_px:.1f} px)"
                   ", not cross-checked (in front light it read within 2-3 % on the renderers tried) — give "
                   f"tube_outer_diameter_mm= to check it against the tube's outer silhouette, or {fix}")
    elif not math.isfinite(bore.agreement):
        out.append(f"the scale comes from the tube model alone ({bore.method}: bore {bore.diameter_px:.1f} px, "
                   f"about ±{100 * bore.rel_sd:.2g} %, glass index {params.glass_index:g} assumed), not cross-checked "
                   "— give tube_outer_diameter_mm= to check it against the outer silhouette, or " + fix)
    elif bore.agreement > AGREEMENT:
        parts = ", ".join(f"{m} {v:.1f} px" for m, v in est.items() if m != "contents")
        out.append(f"the tube model's estimates of the bore disagree by {100 * bore.agreement:.0f} % ({parts}): "
                   "check tube_diameter_mm=, tube_outer_diameter_mm= and glass_index= — or " + fix)
    if bore.diameter_px < NARROW_TUBE_PX:
        out.append(f"the tube is only {bore.diameter_px:.1f} px wide: a scale from its width is uncertain by "
                   f"{100 * bore.rel_sd:.2g} % (one standard deviation), and every length and celerity with it — "
                   f"{fix}")
    if bore.diameter_px > WIDE_TUBE_SHARE * across:
        out.append(f"the tube fills {100 * bore.diameter_px / across:.0f} % of the frame's width: its walls may "
                   f"be out of view and the scale from its width wrong — {fix}")
    return out


def _calibrated_scale(cal: Calibration, tube: TubeGeometry, info: MovieInfo, from_tube: float,
                      diameter_mm: float, bore: BoreEstimate) -> tuple[float, str, float, list[str]]:
    """The calibration's scale along the tube's axis, its uncertainty, and what is doubtful.

    The uncertainty combines the fit's with the scale's variation over the pattern
    (the tube may lie anywhere in it: a uniform spread, ``variation / sqrt(12)``).
    """
    slope = math.tan(math.radians(tube.tilt_deg))
    axis = (slope, 1.0) if tube.orientation == "vertical" else (1.0, slope)
    mm_per_px = cal.mm_per_px_along(axis)
    rel_sd = math.hypot(cal.rel_sd, cal.scale_variation / math.sqrt(12.0))
    name = cal.image.get("name")
    source = (f"calibration image{' ' + name if name else ''} ({cal.pattern}, {cal.n_points} points "
              f"{cal.pitch_mm:g} mm apart, along the tube's axis)")
    warnings = list(cal.warnings)
    if tuple(cal.image_shape) != (info.height, info.width):
        warnings.append(f"the calibration image is {cal.image_shape[1]} x {cal.image_shape[0]} px but the movie's "
                        f"frames are {info.width} x {info.height}: its scale holds only if the camera, lens, focus "
                        "and distance did not change (a crop is fine)")
    disagree = from_tube / mm_per_px - 1
    if abs(disagree) > 0.03:
        if disagree > 0:  # the bore reads narrower than the calibration says
            advice = ("back-lit tubes look narrower than their bore — trust the calibration if the pattern was at "
                      "the tube's plane, else check tube_diameter_mm= (and tube_outer_diameter_mm=)")
        else:  # the bore reads wider: refraction does not do that
            advice = ("the tube reads wider than the calibration implies, which refraction does not do — check "
                      "that the pattern was at the tube's plane (not behind it), its pitch (pitch_mm=), and "
                      "tube_diameter_mm=")
        warnings.append(f"the tube's bore reads {bore.diameter_px:.1f} px ({bore.method}), {diameter_mm:g} mm by the "
                        f"calibration being {diameter_mm / mm_per_px:.1f} px ({100 * disagree:+.0f} % in scale): "
                        + advice)
    return mm_per_px, source, rel_sd, warnings


def _top_value(info: MovieInfo) -> float | None:
    """The sensor's top value in the movie's samples (None when unknown)."""
    bits = info.bit_depth or (8 if info.dtype == "uint8" else 16 if info.dtype == "uint16" else 0)
    return float(2**bits - 1) if bits else None


def _check_background(params: AnalysisParams, info: MovieInfo) -> None:
    bg = params.background
    if bg is not None and tuple(bg.image.shape[:2]) != (info.height, info.width):
        raise ParameterError(f"the background is {bg.image.shape[1]} x {bg.image.shape[0]} px but the movie's frames "
                             f"are {info.width} x {info.height}: take it with the movie's camera and settings",
                             param="background")


def _check_finite(values: np.ndarray, info: MovieInfo) -> None:
    """Float frames with NaN or infinite pixels in the tube (beyond the sampled frames, checked with the tube) are
    refused: their band averages would read as a change of light."""
    if np.dtype(info.dtype).kind != "f":
        return
    bad = np.flatnonzero(~np.isfinite(values).all(axis=1))
    if bad.size:
        shown = ", ".join(str(k) for k in bad[:5]) + (", ..." if bad.size > 5 else "")
        raise non_finite_frames(f"{bad.size} of the {len(values)} frames (frame{'s' if bad.size > 1 else ''} "
                                f"{shown} of the analysis)")


def _saturated_share(frames: list[np.ndarray], band: Band, info: MovieInfo) -> float:
    """Share of the tube's pixels (the band's, in the frames kept from the sample) at the top
    value the camera can give (``2**bit_depth - 1``, any channel)."""
    if not frames or np.dtype(info.dtype).kind == "f":  # float frames have no top value a camera clips at
        return 0.0
    top = (1 << min(info.bit_depth, 8 * np.dtype(info.dtype).itemsize)) - 1
    hits = [np.asarray(f)[band.rows, band.cols] >= top for f in frames]
    return float(np.mean([h.any(axis=-1).mean() if h.ndim == 3 else h.mean() for h in hits]))


def _implausible(motion: Motion | None, grains: GrainMotion | None, saturation: float) -> list[str]:
    """Warnings for numbers that cannot be right, each with what to check."""
    out = []
    if motion is not None and motion.celerity_m_s is not None and abs(motion.celerity_m_s) > IMPLAUSIBLE_SPEED_M_S:
        out.append(f"the plugs move at {motion.celerity_m_s:.3g} m/s, faster than grains can fall in a pipe: check "
                   "the frame rate (fps=) and the scale (calibration= or mm_per_px=)")
    if grains is not None and grains.speed_m_s is not None and abs(grains.speed_m_s) > IMPLAUSIBLE_SPEED_M_S:
        out.append(f"the grains fall through the bubbles at {grains.speed_m_s:.3g} m/s, faster than free fall "
                   "allows: check the frame rate (fps=) and the scale")
    if saturation > SATURATION_WARN:
        out.append(f"{100 * saturation:.1f} % of the tube's pixels are at the camera's top value (saturated): plug "
                   "and bubble contrast is lost there — lower the exposure or the light")
    return out


#: how far (in frame periods) time stamps may stray from a constant rate and still be its rounding
EVEN_TIMES_PERIODS = 0.25
#: ... or in seconds: Matroska stores times in whole milliseconds (16 and 17 ms apart at 60 fps)
EVEN_TIMES_S = 0.0006


def uneven(stamps: np.ndarray) -> bool:
    """Whether a file's frame times stray from a constant rate by more than their rounding (then they time the
    frames; else ``index / fps`` does)."""
    stamps = np.asarray(stamps, float)
    n = len(stamps)
    if n < 3:
        return False
    k = np.arange(n)
    slope, intercept = np.polyfit(k, stamps, 1)
    stray = float(np.max(np.abs(stamps - (intercept + slope * k))))
    period = float(np.median(np.diff(stamps)))
    return stray > max(EVEN_TIMES_PERIODS * period, EVEN_TIMES_S)


def timing_stamps(movie: Movie, info: MovieInfo) -> np.ndarray | None:
    """The file's own frame times (s) where they time the frames: recorded, the rate the file's own, and uneven
    (:func:`uneven`); else None, and ``index / fps`` times them."""
    if not (movie.has_file_timestamps and info.fps_source == "file"):
        return None
    stamps = np.asarray(movie.timestamps_s(), float)  # recorded while streaming, for video
    return stamps if uneven(stamps) else None


def _frame_times(movie: Movie, info: MovieInfo, n: int) -> tuple[np.ndarray, list[str]]:
    """Time of each frame, and a warning when the file's own times are unevenly spaced.

    Where the file records a time for each frame and they keep to a constant rate within their rounding,
    the rate's times (``index / fps``: exact, where whole-millisecond stamps of a 2000 fps movie are not);
    where they stray from it (a variable frame rate, dropped frames), the file's times, with a warning.
    """
    stamps = timing_stamps(movie, info)
    if stamps is None or len(stamps) != n:
        return (np.arange(n) + movie.first_frame_index) / info.fps, []
    dt = np.diff(stamps)
    return stamps, [f"the frames are not evenly spaced in time ({1000 * dt.min():.3g} to {1000 * dt.max():.3g} ms "
                    "apart): the file's own time stamps are used, but a high-speed camera records at a constant "
                    "rate — check how the file was made (re-encoded, frames dropped?), or give fps= to time the "
                    "frames by their number"]


def _falling(norm: Normalized, diagram: Diagram, fps: float) -> GrainMotion | None:
    if not norm.two_phase:
        return None
    ds = float(diagram.position_mm[1] - diagram.position_mm[0])
    return falling_grains(norm.z, mm_per_sample=ds, fps=fps)


@dataclass(frozen=True)
class _Flow:
    direction: str
    source: str
    warnings: tuple[str, ...] = ()


#: positions whose grey level varies over the record less than this share of the tube's typical variation are still
STILL_REGION_SHARE = 0.1


def _still_regions(diagram: Diagram, motion: Motion | None, lengths: Lengths | None) -> list[str]:
    """A warning naming the stretches of the tube (1 mm or more) where nothing changes over the record while the
    rest of it does: an opaque object over the tube (a clamp, a fitting, the tube's end), which cuts or merges the
    plugs crossing it. Judged only where the train travelled a plug and a bubble over the record, so that every
    place should have seen both (in a shorter record a long plug may cover a place throughout)."""
    if (motion is None or motion.regime != "propagative" or lengths is None or lengths.plug_length_mm is None
            or lengths.bubble_length_mm is None):
        return []
    travel_mm = abs(motion.celerity_m_s) * 1000.0 * float(diagram.time_s[-1] - diagram.time_s[0])
    if travel_mm < lengths.plug_length_mm + lengths.bubble_length_mm:
        return []
    values = diagram.values
    d = np.log(np.maximum(np.asarray(values[:: max(1, values.shape[0] // 1000)], np.float32), np.float32(1e-3)))
    sd = d.std(axis=0)
    typical = float(np.median(sd))
    if not typical > 0.01:  # nothing moves anywhere (a jammed or empty record): no contrast to judge by
        return []
    step = np.diff(np.concatenate([[0], (sd < STILL_REGION_SHARE * typical).astype(np.int8), [0]]))
    starts, stops = np.nonzero(step == 1)[0], np.nonzero(step == -1)[0]
    pos, half = diagram.position_mm, 0.5 * diagram.mm_per_px
    spans = [(pos[a] - half, pos[b - 1] + half) for a, b in zip(starts, stops, strict=True)
             if (b - a) * diagram.mm_per_px >= 1.0]
    if not spans:
        return []
    where = ", ".join(f"{lo:.1f}-{hi:.1f} mm" for lo, hi in spans[:4]) + (", ..." if len(spans) > 4 else "")
    return [f"nothing changes at {where} (from the upstream end of the view) over the whole record while the rest "
            "of the tube does: an object over the tube there (a clamp, a fitting, the tube's end)? Plugs crossing it "
            "are cut or merged, and their lengths with them — leave it out of the region analysed (roi=, on one side "
            "of it)"]


#: a track that moves less than this share of what the plug train moves over its life stays put
STILL_SHARE = 0.2
#: ... judged only where the train moves at least this many pixels over the track's life
STILL_MIN_TRAIN_PX = 5.0


def _still_objects(runs: Runs, links: Tracks, time_s: np.ndarray, motion: Motion | None,
                   mm_per_px: float) -> list[str]:
    """A warning for the tracks that stay put while the plug train moves: a still object over the tube (a clamp,
    a label, a fitting, the tube's end) taken for a plug, whose "length" enters the lengths."""
    if motion is None or motion.regime != "propagative" or motion.celerity_m_s is None:
        return []
    speed = abs(motion.celerity_m_s) * 1000.0  # mm/s
    still = []
    for tid in range(len(links)):
        sel = links.run_track == tid
        if np.count_nonzero(sel) < 3:
            continue
        t = time_s[runs.frame[sel]]
        span = float(t.max() - t.min())
        top, bottom = runs.top_mm[sel], runs.bottom_mm[sel]
        edge = top if np.isfinite(top).sum() >= 2 else bottom
        ok = np.isfinite(edge)
        if speed * span < STILL_MIN_TRAIN_PX * mm_per_px or ok.sum() < 2 or np.ptp(t[ok]) <= 0:
            continue
        if abs(float(np.polyfit(t[ok], edge[ok], 1)[0])) <= STILL_SHARE * speed:
            seen = np.concatenate([top[np.isfinite(top)], bottom[np.isfinite(bottom)]])
            still.append(f"plug {tid} at {seen.min():.0f}-{seen.max():.0f} mm for {span:.2g} s")
    if not still:
        return []
    return [f"{'; '.join(still[:5])}{' and more' if len(still) > 5 else ''} (from the upstream end of the view): "
            f"{'it stays' if len(still) == 1 else 'they stay'} put while the plugs move at "
            f"{motion.celerity_m_s:+.3g} m/s — a still object over the tube (a clamp, a label, a fitting, the tube's "
            "end)? Measured as plugs, they bias the lengths: exclude them (grainplug review, or Corrections in "
            "Python) or leave them out with roi="]


#: plugs just over ``min_plug_mm``: this share of the whole plugs seen within :data:`NEAR_THRESHOLD` of it ...
NEAR_SHARE = 0.1
#: ... above it (relative) is a train whose shorter plugs are dropped
NEAR_THRESHOLD = 0.2


def _near_the_threshold(runs: Runs, motion: Motion | None, params: AnalysisParams) -> list[str]:
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
    return [f"{100 * near:.0f} % of the plugs seen are within {100 * NEAR_THRESHOLD:.0f} % of min_plug_mm = "
            f"{params.min_plug_mm:g} mm: shorter plugs are likely there, dropped (the bubbles about them are "
            "measured as one) and plugs at the threshold come and go (their tracks split) — lower min_plug_mm="]


#: how :func:`_resolve_flow` says it took the flow down a vertical tube for want of anything better
GRAVITY_DOWN = "assumed (gravity down)"


def _guessed_sign(flow: _Flow, motion: Motion | None) -> list[str]:
    """A warning when a celerity was measured along a flow direction only assumed (down a vertical tube): its
    sign rests on the camera having been upright."""
    if flow.source != GRAVITY_DOWN or motion is None or motion.celerity_m_s is None:
        return []
    return ["no grains were seen falling through the bubbles, so the flow is assumed to run down the image "
            "(gravity down) and the celerity's sign rests on that: if the camera was not upright, give the flow "
            "direction (flow_direction=)"]


def _resolve_flow(given: str | None, tube: TubeGeometry, grains: GrainMotion | None) -> _Flow:
    """The direction of the flow in the image, decided here and only here.

    The diagram is always streamed top to bottom (left to right); the flow runs the
    way the user said, else the way the grains fall through the bubbles, else down
    a vertical tube (gravity) and, with a warning, right along a horizontal one.
    """
    speed = None if grains is None else grains.speed_m_s  # positive: falling top to bottom / left to right
    forward = "down" if tube.orientation == "vertical" else "right"
    if given:
        warnings = ()
        if speed is not None and (speed < 0) != runs_backwards(given):
            warnings = (f"the grains falling through the bubbles move against the given flow direction ({given}; "
                        f"{abs(speed):.2f} m/s the other way): check the flow direction "
                        "(flow_direction=)",)
            log.warning(warnings[0])
        return _Flow(given, "user", warnings)
    if speed is not None:
        direction = opposite(forward) if speed < 0 else forward
        return _Flow(direction, f"inferred from the grains falling through the bubbles ({abs(speed):.2f} m/s)")
    if tube.orientation == "vertical":
        return _Flow(forward, GRAVITY_DOWN)
    return _Flow(forward, "assumed", (f"no grains seen falling through the bubbles: the flow is assumed to run "
                                      f"{forward}; if it does not, give the flow direction "
                                      "(flow_direction=)",))


def _orient(diagram: Diagram, norm: Normalized, grains: GrainMotion | None, tube: TubeGeometry,
            direction: str) -> tuple[Diagram, Normalized, GrainMotion | None]:
    """Turn the diagram so that positions increase with the flow (a no-op for a flow down or right).

    Notes
    -----
    Streamed top to bottom, position :math:`s_i = (r_i + 1/2) / \\cos\\theta` for canonical
    row :math:`r_i`. Reversed, the distance from the bottom edge of an :math:`h`-row view is
    :math:`(h - 1 - r_i + 1/2)/\\cos\\theta = h/\\cos\\theta - s_i`, read in reverse order.
    """
    if not runs_backwards(direction):
        return diagram, norm, grains
    view_px = tube.canonical_shape[0] / np.cos(np.radians(tube.tilt_deg))
    d = dataclasses.replace(diagram, values=diagram.values[:, ::-1],
                            position_mm=view_px * diagram.mm_per_px - diagram.position_mm[::-1])
    n = dataclasses.replace(norm, z=norm.z[:, ::-1], position_gain=norm.position_gain[::-1])
    g = None if grains is None else dataclasses.replace(
        grains, speed_m_s=None if grains.speed_m_s is None else -grains.speed_m_s)
    return d, n, g


def _plugs(norm: Normalized, diagram: Diagram, params: AnalysisParams) -> tuple[Runs, Tracks]:
    """Plugs in every frame (runs of grains along the tube), linked into tracks over time."""
    ds = float(diagram.position_mm[1] - diagram.position_mm[0])
    mask = plug_mask(norm.z, mm_per_sample=ds, min_plug_mm=params.min_plug_mm, min_gap_mm=params.min_gap_mm)
    if not norm.two_phase:  # one material only: no plug to find
        mask[:] = False
    runs = find_runs(norm.z, mask, diagram.position_mm)
    return runs, link(runs, diagram.n_frames)


def _measures(norm: Normalized, diagram: Diagram, runs: Runs, links: Tracks, background_level: float, *, fps: float,
              mm_per_px: float, scale_rel_sd: float,
              params: AnalysisParams) -> tuple[Motion | None, Lengths | None, str]:
    """Celerity and oscillation of the plug train, plug and bubble lengths; or why there are none."""
    if not norm.two_phase and _weakly_two(norm):
        averaged = ("" if norm.averaged_eta is None else
                    f"; {norm.averaged_eta:.2f} averaged along the tube, {CONFIRMED_ETA:g} needed")
        return None, None, (f"no plugs: the tube seems to hold a single phase ({_single_phase(norm, background_level)})"
                            f", but its grey levels hint at two, too close to tell apart (separation "
                            f"{norm.separation_eta:.2f}, {MIN_SEPARATION_ETA:g} needed{averaged}): if there are plugs, "
                            "raise the contrast between grains and air (lighting, exposure, a less compressed file); "
                            "no celerity, length or frequency is measured")
    if not norm.two_phase:
        return None, None, (f"no plugs: the tube holds a single phase over the whole record "
                            f"({_single_phase(norm, background_level)}); "
                            "no celerity, length or frequency is measured")
    if len(runs) == 0:
        view = float(diagram.position_mm[-1] - diagram.position_mm[0]) if len(diagram.position_mm) > 1 else 0.0
        longer = f", longer than the {view:.0f} mm in view" if params.min_plug_mm >= view else ""
        return None, None, (f"no plugs: grains and air are both seen, but no run of grains is at least "
                            f"{params.min_plug_mm:g} mm long{longer} — lower min_plug_mm= "
                            "(or min_gap_mm=), or check the scale; no celerity, length or frequency is measured")
    # small least-squares problems: a BLAS thread pool would only add wake-up latency
    with threadpool_limits(limits=1, user_api="blas"):
        motion = measure_motion(diagram.time_s, runs.top_mm, links.run_track, runs.frame, fps=fps,
                                mm_per_px=mm_per_px, scale_rel_sd=scale_rel_sd)
        lengths = measure_lengths(runs, links, scale_rel_sd=scale_rel_sd)
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


def measure_diagram(diagram: Diagram, params: AnalysisParams | None = None, *, fps: float,
                    background_level: float = 0.0) -> DiagramMeasures:
    """The analysis from the diagram on: plugs, tracks, celerity, regime, plug and bubble lengths.

    The stages :func:`analyze` runs after streaming the movie, for a diagram from
    elsewhere (a simulation, :mod:`grainplug.simulation.measure`). ``diagram.values``
    are grey levels with grains dark, rows in time, positions increasing downstream.
    """
    params = params or AnalysisParams()
    norm = normalize(diagram.values, background_level=background_level or None,
                     confirm_px=_confirm_px(params.min_plug_mm, diagram.mm_per_px))
    runs, links = _plugs(norm, diagram, params)
    motion, lengths, statement = _measures(norm, diagram, runs, links, background_level, fps=fps,
                                           mm_per_px=diagram.mm_per_px, scale_rel_sd=0.0, params=params)
    return DiagramMeasures(norm, runs, links, motion, lengths, statement)


#: a separation that averaging along the tube lowers by more than this is of short things (falling grains), not plugs
AVERAGED_LOSS = 0.05


def _weakly_two(norm: Normalized) -> bool:
    """Whether the diagram's two grey levels, too close to be called plugs and bubbles, are still more than one
    level with noise (a separation of 2/pi = 0.64), each hold a fair share of it, and do not part less once
    averaged along the tube."""
    return (norm.separation_eta >= LOW_SEPARATION_ETA
            and MIN_CLASS_FRACTION <= norm.plug_fraction <= 1 - MIN_CLASS_FRACTION
            and not (norm.averaged_eta is not None and norm.averaged_eta < norm.separation_eta - AVERAGED_LOSS))


def _confirm_px(min_plug_mm: float, mm_per_px: float) -> int:
    """Positions along the tube over which a weak plug/bubble separation is looked for again: a third of the
    shortest plug (:func:`grainplug.diagram.normalize`)."""
    return max(1, int(round(min_plug_mm / 3 / mm_per_px)))


def _single_phase(norm: Normalized, background: float) -> str:
    level = float(np.median([norm.plug_level, norm.bubble_level]))
    if background <= 0:
        return "compact flow or empty tube"
    if 0.75 <= level / background <= 1.35:
        return "empty tube or dilute flow"
    return "compact flow by its grey level: grains fill the tube"


def _most_edges(runs: Runs, frames: np.ndarray) -> int:
    """Which of ``frames`` shows the most plugs (for the annotated figure)."""
    if not len(runs):
        return 0
    return int(np.argmax([np.count_nonzero(runs.frame == int(k)) for k in frames]))


# -- provenance ------------------------------------------------------------------------
def fingerprint(path: str | Path, *, full: bool = False) -> dict[str, object]:
    """Identity of an input: path, size, modification time and a SHA-256 of sampled content.

    Parameters
    ----------
    path : path
        A movie file, or a folder of image files (every file is covered, with its name).
    full : bool
        Also hash every byte (``sha256``): slow on large movies, exact.

    Notes
    -----
    ``sha256_sampled`` covers the first and last MiB of each file (the header and the
    last frames) and 32 blocks of 64 KiB evenly spaced between them, so that a movie
    changed in place (re-exported, re-recorded under the same name) is told apart
    without reading gigabytes; a change confined to bytes between the blocks is only
    seen with ``full=True`` (``grainplug batch --verify``).
    """
    p = Path(path)
    h = hashlib.sha256()
    whole = hashlib.sha256() if full else None
    files = sorted(q for q in p.iterdir() if q.is_file()) if p.is_dir() else [p]
    size = 0
    mtime = 0.0
    block, ends, n_blocks = 1 << 16, 1 << 20, 32
    for f in files:
        st = f.stat()
        size += st.st_size
        mtime = max(mtime, st.st_mtime)
        h.update(f.name.encode())
        h.update(str(st.st_size).encode())
        with open(f, "rb") as fh:
            h.update(fh.read(ends))
            if st.st_size > 2 * ends:
                span = st.st_size - 2 * ends - block
                for k in range(n_blocks):
                    fh.seek(ends + span * k // (n_blocks - 1))
                    h.update(fh.read(block))
                fh.seek(-ends, os.SEEK_END)
                h.update(fh.read(ends))
            if whole is not None:
                whole.update(f.name.encode())
                fh.seek(0)
                while chunk := fh.read(1 << 22):
                    whole.update(chunk)
    out: dict[str, object] = {"path": str(p.resolve()), "bytes": size, "files": len(files), "mtime": mtime,
                              "sha256_sampled": h.hexdigest()}
    if whole is not None:
        out["sha256"] = whole.hexdigest()
    return out


def _identity(movie: Movie) -> dict[str, object]:
    """Provenance of the input: a file's :func:`fingerprint`, or an array's shape and the hash
    of its first and last frames."""
    if not movie.info.format.startswith("array"):
        return fingerprint(movie.path)
    n = movie.info.n_frames
    h = hashlib.sha256()
    for k in sorted({0, n - 1}):
        h.update(np.ascontiguousarray(movie.read(k)).tobytes())
    return {"path": None, "kind": "array", "shape": [n, *movie.info.frame_shape], "dtype": movie.info.dtype,
            "sha256_first_last_frames": h.hexdigest()}
