"""The main job: movie -> tube -> spatiotemporal diagram -> plugs -> measures.

:func:`analyze` runs the whole pipeline on one movie, streaming its frames
once (plus a small sample spread over the movie to find the tube first), and
returns an :class:`AnalysisResult`. Nothing here draws or prints; see
:mod:`grainplug.outputs` for the files and figures.
"""

from __future__ import annotations

import dataclasses
import hashlib
import logging
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

try:
    from numpy.lib.array_utils import byte_bounds
except ImportError:  # numpy < 2
    from numpy import byte_bounds

from ._system import ReadAhead
from ._version import __version__
from .calibration import TubeGeometry, find_tube
from .diagram import BandSampler, Diagram, Normalized, build_diagram, build_diagram_blocks, normalize
from .errors import ParameterError
from .measures import Lengths, Motion, measure_lengths, measure_motion
from .measures.grains import falling_grains
from .plugs import Runs, Tracks, find_runs, link, plug_mask
from .readers import Movie, MovieInfo, open_movie

log = logging.getLogger(__name__)

FLOW_DIRECTIONS = ("down", "up", "left", "right")
_OPPOSITE = {"down": "up", "up": "down", "left": "right", "right": "left"}
#: assumed standard uncertainty of the tube's measured inner width, in px
TUBE_WIDTH_SD_PX = 0.25


@dataclass(frozen=True)
class AnalysisParams:
    """Every tunable of :func:`analyze` (all optional).

    Attributes
    ----------
    fps : float, optional
        Frame rate overriding the file's (required for image folders).
    mm_per_px : float, optional
        Scale; without it the scale comes from the tube's inner width.
    tube_diameter_mm : float
        Inner diameter of the tube (3 mm in the paper).
    flow_direction : {"down", "up", "left", "right"}, optional
        Direction of the grain flow in the image. By default it is read from
        the grains falling through the bubbles; when none are seen, down for a
        vertical tube and right for a horizontal one (the summary says which).
    min_plug_mm : float
        Shortest grain region counted as a plug (the paper's 3 mm).
    min_gap_mm : float
        Shortest gap between grains counted as a bubble.
    sample_frames : int
        Frames sampled over the movie to find the tube.
    glob : str, optional
        For image folders: only files matching this pattern.
    """

    fps: float | None = None
    mm_per_px: float | None = None
    tube_diameter_mm: float = 3.0
    flow_direction: str | None = None
    min_plug_mm: float = 3.0
    min_gap_mm: float = 0.6
    sample_frames: int = 32
    glob: str | None = None

    def __post_init__(self) -> None:
        if self.fps is not None and not self.fps > 0:
            raise ParameterError(f"--fps must be positive, got {self.fps}")
        if self.mm_per_px is not None and not self.mm_per_px > 0:
            raise ParameterError(f"--mm-per-px must be positive, got {self.mm_per_px}")
        if not self.tube_diameter_mm > 0:
            raise ParameterError(f"--tube-diameter-mm must be positive, got {self.tube_diameter_mm}")
        if self.flow_direction is not None and self.flow_direction not in FLOW_DIRECTIONS:
            raise ParameterError(f"--flow-direction must be one of {', '.join(FLOW_DIRECTIONS)}")
        if not self.min_plug_mm > 0 or self.min_gap_mm < 0:
            raise ParameterError("min_plug_mm must be positive and min_gap_mm non-negative")
        if self.sample_frames < 4:
            raise ParameterError("sample_frames must be at least 4")


@dataclass(frozen=True)
class AnalysisResult:
    """Everything the analysis found, ready to be written or plotted."""

    params: AnalysisParams
    input: dict[str, object]
    info: MovieInfo
    tube: TubeGeometry
    mm_per_px: float
    scale_source: str
    flow_direction: str
    flow_direction_source: str
    diagram: Diagram
    normalized: Normalized
    runs: Runs
    tracks: Tracks
    motion: Motion | None
    lengths: Lengths | None
    has_plugs: bool
    statement: str
    sample_frame: np.ndarray = field(repr=False)
    sample_frame_index: int = 0
    timings: dict[str, float] = field(default_factory=dict)
    falling_grain_speed_m_s: float | None = None
    warnings: list[str] = field(default_factory=list)

    @property
    def summary(self) -> dict[str, object]:
        """The figures of ``summary.json``."""
        return build_summary(self)


def fingerprint(path: str | Path) -> dict[str, object]:
    """Identity of an input: path, size, modification time and a SHA-256 of its ends.

    The hash covers the first and last MiB of a file (of every file, for a
    folder, with their names), which identifies a movie without reading gigabytes.
    """
    p = Path(path)
    h = hashlib.sha256()
    files = sorted(q for q in p.iterdir() if q.is_file()) if p.is_dir() else [p]
    size = 0
    mtime = 0.0
    for f in files:
        st = f.stat()
        size += st.st_size
        mtime = max(mtime, st.st_mtime)
        h.update(f.name.encode())
        with open(f, "rb") as fh:
            h.update(fh.read(1 << 20))
            if st.st_size > 2 << 20:
                fh.seek(-(1 << 20), os.SEEK_END)
                h.update(fh.read(1 << 20))
    return {"path": str(p.resolve()), "bytes": size, "files": len(files), "mtime": mtime,
            "sha256_ends": h.hexdigest()}


def _flow_angle_deg(tube: TubeGeometry, reverse: bool) -> float:
    """Direction of the flow in the image, degrees from +x towards +y (y down)."""
    a = np.radians(tube.tilt_deg)
    ex, ey = np.sin(a), np.cos(a)
    if reverse:
        ex, ey = -ex, -ey
    if tube.orientation == "horizontal":
        ex, ey = ey, ex
    return float(np.degrees(np.arctan2(ey, ex)))


def _early_restriction(movie: Movie, read_block: Callable[[int, int], np.ndarray] | None
                       ) -> Callable[[str, int, int], None] | None:
    """What to do when the tube search's first stage knows where the tube lies: ask the
    read-ahead for those bytes of every frame only (a horizontal tube across wide frames),
    so that the file is not read whole meanwhile (:meth:`Movie.prefetch_only`); the band
    the analysis reads lies within, and narrows it once the tube is measured."""
    if read_block is None:
        return None

    def restrict(orientation: str, lo: int, hi: int) -> None:
        frame = read_block(0, 1)[0]
        part = frame[lo:hi] if orientation == "horizontal" else frame[:, lo:hi]
        if part.size:
            base = byte_bounds(frame)[0]
            a, b = byte_bounds(part)
            movie.prefetch_only(a - base, b - base)

    return restrict


def analyze(path: str | Path, params: AnalysisParams | None = None, *,
            progress: Callable[[int, int], None] | None = None, threads: int | None = None) -> AnalysisResult:
    """Analyse one movie of plug flow.

    Parameters
    ----------
    path : str or Path
        Any movie :func:`grainplug.open_movie` reads.
    params : AnalysisParams, optional
        Tunables; the defaults need no hand tuning.
    progress : callable, optional
        ``progress(done, total)`` called while frames are streamed.
    threads : int, optional
        Threads that read the frames, where the reader allows it (uncompressed TIFF
        stacks and raw video, memory-mapped); default: one per core. Results do not
        depend on it.

    Returns
    -------
    AnalysisResult
    """
    params = params or AnalysisParams()
    clock = [time.perf_counter()]
    timings: dict[str, float] = {}

    def lap(name: str) -> None:
        now = time.perf_counter()
        timings[name] = round(now - clock[0], 4)
        clock[0] = now

    early = ReadAhead.for_path(path) if Path(path).is_file() else None
    if early is not None:  # the file's headers and the sampled frames get the disk first
        early.pause()
    with open_movie(path, glob=params.glob, fps=params.fps) as movie:
        info = movie.info
        if not info.fps:
            raise ParameterError(
                f"{path}: the frame rate is unknown (image folders and some TIFFs hold none) — pass --fps"
            )
        if info.n_frames < 8:
            raise ParameterError(f"{path} holds {info.n_frames} frames; at least 8 are needed")
        direction = params.flow_direction
        orientation = None
        if direction:
            orientation = "vertical" if direction in ("down", "up") else "horizontal"
        lap("open_s")
        sample_idx, sample = movie.sample(params.sample_frames)
        movie.prefetch()  # the rest of the file is read while the tube is found
        read_block = movie.block_reader()  # frames straight from the file, where the format allows
        lap("sample_s")
        coarse_band = _early_restriction(movie, read_block)
        tube = find_tube(sample, orientation=orientation, on_coarse=coarse_band)
        lap("tube_s")
        # keep a few of the sampled frames for the annotated figure, not all of them
        keep = np.unique(np.linspace(0, len(sample) - 1, min(len(sample), 6)).round().astype(int))
        sample_idx, sample = np.asarray(sample_idx)[keep], [sample[i] for i in keep]
        if direction:
            dir_source = "user"
        else:
            direction = "down" if tube.orientation == "vertical" else "right"
            dir_source = "assumed (gravity down)" if tube.orientation == "vertical" else "assumed"
        reverse = direction in ("up", "left")
        if params.mm_per_px:
            mm_per_px, scale_source = float(params.mm_per_px), "user"
            scale_rel_sd = 0.0
        else:
            mm_per_px = params.tube_diameter_mm / tube.inner_diameter_px
            scale_source = f"tube inner width ({params.tube_diameter_mm:g} mm = {tube.inner_diameter_px:.3f} px)"
            scale_rel_sd = TUBE_WIDTH_SD_PX / tube.inner_diameter_px
        sampler = BandSampler(tube, reverse=reverse)
        times = np.arange(info.n_frames) / info.fps
        cb = (lambda k: progress(k, info.n_frames)) if progress else None
        lap("setup_s")
        n_threads = max(1, threads if threads is not None else (os.cpu_count() or 1))
        if read_block is not None:
            lo, hi = sampler.byte_span(read_block(0, 1)[0])
            if movie.prefetch_only(lo, hi):  # e.g. a horizontal tube: most of each frame is never read
                stride = np.diff(movie.frame_offsets()[:2])[0]
                log.info("reading %.1f%% of each frame from the disk (the tube's band)", 100.0 * (hi - lo) / stride)
            diagram = build_diagram_blocks(read_block, sampler, n_frames=info.n_frames, time_s=times,
                                           mm_per_px=mm_per_px, threads=n_threads, progress=cb)
        else:
            diagram = build_diagram(movie.analysis_frames(), sampler, n_frames=info.n_frames, time_s=times,
                                    mm_per_px=mm_per_px, progress=cb)
        lap("stream_s")
        if movie.has_file_timestamps and info.fps_source == "file":
            # presentation times from the file (recorded while streaming, for video)
            stamps = movie.timestamps_s()
            if len(stamps) == diagram.n_frames:
                diagram = dataclasses.replace(diagram, time_s=np.asarray(stamps, float))
        background = tube.background_level
        result_input = fingerprint(path)
        lap("fingerprint_s")
    norm = normalize(diagram.values, background_level=background)
    lap("normalize_s")
    ds = float(diagram.position_mm[1] - diagram.position_mm[0])
    grains = falling_grains(norm.z, mm_per_sample=ds, fps=info.fps) if norm.two_phase else None
    warnings: list[str] = []
    if grains is not None and grains.speed_m_s is not None:
        if params.flow_direction is None:
            if grains.speed_m_s < 0:  # the grains fall the other way: the view is the other way round
                direction = _OPPOSITE[direction]
                diagram = dataclasses.replace(diagram, values=diagram.values[:, ::-1])
                norm = dataclasses.replace(norm, z=norm.z[:, ::-1], position_gain=norm.position_gain[::-1])
                grains = dataclasses.replace(grains, speed_m_s=-grains.speed_m_s)
            dir_source = (f"inferred from the grains falling through the bubbles "
                          f"({grains.speed_m_s:.2f} m/s)")
        elif grains.speed_m_s < 0:
            warnings.append(f"the grains falling through the bubbles move against --flow-direction "
                            f"{direction} ({grains.speed_m_s:.2f} m/s): check the flow direction")
            log.warning(warnings[-1])
    mask = plug_mask(norm.z, mm_per_sample=ds, min_plug_mm=params.min_plug_mm,
                     min_gap_mm=params.min_gap_mm)
    if not norm.two_phase:  # one material only: no plug to find
        mask[:] = False
    runs = find_runs(norm.z, mask, diagram.position_mm)
    tracks = link(runs, diagram.n_frames)
    lap("plugs_s")
    motion = lengths = None
    has_plugs = norm.two_phase and len(runs) > 0
    statement = ""
    if has_plugs:
        motion = measure_motion(diagram.time_s, runs.top_mm, tracks.run_track, runs.frame,
                                fps=info.fps, mm_per_px=mm_per_px, scale_rel_sd=scale_rel_sd)
        lengths = measure_lengths(runs, tracks, scale_rel_sd=scale_rel_sd)
        if motion is None:
            statement = "plugs were seen but no plug edge could be followed over time"
    else:
        state = _no_plug_state(norm, background)
        statement = (
            f"no plugs: the tube holds a single phase over the whole record ({state}); "
            "no celerity, length or frequency is measured"
        )
    lap("measures_s")
    timings["stream_fps"] = round(diagram.n_frames / max(timings["stream_s"], 1e-9), 1)
    if dir_source.startswith("assumed") and tube.orientation == "horizontal":
        warnings.append(f"no grains seen falling through the bubbles: the flow is assumed to run {direction}; "
                        "pass --flow-direction if it does not")
    # the annotated frame: the sampled frame showing the most plug edges
    best = 0
    if len(runs):
        counts = [np.count_nonzero(runs.frame == int(k)) for k in sample_idx]
        best = int(np.argmax(counts))
    return AnalysisResult(
        params=params, input=result_input, info=info, tube=tube, mm_per_px=mm_per_px,
        scale_source=scale_source, flow_direction=direction, flow_direction_source=dir_source,
        diagram=diagram, normalized=norm, runs=runs, tracks=tracks, motion=motion,
        lengths=lengths, has_plugs=bool(has_plugs), statement=statement,
        sample_frame=sample[best], sample_frame_index=int(sample_idx[best]), timings=timings,
        falling_grain_speed_m_s=None if grains is None else grains.speed_m_s, warnings=warnings,
    )


def _no_plug_state(norm: Normalized, background: float) -> str:
    level = float(np.median([norm.plug_level, norm.bubble_level]))
    if background <= 0:
        return "compact flow or empty tube"
    ratio = level / background
    if 0.75 <= ratio <= 1.35:
        return "empty tube or dilute flow"
    return "compact flow: grains fill the tube"


def _r(x: float | None, nd: int = 6) -> float | None:
    return None if x is None or not np.isfinite(x) else round(float(x), nd)


def build_summary(res: AnalysisResult) -> dict[str, object]:
    """JSON-ready summary with provenance (see ``summary.json`` in the docs)."""
    m, ln, tube = res.motion, res.lengths, res.tube
    D = res.params.tube_diameter_mm
    plug_len = ln.plug_length_mm if ln else None
    s: dict[str, object] = {
        "grainplug_version": __version__,
        "input": res.input,
        "movie": res.info.as_dict(),
        "parameters": asdict(res.params),
        "has_plugs": res.has_plugs,
        "statement": res.statement or None,
        "celerity_m_s": _r(m.celerity_m_s) if m else None,
        "celerity_ci95_m_s": [_r(x) for x in m.celerity_ci95_m_s] if m else None,
        "plug_length_mm": _r(plug_len, 4),
        "plug_length_ci95_mm": [_r(x, 4) for x in ln.plug_length_ci95_mm] if ln and ln.plug_length_ci95_mm else None,
        "plug_length_sd_mm": _r(ln.plug_length_sd_mm, 4) if ln else None,
        "plug_length_over_diameter": _r(plug_len / D, 4) if plug_len else None,
        "bubble_length_mm": _r(ln.bubble_length_mm, 4) if ln else None,
        "bubble_length_ci95_mm": (
            [_r(x, 4) for x in ln.bubble_length_ci95_mm] if ln and ln.bubble_length_ci95_mm else None
        ),
        "oscillation_frequency_hz": _r(m.oscillation_frequency_hz, 4) if m and m.oscillation_frequency_hz else None,
        "oscillation_amplitude_mm": _r(m.oscillation_amplitude_mm, 4) if m else None,
        "oscillation_explained_fraction": _r(m.explained_fraction, 4) if m else None,
        "regime": m.regime if m else "none",
        "n_plugs": int(ln.n_plugs_measured) if ln else 0,
        "n_tracks": len(res.tracks),
        "n_bubbles": int(ln.n_bubbles_measured) if ln else 0,
        "n_edges_used": m.n_edges if m else 0,
        "n_frames": int(res.diagram.n_frames),
        "fps": res.info.fps,
        "duration_s": _r(res.diagram.n_frames / res.info.fps, 6),
        "mm_per_px": _r(res.mm_per_px, 6),
        "scale_source": res.scale_source,
        "tube_diameter_mm": D,
        "tube_diameter_px": _r(tube.inner_diameter_px, 4),
        "tube_axis_angle_deg": _r(_flow_angle_deg(tube, res.flow_direction in ("up", "left")), 4),
        "tube_tilt_deg": _r(tube.tilt_deg, 4),
        "tube_orientation": tube.orientation,
        "tube_detection": tube.method,
        "flow_direction": res.flow_direction,
        "flow_direction_source": res.flow_direction_source,
        "falling_grain_speed_m_s": _r(res.falling_grain_speed_m_s, 4),
        "warnings": list(res.warnings),
        "view_length_mm": _r(float(res.diagram.position_mm[-1] + 0.5 * res.mm_per_px), 4),
        "illumination": {
            "plugs_darker_than_bubbles": res.normalized.plugs_darker,
            "plug_bubble_separation_eta": _r(res.normalized.separation_eta, 4),
            "flicker_sd": _r(float(np.std(res.normalized.frame_gain)), 5),
            "gradient_along_view": _r(float(res.normalized.position_gain[-1] / res.normalized.position_gain[0] - 1), 4),
        },
        "timings_s": dict(res.timings),
        "conventions": "positions in mm along the tube from the upstream end of the view, increasing "
                       "with the flow; celerity in m/s, positive downstream (negative: plugs climb)",
    }
    return s
