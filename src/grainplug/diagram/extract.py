"""Stream a movie into its spatiotemporal diagram.

Each frame is reduced to one profile along the tube axis: the mean grey level
over the core of the bore (the central 70% of the inner diameter, away from the
walls), sampled at every pixel row along the axis. Only the few pixels of that
band are gathered from each frame, so memory does not depend on the movie's
length and the per-frame work is small.
"""

from __future__ import annotations

import copy
import logging
import threading
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ..calibration.tube import TubeGeometry

log = logging.getLogger(__name__)

CORE_FRACTION = 0.7


@dataclass(frozen=True)
class Diagram:
    """Spatiotemporal diagram: grey level along the tube (columns) against time (rows).

    Attributes
    ----------
    values : ndarray, shape (n_frames, n_positions)
        Mean grey level of the bore's core, float32.
    time_s : ndarray, shape (n_frames,)
        Time of each frame from the first one.
    position_mm : ndarray, shape (n_positions,)
        Position along the tube from the upstream end of the view, increasing with the flow.
    mm_per_px : float
        Scale used to turn axis samples into mm.
    """

    values: np.ndarray
    time_s: np.ndarray
    position_mm: np.ndarray
    mm_per_px: float

    @property
    def n_frames(self) -> int:
        return self.values.shape[0]


def display_stride(shape: tuple[int, int], max_side: int = 1200) -> tuple[int, int]:
    """Strides (time, position) that bring a diagram to at most ``max_side`` samples a side.

    A figure ~1000 px wide shows no more; matplotlib resamples the image to RGBA
    floats, which for a long record would cost more memory than the analysis.
    """
    return -(-shape[0] // max_side), -(-shape[1] // max_side)


class BandSampler:
    """Gathers the core band of the bore along the axis from a frame.

    Parameters
    ----------
    tube : TubeGeometry
        The tube found by :func:`grainplug.calibration.find_tube`.
    reverse : bool
        The flow runs towards decreasing canonical rows (upwards, or leftwards).
    core_fraction : float
        Part of the inner diameter that is averaged across the tube.
    """

    def __init__(self, tube: TubeGeometry, *, reverse: bool = False,
                 core_fraction: float = CORE_FRACTION) -> None:
        self.tube = tube
        h, w = tube.canonical_shape
        half = max(1.0, 0.5 * core_fraction * tube.inner_diameter_px)
        offsets = np.arange(-np.floor(half), np.floor(half) + 1)
        rows = np.arange(h)
        centre = tube.axis_x(rows)
        cols = np.rint(centre[:, None] + offsets[None, :]).astype(np.int64)
        valid = (cols >= 0) & (cols < w)
        keep = valid.mean(axis=1) >= 0.5  # rows where the band is mostly in the frame
        self.rows = rows[keep]
        cols = np.clip(cols[keep], 0, w - 1)
        self.weights = valid[keep].astype(np.float32)
        self.weights /= self.weights.sum(axis=1, keepdims=True)
        if tube.orientation == "horizontal":
            self._r, self._c = cols, np.repeat(self.rows[:, None], cols.shape[1], axis=1)
        else:
            self._r, self._c = np.repeat(self.rows[:, None], cols.shape[1], axis=1), cols
        self.reverse = reverse
        if reverse:
            self._r, self._c, self.weights = self._r[::-1], self._c[::-1], self.weights[::-1]
            self.rows = self.rows[::-1]
        # distance along the axis from the upstream edge of the view, in px
        cos_t = np.cos(np.radians(tube.tilt_deg))
        edge = (h - 1 - self.rows) if reverse else self.rows
        self.axis_px = (edge + 0.5) / cos_t
        self._key: tuple | None = None

    def _prepare(self, frame: np.ndarray) -> None:
        """Flat element offsets of the band in an array laid out like ``frame``.

        Axes stored backwards (negative strides: the bottom-up rows of an AVI's
        DIB) are read through a reversed view, whose first element is the lowest
        address; the offsets count from there, so no frame is copied.
        """
        item = frame.itemsize
        self._lowest = tuple(slice(None, None, -1) if s < 0 else slice(None) for s in frame.strides)
        st = [abs(s) // item for s in frame.strides]
        n_ch = frame.shape[2] if frame.ndim == 3 else 1
        r = frame.shape[0] - 1 - self._r if frame.strides[0] < 0 else self._r
        c = frame.shape[1] - 1 - self._c if frame.strides[1] < 0 else self._c
        off = r * st[0] + c * st[1]
        if n_ch > 1:
            ch = np.arange(n_ch)
            off = off[:, :, None] + (ch[::-1] if frame.strides[2] < 0 else ch) * st[2]
        self._idx = np.ascontiguousarray(off.reshape(len(self.rows), -1), dtype=np.intp)
        self._span = int(self._idx.max()) + 1
        w = self.weights if n_ch == 1 else np.repeat(self.weights, n_ch, axis=1) / n_ch
        self._w = np.ascontiguousarray(w, dtype=np.float32)
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
        """Bytes ``[lo, hi)`` of a frame laid out like ``frame`` that :meth:`__call__`
        reads, counted from the frame's lowest address."""
        frame = self._adopt(frame)
        return int(self._idx.min()) * frame.itemsize, self._span * frame.itemsize

    def __call__(self, frame: np.ndarray) -> np.ndarray:
        """Core profile along the axis of one frame (float32).

        Only the band's samples are read: their offsets are computed once from the
        frame's layout (strides), so a view into a memory-mapped file or a padded
        video plane is sampled without copying the frame. Channels are averaged
        with equal weights, so their order does not matter.
        """
        frame = self._adopt(frame)
        if frame.strides[0] < 0 or frame.strides[1] < 0 or (frame.ndim == 3 and frame.strides[2] < 0):
            frame = frame[self._lowest]
        flat = np.lib.stride_tricks.as_strided(frame, shape=(self._span,), strides=(frame.itemsize,))
        vals = np.take(flat, self._idx)
        return np.einsum("ij,ij->i", vals.astype(np.float32), self._w)


def build_diagram(frames: Iterable[np.ndarray], sampler: BandSampler, *, n_frames: int,
                  time_s: np.ndarray, mm_per_px: float,
                  progress: Callable[[int], None] | None = None) -> Diagram:
    """Reduce every frame to its axial profile and stack them.

    Parameters
    ----------
    frames : iterable of ndarray
        The movie's frames, in order (streamed).
    sampler : BandSampler
        Where to read each frame.
    n_frames : int
        Number of frames expected (sizes the output).
    time_s : ndarray
        Time of each frame.
    mm_per_px : float
        Scale.
    progress : callable, optional
        Called with the number of frames done, now and then.
    """
    out = np.empty((n_frames, len(sampler.axis_px)), np.float32)
    k = 0
    for k, frame in enumerate(frames):
        if k >= n_frames:
            break
        out[k] = sampler(frame)
        if progress is not None and (k & 15) == 15:
            progress(k + 1)
    done = k + 1 if n_frames else 0
    if progress is not None:
        progress(done)
    if done < n_frames:
        out = out[:done]
    return Diagram(out, np.asarray(time_s[:done], float), sampler.axis_px * mm_per_px, mm_per_px)


def build_diagram_blocks(read_block: Callable[[int, int], np.ndarray], sampler: BandSampler, *,
                         n_frames: int, time_s: np.ndarray, mm_per_px: float, block_frames: int = 16,
                         threads: int = 2, progress: Callable[[int], None] | None = None) -> Diagram:
    """:func:`build_diagram` from blocks of frames read by several threads at once.

    Parameters
    ----------
    read_block : callable
        ``read_block(start, count)`` returns frames ``start .. start+count-1`` (for
        example :meth:`grainplug.readers.base.Movie.block_reader`); called from
        worker threads, in file order.
    sampler : BandSampler
        Where to read each frame (each thread works with its own copy).
    n_frames, time_s, mm_per_px, progress
        As for :func:`build_diagram`.
    block_frames : int
        Frames per block.
    threads : int
        Worker threads.

    Notes
    -----
    Sampling a memory-mapped frame is mostly page faults and a gather, during which
    numpy releases the GIL, so threads scale with the cores. Blocks are handed out
    in file order, so every thread reads near the same front of the file.
    """
    out = np.empty((n_frames, len(sampler.axis_px)), np.float32)
    local = threading.local()

    def work(start: int) -> int:
        smp = getattr(local, "sampler", None)
        if smp is None:
            smp = local.sampler = copy.copy(sampler)
        count = min(block_frames, n_frames - start)
        block = read_block(start, count)
        for k in range(count):
            out[start + k] = smp(block[k])
        del block
        return count

    done = 0
    with ThreadPoolExecutor(max_workers=max(1, threads), thread_name_prefix="grainplug-stream") as pool:
        for count in pool.map(work, range(0, n_frames, block_frames)):
            done += count
            if progress is not None:
                progress(done)
    return Diagram(out, np.asarray(time_s[:n_frames], float), sampler.axis_px * mm_per_px, mm_per_px)
