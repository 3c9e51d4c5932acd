"""Multi-page TIFF stacks, read page by page (or memory-mapped when contiguous)."""

from __future__ import annotations

import json
import logging
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import tifffile

from ..errors import MovieError
from .base import TIFF_SIGNATURES, Movie, MovieInfo, choose_fps, map_file, read_file

log = logging.getLogger(__name__)


def _fps_from_metadata(tif: tifffile.TiffFile) -> float | None:
    """Frame rate from grainplug/tifffile JSON, ImageJ or OME metadata, if any."""
    try:
        shaped = tif.shaped_metadata
        if shaped:
            for key in ("fps", "frame_rate"):
                if key in shaped[0]:
                    return float(shaped[0][key])
    except (ValueError, TypeError, json.JSONDecodeError):
        pass
    ij = tif.imagej_metadata or {}
    if ij.get("fps"):
        return float(ij["fps"])
    if ij.get("finterval"):
        return 1.0 / float(ij["finterval"])
    return None


class TiffStackMovie(Movie):
    """A multi-page TIFF (8/16-bit, grey or RGB): one page is one frame.

    Pages are decoded one at a time; an uncompressed contiguous stack is
    memory-mapped so that only the bytes asked for are read.
    """

    def __init__(self, path: Path, *, fps: float | None = None) -> None:
        try:
            self._open(path, fps=fps)
        except MovieError:
            raise
        except Exception as exc:  # tifffile raises many types on a malformed file (RuntimeError: incompatible
            # keyframe, for pages of another layout than the first's)
            tif = getattr(self, "_tif", None)
            if tif is not None:
                tif.close()
            raise MovieError(f"{path}: its pages cannot be read as one movie ({type(exc).__name__}: {exc}) — "
                             "a movie's frames must all have one size, bit depth and layout: export them "
                             "again") from None

    def _open(self, path: Path, *, fps: float | None) -> None:
        try:
            self._tif = tifffile.TiffFile(str(path))
        except (tifffile.TiffFileError, ValueError, OSError) as exc:
            with open(path, "rb") as fh:
                head = fh.read(4)
            if head not in TIFF_SIGNATURES:
                raise MovieError(f"{path} is not a TIFF file (it does not start as one: {head!r}) — check that it "
                                 "is the movie, or give it its real extension") from None
            raise MovieError(f"cannot read {path} as a TIFF stack ({exc}) — is the file complete?") from None
        try:
            series = self._tif.series[0]
            page0 = self._tif.pages.first
            shape = page0.shape
            dtype = np.dtype(page0.dtype)
        except (IndexError, ValueError, tifffile.TiffFileError) as exc:
            self._tif.close()
            raise MovieError(f"{path} holds no readable image ({exc}) — the file is corrupt") from None
        if dtype not in (np.uint8, np.uint16):
            self._tif.close()
            raise MovieError(f"{path}: {dtype} samples are not supported — export 8- or 16-bit frames")
        if len(shape) == 3 and shape[-1] in (3, 4):
            height, width, channels = shape[0], shape[1], 3
        elif len(shape) == 2:
            height, width, channels = shape[0], shape[1], 1
        else:
            self._tif.close()
            raise MovieError(f"{path}: pages of shape {shape} are not frames — export H x W or H x W x 3")
        self._page_shape = shape
        self._contiguous: tuple[int, np.dtype] | None = None
        if len(self._tif.series) > 1:  # pages written one by one: they must agree on size and depth
            for k, other in enumerate(self._tif.series[1:], start=1):
                if tuple(other.shape) != tuple(shape) or np.dtype(other.dtype) != dtype:
                    self._tif.close()
                    raise MovieError(
                        f"{path}: page {k} is {'x'.join(map(str, other.shape))} {np.dtype(other.dtype).name} but "
                        f"page 0 is {'x'.join(map(str, shape))} {dtype.name} — a movie's frames must all have one "
                        "size and bit depth: export them again")
        # frames = the series' samples over one page's (a trailing axis of 1, T x H x W x 1, is no frame axis)
        n_frames = max(1, int(np.prod(series.shape)) // max(1, int(np.prod(shape))))
        if series.dataoffset is not None and not page0.is_tiled and page0.compression == 1:
            dt = series.dtype.newbyteorder(self._tif.byteorder)
            need = series.dataoffset + n_frames * int(np.prod(shape)) * dt.itemsize
            if path.stat().st_size < need:
                self._tif.close()
                raise MovieError(f"{path} is truncated: it holds {path.stat().st_size} of {need} bytes "
                                 "— copy the file again")
            self._contiguous = (int(series.dataoffset), dt)
        else:
            n_frames = len(self._tif.pages)
        file_fps = _fps_from_metadata(self._tif)
        use_fps, source, fps_doubts = choose_fps(fps, file_fps)
        info = MovieInfo(
            path=str(path), format="tiff-stack", width=width, height=height, n_frames=n_frames,
            fps=use_fps, channels=channels, bit_depth=8 * dtype.itemsize, dtype=dtype.name,
            fps_source=source, warnings=tuple(fps_doubts),
        )
        super().__init__(path, info)

    #: frames mapped at once while streaming (the map is released after each chunk)
    CHUNK_FRAMES = 16

    @property
    def _frame_bytes(self) -> int:
        return int(np.prod(self._page_shape)) * self._contiguous[1].itemsize

    def _map(self, start: int, count: int) -> np.ndarray:
        offset, dt = self._contiguous
        return map_file(self.path, offset + start * self._frame_bytes, (count, *self._page_shape), dt,
                        sparse=self._sparse)

    def _read_block(self, start: int, count: int) -> np.ndarray:
        """Frames ``start .. start+count-1`` as a memory map; moves the read-ahead window
        (:meth:`prefetch`) to the block's start, so blocks read in file order keep the
        disk ahead of the stream. Safe from any thread."""
        self._advise_ahead(self._contiguous[0] + start * self._frame_bytes)
        return self._map(start, count)

    def _analysis_frames(self) -> Iterator[np.ndarray]:
        """Frames as views into memory maps of a few frames at a time (uncompressed stacks):
        only the bytes the caller touches are read, and each map is released after use."""
        if self._contiguous is None:
            yield from self.frames()
            return
        n = self.info.n_frames
        for start in range(0, n, self.CHUNK_FRAMES):
            mm = self._read_block(start, min(self.CHUNK_FRAMES, n - start))
            for frame in mm:
                yield frame[..., :3] if mm.ndim == 4 and mm.shape[-1] == 4 else frame
            del mm  # unmapped as soon as the caller drops its last view

    def _frame_offsets(self) -> np.ndarray | None:
        if self._contiguous is None:
            return None
        return self._contiguous[0] + np.arange(self.info.n_frames, dtype=np.int64) * self._frame_bytes

    def _block_reader(self) -> Callable[[int, int], np.ndarray] | None:
        """Blocks of frames as memory maps, for uncompressed contiguous stacks (any thread)."""
        return self._read_block if self._contiguous is not None else None

    def _page(self, index: int, *, random_access: bool = False) -> np.ndarray:
        if self._contiguous is not None:
            arr = read_file(self.path, self._contiguous[0] + index * self._frame_bytes, self._page_shape,
                            self._contiguous[1], random_access=random_access)
        else:
            try:
                arr = self._tif.pages[index].asarray()
            except Exception as exc:  # tifffile raises many types on corrupt pages
                raise MovieError(f"{self.path}: page {index} cannot be decoded ({exc})") from None
        if arr.ndim == 3 and arr.shape[-1] == 4:
            arr = arr[..., :3]
        return np.ascontiguousarray(arr, dtype=arr.dtype.newbyteorder("="))

    def _iter(self, start: int, stop: int, step: int) -> Iterator[np.ndarray]:
        for i in range(start, stop, step):
            yield self._page(i)

    def read(self, index: int) -> np.ndarray:
        if not 0 <= index < self.info.n_frames:
            raise IndexError(f"frame {index} out of range 0..{self.info.n_frames - 1}")
        return self._page(index)

    def _read_sampled(self, index: int) -> np.ndarray:
        return self._page(index, random_access=True)

    def region(self, index: int, rows: slice, cols: slice) -> np.ndarray:
        """Read only a rectangle of one frame (fast on memory-mapped stacks)."""
        if self._contiguous is not None:
            mm = self._map(index, 1)
            out = np.array(mm[0][rows, cols])
            del mm
            return out
        return self._page(index)[rows, cols]

    def _close(self) -> None:
        self._tif.close()
