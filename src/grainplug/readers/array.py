"""Frames already in memory: a numpy (or dask, or any array-like) stack as a Movie."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from ..errors import MovieError
from ..params import checked_fps
from .base import Movie, MovieInfo


class ArrayMovie(Movie):
    """A stack of frames ``T x H x W`` (grey) or ``T x H x W x 3`` (RGB) as a movie.

    Parameters
    ----------
    frames : array-like
        A numpy array, a ``numpy.memmap``, a dask array or anything with
        ``shape``, ``dtype`` and slicing (``frames[a:b]``). It is not copied:
        frames are taken from it as the analysis needs them (a dask array is
        computed block by block, so it may be larger than memory).
    fps : float
        Frame rate of the recording.
    name : str
        How the movie is named in the results (``info.path``).

    Examples
    --------
    >>> import numpy as np
    >>> movie = ArrayMovie(np.zeros((10, 64, 32), np.uint8), fps=1000.0)
    >>> movie.info.n_frames, movie.info.fps, movie.info.format
    (10, 1000.0, 'array:uint8')
    """

    #: frames taken from the array at a time when iterating (a dask array computes a block at once)
    BLOCK_FRAMES = 16

    def __init__(self, frames: object, *, fps: float | None = None, name: str = "<array>") -> None:
        shape = getattr(frames, "shape", None)
        dtype = getattr(frames, "dtype", None)
        if shape is None or dtype is None:
            try:
                frames = np.asarray(frames)
            except ValueError:  # a list of frames of several sizes
                sizes = sorted({tuple(np.shape(f)) for f in frames})  # type: ignore[attr-defined]
                raise MovieError(f"the frames are not all the same size ({', '.join(map(str, sizes[:3]))}"
                                 f"{', ...' if len(sizes) > 3 else ''}) — pass frames of one size") from None
            shape, dtype = frames.shape, frames.dtype
        shape = tuple(int(s) for s in shape)
        if len(shape) == 4 and shape[3] in (3, 4):
            channels = 3
        elif len(shape) == 3 and shape[2] in (3, 4) and min(shape[:2]) >= 8:
            raise MovieError(f"an array of shape {shape} is one colour frame, not a movie — pass many frames, "
                             "T x H x W x 3")
        elif len(shape) == 3:
            channels = 1
        else:
            raise MovieError(f"frames of shape {shape} are not a movie — pass an array T x H x W "
                             "(grey) or T x H x W x 3 (RGB)")
        dtype = np.dtype(dtype)
        if dtype.kind == "b" or not (np.issubdtype(dtype, np.integer) or np.issubdtype(dtype, np.floating)):
            raise MovieError(f"frames of dtype {dtype} are not images — pass integer or float pixel values")
        if dtype.kind == "i":  # grey levels in a signed type (Python ints, .astype(int)): as the unsigned they fit
            lo, hi = (int(frames.min()), int(frames.max())) if isinstance(frames, np.ndarray) else (-1, 0)
            if lo < 0:  # a camera's grey levels start at 0: a signed type's negative half would read as "dark"
                raise MovieError(f"frames of dtype {dtype} hold negative values, not a camera's grey levels — pass "
                                 "unsigned integers or floats from 0 (a dask array of a signed type: convert it)")
            dtype = np.dtype(np.uint8 if hi <= 255 else np.uint16 if hi <= 65535 else np.float32)
            frames = frames.astype(dtype)
        fps = checked_fps(fps)
        self._frames = frames
        self._dask = hasattr(frames, "compute") and hasattr(frames, "chunks")
        info = MovieInfo(
            path=name, format=f"array:{dtype.name}", width=shape[2], height=shape[1], n_frames=shape[0],
            fps=float(fps) if fps else None, channels=channels,
            bit_depth=8 * dtype.itemsize,
            dtype=dtype.name, fps_source="user" if fps else "none",
        )
        super().__init__(Path(name), info)

    def _get(self, start: int, stop: int) -> np.ndarray:
        block = self._frames[start:stop]
        if self._dask:
            block = block.compute()
        block = np.asarray(block)
        return block[..., :3] if block.ndim == 4 and block.shape[3] == 4 else block

    def _iter(self, start: int, stop: int, step: int) -> Iterator[np.ndarray]:
        for a in range(start, stop, self.BLOCK_FRAMES * step):
            block = self._get(a, min(stop, a + self.BLOCK_FRAMES * step))
            yield from block[::step]

    def read(self, index: int) -> np.ndarray:
        if not 0 <= index < self.info.n_frames:
            raise IndexError(f"frame {index} out of range 0..{self.info.n_frames - 1}")
        return self._get(index, index + 1)[0]

    def prefetch(self) -> None:
        """Nothing to read ahead: the frames are in memory (or computed on demand)."""

    def _block_reader(self) -> Callable[[int, int], np.ndarray] | None:
        # numpy arrays are sliced without copies by several threads at once; a dask
        # array is computed block by block (its own scheduler may use threads too)
        return lambda start, count: self._get(start, start + count)
