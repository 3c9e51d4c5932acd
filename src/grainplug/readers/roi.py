"""A region of interest of a movie: the same frames, cropped to a rectangle, as a movie.

``analyze --roi X0,Y0,X1,Y1`` (:attr:`grainplug.AnalysisParams.roi`) wraps the opened
movie in a :class:`RegionOfInterest`: the tube is looked for inside the rectangle only
(the way to choose one tube when a frame holds several, or to leave out a bright
fixture), and the band along the tube is read from the full movie with its pixel
coordinates shifted, so each reader's fast path still applies. Positions along the tube
then start at the rectangle's edge.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator

import numpy as np

from ..band import Band
from ..errors import ParameterError
from .base import Movie


class RegionOfInterest(Movie):
    """Columns ``[x0, x1)`` and rows ``[y0, y1)`` of every frame of ``movie`` (which stays open)."""

    def __init__(self, movie: Movie, roi: tuple[int, int, int, int]) -> None:
        x0, y0, x1, y1 = (int(v) for v in roi)
        h, w = movie.info.frame_shape[:2]
        if not (0 <= x0 < x1 <= w and 0 <= y0 < y1 <= h):
            raise ValueError(f"the region {x0},{y0},{x1},{y1} is not inside the {w} x {h} frames")
        self.inner, self.roi = movie, (x0, y0, x1, y1)
        shape = (y1 - y0, x1 - x0, *movie.info.frame_shape[2:])
        details = {**movie.info.details, "roi_px": [x0, y0, x1, y1], "movie_frame_shape": list(movie.info.frame_shape)}
        info = dataclasses.replace(movie.info, width=x1 - x0, height=y1 - y0, details=details)
        if info.frame_shape[:2] != shape[:2]:
            raise ValueError("the region changes the frame's layout")
        super().__init__(movie.path, info)

    def _crop(self, frame: np.ndarray) -> np.ndarray:
        x0, y0, x1, y1 = self.roi
        return np.asarray(frame)[y0:y1, x0:x1]

    @property
    def first_frame_index(self) -> int:
        return self.inner.first_frame_index

    def _iter(self, start: int, stop: int, step: int) -> Iterator[np.ndarray]:
        return (self._crop(f) for f in self.inner.frames(start, stop, step))

    def _read_sampled(self, index: int) -> np.ndarray:
        return self._crop(self.inner._read_sampled(index))

    def prefetch(self) -> None:
        self.inner.prefetch()

    def read_band(self, band: Band, *, threads: int | None = None,
                  progress: Callable[[int], None] | None = None) -> np.ndarray:
        x0, y0, _, _ = self.roi
        full = Band(band.rows + y0, band.cols + x0, band.weights, tuple(self.inner.info.frame_shape[:2]))
        return self.inner.read_band(full, threads=threads, progress=progress)

    def timestamps_s(self) -> np.ndarray:
        return self.inner.timestamps_s()

    @property
    def has_file_timestamps(self) -> bool:
        return self.inner.has_file_timestamps

    def file_timestamps_upto(self, stop: int) -> np.ndarray | None:
        return self.inner.file_timestamps_upto(stop)

    def _stop_prefetch(self) -> None:  # the movie's own read-ahead is the movie's to stop
        pass


def region_of(movie: Movie, roi: tuple[int, int, int, int] | None) -> Movie:
    """The region of interest ``roi`` of the movie (:class:`RegionOfInterest`), or the movie without one; a region
    outside the frame is refused naming ``roi=``."""
    if roi is None:
        return movie
    try:
        return RegionOfInterest(movie, roi)
    except ValueError as exc:
        raise ParameterError(f"{exc} — give x0,y0,x1,y1 inside the frame", param="roi") from None
