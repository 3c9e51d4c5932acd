"""The analysis, top to bottom: movie -> tube -> band -> diagram -> plugs -> tracks -> measures.

:func:`analyze` is the whole pipeline; read it first. Each stage is a function of
arrays and frozen dataclasses from the science packages (:mod:`grainplug.calibration`,
:mod:`grainplug.diagram`, :mod:`grainplug.plugs`, :mod:`grainplug.measures`); the
movie is touched in three places only, all through the
:class:`~grainplug.readers.Movie` protocol: a sample of frames, the band of the
tube for every frame (:meth:`~grainplug.readers.Movie.read_band`), and the frame
times. Nothing here draws, prints or writes a file (see :mod:`grainplug.outputs`).

This module only wires. Where the work is done:

- the window and region of a movie, the frames' times: :mod:`grainplug.readers.window`,
  :mod:`grainplug.readers.roi`, :mod:`grainplug.readers.timing`;
- the scale: :func:`grainplug.calibration.scale.decide_scale`;
- the flow's direction: :mod:`grainplug.measures.flow`;
- plugs, tracks and measures from the diagram: :func:`grainplug.measures.diagram.measure_diagram`;
- what the analysis doubts: :mod:`grainplug.checks`;
- the input's identity: :mod:`grainplug.provenance`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import numbers
import os
import time
from collections.abc import Callable, Iterator, Mapping

import numpy as np

from .calibration import find_tube
from .calibration.background import flat_field
from .calibration.scale import decide_scale, shaken_scale, uniform_samples
from .checks import (
    NO_TUBE,
    check_background,
    check_finite,
    check_movie,
    cut_by_the_frame,
    given_scale_doubts,
    implausible,
    nothing_whole_without_walls,
    other_moving_regions,
    passing_shadow,
    saturated_share,
    train_warnings,
    tube_out_of_view,
    walls_unseen,
)
from .diagram import Diagram, Normalized, normalize
from .diagram.extract import CORE_FRACTION, probes_along_tube, resample_positions
from .diagram.frames import repair_frames
from .diagram.light import divide_by_lamp, moving_light
from .errors import MovieError, ParameterError
from .measures.compactness import grain_contents, reference_reads
from .measures.creep import grain_velocity
from .measures.diagram import DiagramMeasures, confirm_px, measure_diagram
from .measures.flow import falling, orient, resolve_flow
from .measures.shake import band_margin_px, best_along, measure_shake, register_sample, shake_hz, shift_along
from .measures.still import blind_positions, shaken_margin, unmeasured_wander_mm
from .measures.view import tube_view
from .params import AnalysisParams, runs_backwards, tube_orientation
from .plugs import Runs
from .provenance import fingerprint, movie_identity
from .readers import Movie, MovieInfo, as_movie
from .readers.roi import region_of
from .readers.timing import frame_times, timing_stamps
from .readers.window import first_movie_frame, window_of, window_start
from .result import AnalysisResult
from .warning_codes import all_coded

log = logging.getLogger(__name__)

#: the annotated figure's frame is chosen among this many of the sampled frames
KEPT_SAMPLE_FRAMES = 6

#: moved to the modules named in this module's docstring; importable from here for one release
__all__ = ["DiagramMeasures", "analyze", "fingerprint", "measure_diagram", "timing_stamps", "window_start"]


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
    for key, read in (("calibration", _load_calibration), ("background", _read_background),
                      ("packed", _read_background)):
        if isinstance(overrides.get(key), (str, os.PathLike)):  # a file, as the command line takes it
            overrides[key] = read(overrides[key])
    params = (params or AnalysisParams()).replace(**overrides)
    if threads is not None and (isinstance(threads, bool) or not isinstance(threads, numbers.Integral) or threads < 1):
        raise ParameterError(f"give a whole number, at least 1 (or None for one per core), got {threads!r}",
                             param="threads")
    laps = _Laps()
    with _opened(source, params) as movie:
        movie = region_of(window_of(movie, params), params.roi)
        info = _movie_info(movie, params)
        check_movie(info)
        laps("open_s")
        sample_idx, sample = movie.sample(params.sample_frames)
        movie.prefetch()  # the rest of the movie is read while the tube is found
        laps("sample_s")
        wanted = tube_orientation(params.flow_direction) if params.flow_direction else None
        tube = find_tube(sample, orientation=wanted)
        # the camera's motion across the tube, measured on the sampled frames' walls: the tube is found again on
        # the frames moved back (a shaking wall is not a second tube, nor the bore found wider by its swing)
        steady, sample_shake = register_sample(sample, orientation=tube.orientation, tilt_deg=tube.tilt_deg)
        if sample_shake.registered:
            try:
                tube = find_tube(steady, orientation=tube.orientation)
            except MovieError as err:  # what moved was not a camera carrying a tube (a vibrating object): as found
                log.info("the tube was not found again on the registered frames (%s): the first look kept", err)
                steady, sample_shake = sample, dataclasses.replace(sample_shake, registered=False)
        other_tubes = other_moving_regions(steady, tube)
        del steady
        probe_band, axis_px, probes = probes_along_tube(tube)  # the tube's core, and what does not move with it
        # of the profiles along the tube's walls, just beyond them and beside the tube, the one that measures its
        # motion along best is read, if one can (something still on it: a clamp, a label, a ruler; tried on the
        # sampled frames): plain glass, and the others, cost nothing (each costs a fifth of the core's reading)
        best = best_along(probes.near_of(probe_band, sample), probes.near_jumps(probe_band))
        probe_band, axis_px, probes = probes_along_tube(tube, near=tuple(best == k for k in range(len(probes.near))))
        sample_idx, sample = _keep_for_figure(sample_idx, sample)  # free the rest before streaming
        laps("tube_s")
        band = probes.core_band(probe_band)
        saturation = saturated_share(sample, band, info)
        scale = decide_scale(tube, params, mm_per_px=params.mm_per_px, calibration=params.calibration,
                             frame_shape=(info.height, info.width))
        check_background(params, info)
        reads = None if params.packed is None or not tube.back_lit else reference_reads(
            probe_band, probes, params.background.image, params.packed.image,
            packed_compactness=params.packed_compactness)
        laps("setup_s")
        read = movie.read_band(probe_band, threads=threads,
                               progress=(lambda k: progress(k, info.n_frames)) if progress else None)
        values, across, beside, beside_at = probes.split(read)
        check_finite(values, info)
        light_warnings: list[str] = []
        if params.background is not None:
            values, light = flat_field(values, band, params.background)
            light_warnings = all_coded("light.background", light)
        movie_beside = None if reads is None else np.array(beside[:: max(1, len(beside) // 500)])
        values, lamp = divide_by_lamp(values, beside, beside_at, back_lit=tube.back_lit)
        values = np.ascontiguousarray(values)  # its own memory, not a view of the read
        shake = measure_shake(across, probes.along(read), fps=info.fps,
                              band_margin_px=band_margin_px(tube.inner_diameter_px, CORE_FRACTION))
        view = tube_view(across, len(values))  # frames where the tube's walls are not seen: not measured
        del read, across, beside  # the diagram is all that is kept of the read
        if shake.held_along:  # the diagram held still against the tube
            values = shift_along(values, shake.along_px)
        laps("stream_s")
        time_s, time_warnings = frame_times(movie, info, len(values))
        identity = movie_identity(movie)
        laps("fingerprint_s")
    values, repair = repair_frames(values, top=_top_value(info))
    mm_per_px = scale.mm_per_px
    at = None
    shake = dataclasses.replace(shake, mm_per_px=mm_per_px, sample_registered=sample_shake.registered,
                                sample_rms_across_px=sample_shake.rms_px)
    if scale.map_through is not None:  # the lens's distortion: the samples placed evenly in mm along the tube
        at = uniform_samples(scale.map_through, tube, axis_px, mm_per_px)
        values = resample_positions(values, at)
    diagram = Diagram(values, time_s, axis_px * mm_per_px, mm_per_px)
    norm = normalize(diagram.values, background_level=tube.background_level,
                     confirm_px=confirm_px(params.min_plug_mm, mm_per_px))
    laps("normalize_s")
    grains = falling(norm, diagram, info.fps, unseen=np.union1d(repair.bridged, np.flatnonzero(view.unseen)))
    flow = resolve_flow(params.flow_direction, tube, grains)
    diagram, norm, grains = orient(diagram, norm, grains, tube, flow.direction)
    scale = shaken_scale(scale, tube, params, (shake.rms_across_px or 0.0) if shake.shaking else 0.0)
    scale_rel_sd = scale.rel_sd

    def measured(diagram: Diagram, norm: Normalized) -> DiagramMeasures:
        return measure_diagram(diagram, params, fps=info.fps, background_level=tube.background_level,
                               normalized=norm, scale_rel_sd=scale_rel_sd, not_hz=shake_hz(shake),
                               blind_margin_px=shaken_margin(shake), frame_cadence=info.predicts_frames,
                               unseen=view.unseen, wander_mm=unmeasured_wander_mm(shake, mm_per_px))

    found = measured(diagram, norm)
    shadow = None
    if not tube.back_lit and norm.two_phase:  # no lamp beside the tube: a passing shadow read on the contents
        cp = confirm_px(params.min_plug_mm, mm_per_px)
        still = tuple(dataclasses.replace(b, seen_through=None) for b in found.blind)  # seen through or not
        blind = blind_positions(diagram.position_mm, still, margin_samples=shaken_margin(shake) + cp // 2)
        for _ in range(2):  # read again once divided: a deep shadow's plugs are told apart better
            more = moving_light(norm, fps=info.fps, window_px=4 * cp + 1, edge_px=max(2, cp // 2),
                                blind=blind if blind.any() else None)
            if more.log_gain is None:
                break
            shadow = more if shadow is None else shadow.then(more)
            diagram = dataclasses.replace(diagram, values=more.divide(diagram.values))
            norm = normalize(diagram.values, background_level=tube.background_level, confirm_px=cp)
            found = measured(diagram, norm)
    runs, links, motion, lengths = found.runs, found.links, found.motion, found.lengths
    contents = grain_contents(diagram, reads, movie_beside, runs, links, given=params.packed is not None,
                              back_lit=tube.back_lit,
                              backwards=runs_backwards(flow.direction), resample_at=at)
    # plugs: two materials, runs of grains, and edges followed over frames (a droplet's few frames of a blob are not)
    has_plugs = bool(norm.two_phase and len(runs) > 0 and motion is not None)
    if has_plugs and nothing_whole_without_walls(tube, 0 if lengths is None else lengths.n_plugs_measured):
        has_plugs, motion, lengths = False, None, None  # no wall, no plug whole: not a tube (NO_TUBE)
    spacing_mm = float(np.median(np.diff(diagram.position_mm))) if len(diagram.position_mm) > 1 else mm_per_px
    creep = grain_velocity(diagram.values, diagram.time_s, spacing_mm, diagram.position_mm,
                           runs.frame, runs.start, runs.stop) if has_plugs else None
    laps("measures_s")
    no_walls = walls_unseen(tube, has_plugs=has_plugs)
    best = _most_edges(runs, sample_idx)
    timings = dict(laps.timings, stream_fps=round(diagram.n_frames / max(laps.timings["stream_s"], 1e-9), 1))
    return AnalysisResult(
        params=params, input=identity, info=info, tube=tube, mm_per_px=mm_per_px, scale_source=scale.source,
        flow_direction=flow.direction, flow_direction_source=flow.source, diagram=diagram, normalized=found.normalized,
        runs=runs, links=links, motion=motion, lengths=lengths, has_plugs=has_plugs,
        # runs of "grains" seen but never followed, and no wall: a droplet, a jet, not a tube
        statement=NO_TUBE if len(runs) and not has_plugs and no_walls else found.statement,
        sample_frame=sample[best], sample_frame_index=int(sample_idx[best]), timings=timings,
        falling_grain_speed_m_s=None if grains is None else grains.speed_m_s,
        warnings=[*info.warnings, *no_walls, *cut_by_the_frame(tube, params),
                  *scale.warnings,
                  *given_scale_doubts(tube, params, has_plugs=has_plugs, two_phase=norm.two_phase),
                  *light_warnings,
                  *all_coded("frames.repaired", filter(None, [repair.describe(diagram.n_frames,
                                                                              first=first_movie_frame(info))])),
                  *time_warnings,
                  *tube_out_of_view(tuple(view.stretches), diagram.time_s, first=first_movie_frame(info)),
                  *flow.warnings, *other_tubes,
                  *train_warnings(runs, links, diagram.time_s, motion, mm_per_px=mm_per_px, params=params,
                                  info=info, blind=found.blind, shake=shake, flow_source=flow.source,
                                  falling_m_s=None if grains is None else grains.speed_m_s),
                  *implausible(None, None, saturation), *passing_shadow(shadow), *contents.warnings,
                  *(creep.warnings if creep is not None else ())], scale_rel_sd=scale_rel_sd, bore=scale.bore,
        blind=found.blind, shake=shake, lamp=lamp, tube_unseen=tuple(view.stretches),
        compactness=contents.phases, compactness_field=contents.field, compactness_note=contents.note,
        grain_velocity=creep,
    )


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

def _movie_info(movie: Movie, params: AnalysisParams) -> MovieInfo:
    """The movie's description, with the frame rate the user gave (the movie itself is not changed)."""
    if params.fps and movie.info.fps != params.fps:
        return dataclasses.replace(movie.info, fps=float(params.fps), fps_source="user")
    return movie.info

def _top_value(info: MovieInfo) -> float | None:
    """The sensor's top value in the movie's samples (None when unknown)."""
    bits = info.bit_depth or (8 if info.dtype == "uint8" else 16 if info.dtype == "uint16" else 0)
    return float(2**bits - 1) if bits else None

def _load_calibration(path: str | os.PathLike) -> object:
    from .calibration_files import load_calibration

    return load_calibration(path)

def _read_background(path: str | os.PathLike) -> object:
    from .calibration_files import read_background

    return read_background(path)

def _most_edges(runs: Runs, frames: np.ndarray) -> int:
    """Which of ``frames`` shows the most plugs (for the annotated figure)."""
    if not len(runs):
        return 0
    return int(np.argmax([np.count_nonzero(runs.frame == int(k)) for k in frames]))
