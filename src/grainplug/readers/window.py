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
from collections.abc import Callable, Iterator

import numpy as np

from .base import Movie, MovieInfo


def first_movie_frame(info: MovieInfo) -> int:
    """The movie's number of ``info``'s first frame: a window's start, else 0 (frames are named by it)."""
    window = (info.details or {}).get("window_frames")
    return int(window[0]) if window else 0


class FrameWindow(Movie):
    """Frames ``[start, stop)`` of ``movie`` (which stays open; closing the window does not close it)."""

    def __init__(self, movie: Movie, start: int, stop: int, *, notes: tuple[str, ...] = ()) -> None:
        from .cine import frames_named

        n = movie.info.n_frames
        if not 0 <= start < stop <= n:
            raise ValueError(f"the window {start}..{stop} is not within the movie's {n} frames")
        self.inner, self.start, self.stop = movie, int(start), int(stop)
        details = {**movie.info.details, "window_frames": [self.start, self.stop],
                   "movie_n_frames": movie.info.n_frames}
        warnings = list(movie.info.warnings)
        bad = [int(k) for k in details.get("frames_with_bad_timestamp") or []]
        if bad and not any(self.start <= k < self.stop for k in bad):  # a bad stamp outside the window: not its own
            warnings = [w for w in warnings if not w.startswith(frames_named(bad))]
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
