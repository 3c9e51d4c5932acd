"""Fast band profiles: the gather every reader uses to serve :meth:`Movie.read_band`.

A frame handed out by a reader may be a view into a memory-mapped file or a
decoder's padded plane, with rows stored bottom-up or channels in BGR order.
:class:`BandGather` computes, once per frame layout (shape, strides, dtype), the
flat element offsets of the band's samples, and then reads only those samples
from each frame: no frame is copied or converted. Two drivers stream a whole
movie through it: :func:`profiles_from_frames` (frames in order, one thread) and
:func:`profiles_from_blocks` (blocks of memory-mapped frames, several threads).
"""

from __future__ import annotations

import copy
import threading
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..band import Band

__all__ = ["BandGather", "profiles_from_blocks", "profiles_from_frames"]


class BandGather:
    """Band profiles of frames in any memory layout (see :meth:`grainplug.band.Band.profile`)."""

    def __init__(self, band: Band) -> None:
        self.band = band
        self._key: tuple | None = None

    def _prepare(self, frame: np.ndarray) -> None:
        """Flat element offsets of the band in an array laid out like ``frame``.

        Axes stored backwards (negative strides) are read through a reversed view,
        whose first element is the lowest address; the offsets count from there.
        """
        b = self.band
        item = frame.itemsize
        self._lowest = tuple(slice(None, None, -1) if s < 0 else slice(None) for s in frame.strides)
        st = [abs(s) // item for s in frame.strides]
        n_ch = frame.shape[2] if frame.ndim == 3 else 1
        r = frame.shape[0] - 1 - b.rows if frame.strides[0] < 0 else b.rows
        c = frame.shape[1] - 1 - b.cols if frame.strides[1] < 0 else b.cols
        off = r.astype(np.int64) * st[0] + c.astype(np.int64) * st[1]
        if n_ch > 1:
            ch = np.arange(n_ch)
            off = off[:, :, None] + (ch[::-1] if frame.strides[2] < 0 else ch) * st[2]
        # gathered sample by sample across the band (every position's first sample, then every second...): one
        # frame's rows are far apart in memory, and a gather that goes down them at one stride lets the processor
        # fetch the next rows ahead (twice as fast, on a memory-mapped frame, as one that reads the band's
        # samples at one position after another); the same sums follow, in the same order
        off = off.reshape(b.n_positions, -1)
        w = b.weights if n_ch == 1 else np.repeat(b.weights, n_ch, axis=1) / n_ch
        # positions with at most half the samples the band is wide (the profiles along the tube's walls, padded
        # with zero weights) are gathered apart, their samples only: the padding would cost more than the samples.
        # The others are gathered together, padding and all: one sweep down the frame per sample is cheaper, on a
        # memory-mapped frame, than a sweep per group
        nonzero = w != 0
        counts = nonzero.sum(axis=1)
        narrow = counts <= max(int(counts.max(initial=0)) // 2, 0)
        self._groups = []
        wide = np.flatnonzero(~narrow)
        if wide.size:
            self._groups.append((slice(None) if wide.size == b.n_positions else wide,
                                 np.ascontiguousarray(off[wide].T, dtype=np.intp),
                                 np.ascontiguousarray(np.asarray(w, np.float32)[wide]), True))
        for c in np.unique(counts[narrow]):
            if c == 0:
                continue
            rows = np.flatnonzero(narrow & (counts == c))
            keep = np.argsort(~nonzero[rows], axis=1, kind="stable")[:, :c]  # its samples, in their order
            # sample by sample too, and summed over the samples with whole rows of positions at a time (an einsum
            # over a few samples a position spends its time in its loop's overhead)
            self._groups.append((rows, np.ascontiguousarray(np.take_along_axis(off[rows], keep, axis=1).T,
                                                            dtype=np.intp),
                                 np.ascontiguousarray(np.take_along_axis(np.asarray(w, np.float32)[rows], keep,
                                                                         axis=1).T), False))
        self._empty = bool((counts == 0).any())
        self._n = b.n_positions
        self._lo = min((int(g[1].min()) for g in self._groups), default=0)  # (offsets of the samples gathered)
        self._span = max((int(g[1].max()) for g in self._groups), default=0) + 1
        self._key = (frame.shape, frame.strides, frame.dtype.str)

    def _adopt(self, frame: np.ndarray) -> np.ndarray:
        """``frame`` without an alpha channel, the offsets prepared for its layout."""
        if frame.ndim == 3 and frame.shape[2] == 4:
            frame = frame[..., :3]
        if self._key != (frame.shape, frame.strides, frame.dtype.str):
            if any(s == 0 for s in frame.strides):  # broadcast axes: no layout to follow
                frame = np.ascontiguousarray(frame)
            self._prepare(frame)
        return frame

    def byte_span(self, frame: np.ndarray) -> tuple[int, int]:
        """Bytes ``[lo, hi)`` of a frame laid out like ``frame`` that the gather touches,
        counted from the frame's lowest address (a reader restricts its read-ahead to them)."""
        frame = self._adopt(frame)
        return self._lo * frame.itemsize, self._span * frame.itemsize

    def __call__(self, frame: np.ndarray) -> np.ndarray:
        """The band's profile of one frame (float32), reading the band's samples only."""
        frame = self._adopt(frame)
        if frame.strides[0] < 0 or frame.strides[1] < 0 or (frame.ndim == 3 and frame.strides[2] < 0):
            frame = frame[self._lowest]
        flat = np.lib.stride_tricks.as_strided(frame, shape=(self._span,), strides=(frame.itemsize,))
        if len(self._groups) == 1 and not self._empty and self._groups[0][3]:
            _, idx, w, _ = self._groups[0]
            return np.einsum("ij,ij->i", np.ascontiguousarray(np.take(flat, idx).T, dtype=np.float32), w)
        out = np.zeros(self._n, np.float32)
        for rows, idx, w, wide in self._groups:
            vals = np.take(flat, idx)
            if wide:
                out[rows] = np.einsum("ij,ij->i", np.ascontiguousarray(vals.T, dtype=np.float32), w)
            else:  # samples x positions, weights alike
                out[rows] = (vals.astype(np.float32) * w).sum(axis=0)
        return out


def profiles_from_frames(frames: Iterable[np.ndarray], band: Band, *, n_frames: int,
                         progress: Callable[[int], None] | None = None) -> np.ndarray:
    """Profiles of frames streamed in order: array ``(n_read, n_positions)``, float32.

    Stops after ``n_frames``; fewer rows when the stream ends early.
    """
    gather = BandGather(band)
    out = np.empty((n_frames, band.n_positions), np.float32)
    done = 0
    for k, frame in enumerate(frames):
        if k >= n_frames:
            break
        out[k] = gather(frame)
        done = k + 1
        if progress is not None and (k & 15) == 15:
            progress(done)
    if progress is not None:
        progress(done)
    return out if done == n_frames else out[:done]


def profiles_from_blocks(read_block: Callable[[int, int], np.ndarray], band: Band, *, n_frames: int,
                         threads: int = 2, block_frames: int = 16,
                         progress: Callable[[int], None] | None = None) -> np.ndarray:
    """Profiles of blocks of frames read by several threads at once.

    Parameters
    ----------
    read_block : callable
        ``read_block(start, count)`` returns frames ``start .. start+count-1``
        (memory maps); called from worker threads, in file order.
    band : Band
        The pixels to average.
    n_frames : int
        Frames to read.
    threads, block_frames : int
        Worker threads and frames per block.
    progress : callable, optional
        Called with the number of frames done.

    Notes
    -----
    Sampling a memory-mapped frame is mostly page faults and a gather, during which
    numpy releases the GIL, so threads scale with the cores. Blocks are handed out
    in file order, so every thread reads near the same front of the file.
    """
    out = np.empty((n_frames, band.n_positions), np.float32)
    local = threading.local()
    first = BandGather(band)

    def work(start: int) -> int:
        gather = getattr(local, "gather", None)
        if gather is None:
            gather = local.gather = copy.copy(first)
        count = min(block_frames, n_frames - start)
        block = read_block(start, count)
        for k in range(count):
            out[start + k] = gather(block[k])
        del block
        return count

    done = 0
    with ThreadPoolExecutor(max_workers=max(1, threads), thread_name_prefix="grainplug-stream") as pool:
        for count in pool.map(work, range(0, n_frames, block_frames)):
            done += count
            if progress is not None:
                progress(done)
    return out
