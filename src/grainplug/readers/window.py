"""A time window of a movie: frames ``start`` to ``stop`` of another movie, as a movie.

The analysis's ``--start/--end`` (:attr:`grainplug.AnalysisParams.start`) wraps the
opened movie in a :class:`FrameWindow`: every streaming call is served by the movie
itself with frame numbers shifted, so each reader's fast path (memory-mapped blocks,
restricted read-ahead) still applies. Frame times stay those of the movie (a window
that starts at 2 s has its first frame at 2 s).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Callable, Iterator
from typing import Protocol

import numpy as np

from ..errors import ParameterError
from ..warning_codes import code_of, coded
from .base import Movie, MovieInfo


def first_movie_frame(info: MovieInfo) -> int:
    """The movie's number of ``info``'s first frame: a window's start, else 0 (frames are named by it)."""
    window = (info.details or {}).get("window_frames")
    return int(window[0]) if window else 0


class FrameWindow(Movie):
    """Frames ``[start, stop)`` of ``movie`` (which stays open; closing the window does not close it)."""

    def __init__(self, movie: Movie, start: int, stop: int, *, notes: tuple[str, ...] = ()) -> None:
        n = movie.info.n_frames
        if not 0 <= start < stop <= n:
            raise ValueError(f"the window {start}..{stop} is not within the movie's {n} frames")
        self.inner, self.start, self.stop = movie, int(start), int(stop)
        details = {**movie.info.details, "window_frames": [self.start, self.stop],
                   "movie_n_frames": movie.info.n_frames}
        warnings = list(movie.info.warnings)
        bad = [int(k) for k in details.get("frames_with_bad_timestamp") or []]
        if bad and not any(self.start <= k < self.stop for k in bad):  # a bad stamp outside the window: not its own
            warnings = [w for w in warnings if code_of(w) != "movie.frames_out_of_step"]
        info = dataclasses.replace(movie.info, n_frames=self.stop - self.start, details=details,
                                   warnings=(*warnings, *notes))
        super().__init__(movie.path, info)

    @property
    def first_frame_index(self) -> int:
        return self.start + self.inner.first_frame_index

    def _iter(self, start: int, stop: int, step: int) -> Iterator[np.ndarray]:
        return self.inner.frames(start + self.start, stop + self.start, step)

    def prefetch(self) -> None:
        self.inner.prefetch()

    def _block_reader(self) -> Callable[[int, int], np.ndarray] | None:
        read = self.inner._block_reader()
        if read is None:
            return None
        offset = self.start
        return lambda start, count: read(start + offset, count)

    def _frame_offsets(self) -> np.ndarray | None:
        offsets = self.inner._frame_offsets()
        return None if offsets is None else offsets[self.start:self.stop]

    def _prefetch_only(self, lo: int, hi: int) -> bool:
        return self.inner._prefetch_only(lo, hi)

    @property
    def _sparse(self) -> bool:
        return self.inner._sparse

    def _analysis_frames(self) -> Iterator[np.ndarray]:
        # frames before the window are decoded and dropped (compressed video has no cheaper way)
        return itertools.islice(self.inner._analysis_frames(), self.start, self.stop)

    def _analysis_levels(self) -> tuple[float, float] | None:
        return self.inner._analysis_levels()

    def _read_sampled(self, index: int) -> np.ndarray:
        return self.inner._read_sampled(index + self.start)

    def timestamps_s(self) -> np.ndarray:
        stamps = self.inner.file_timestamps_upto(self.stop)
        if stamps is not None:
            return np.asarray(stamps, float)[self.start:self.stop]
        return (np.arange(self.start, self.stop) + self.inner.first_frame_index) / self.info.fps

    @property
    def has_file_timestamps(self) -> bool:
        return self.inner.file_timestamps_upto(self.stop) is not None

    def _stop_prefetch(self) -> None:  # the movie's own read-ahead is the movie's to stop
        pass

class WindowRequest(Protocol):
    """A window of a movie as asked for (an :class:`~grainplug.params.AnalysisParams` is one): frames or seconds,
    either end or none; ``fps`` the frame rate given (None: the movie's)."""

    start_frame: int | None
    end_frame: int | None
    start_s: float | None
    end_s: float | None
    fps: float | None


def window_start(movie: Movie, params: WindowRequest) -> int:
    """The movie frame that is frame 0 of an analysis made with ``params`` (its ``--start``; 0 without one)."""
    if params.start_frame is not None:
        return int(params.start_frame)
    if params.start_s is not None:
        return math.ceil(params.start_s * (params.fps or movie.info.fps) - 1e-6)
    return 0


def window_of(movie: Movie, params: WindowRequest) -> Movie:
    """The frames to analyse: the movie, or the window ``params`` asks for (:class:`FrameWindow`); a window too
    short to analyse, or in seconds without a frame rate, is refused naming the parameter."""
    if all(v is None for v in (params.start_frame, params.end_frame, params.start_s, params.end_s)):
        return movie
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
        notes = (coded("window.end_past_movie", f"the window's end, frame {stop}, is past the movie's {n} frames: it "
                       "was analysed to the movie's end — check the end and its unit (frames or seconds)"),)
    elif params.end_s is not None and stop > n + 1:
        notes = (coded("window.end_past_movie", f"the window's end, {params.end_s:g} s, is past the movie's "
                       f"{n / fps:.4g} s: it was analysed to the movie's end — check the end and its unit (frames or "
                       "seconds)"),)
    stop = min(stop, n)
    if stop - start < 8:
        raise ParameterError(f"the window holds {max(stop - start, 0)} of the movie's {n} frames (frames {start} to "
                             f"{stop}); at least 8 are needed — move its start or its end",
                             param="start_frame" if params.end_frame is None and params.end_s is None else "end_frame")
    return movie if (start, stop) == (0, n) and not notes else FrameWindow(movie, start, stop, notes=notes)
