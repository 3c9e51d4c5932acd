"""Common interface of every movie reader."""

from __future__ import annotations

import abc
import logging
import math
import mmap
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._system import READAHEAD_MEMORY_SHARE, ReadAhead, free_memory_bytes
from ..band import Band
from ..errors import MovieError
from ..warning_codes import coded

log = logging.getLogger(__name__)

#: the first four bytes of a TIFF file (classic and BigTIFF, either byte order)
TIFF_SIGNATURES = (b"II*\0", b"MM\0*", b"II+\0", b"MM\0+")


#: a given frame rate further than this (relative) from the file's own is said to contradict it
FPS_DISAGREEMENT = 0.01


def choose_fps(given: float | None, in_file: float | None) -> tuple[float | None, str, list[str]]:
    """The frame rate to use, where it came from (``"user"``, ``"file"``, ``"none"``), and a warning when a
    given rate contradicts the file's: every time and speed scales with it, so a slip (25 for 250) is said."""
    if not given:
        return in_file, "file" if in_file else "none", []
    if in_file and abs(given / in_file - 1) > FPS_DISAGREEMENT:
        return float(given), "user", [coded(
            "movie.fps_disagrees",
            f"the frame rate given ({given:g} fps) is not the one the file records ({in_file:.6g} fps): the given "
            "one is used, and every time and speed scales with it — right for a video saved at a playback rate, "
            "but check fps=")]
    return float(given), "user", []


#: lossy codecs that predict frames from others (PyAV's names and OpenCV's four-character codes): their groups of
#: pictures hold some frames' contents still and refresh them at others, a cadence of a few frames
PREDICTING_CODECS = frozenset({
    "h264", "hevc", "h265", "mpeg4", "mpeg2video", "mpeg1video", "msmpeg4v2", "msmpeg4v3", "h263", "vp8", "vp9",
    "av1", "theora", "wmv2", "wmv3", "vc1", "avc1", "x264", "hev1", "hvc1", "mp4v", "xvid", "divx", "dx50", "vp80",
    "vp90", "av01", "mpg1", "mpg2"})


@dataclass(frozen=True)
class MovieInfo:
    """What a movie file says about itself.

    Attributes
    ----------
    path : str
        The file or folder that was opened.
    format : str
        Reader name and container/codec, e.g. ``"video:ffv1"`` or ``"tiff-stack"``.
    width, height : int
        Frame size in pixels.
    n_frames : int
        Number of frames.
    fps : float or None
        Frame rate in frames per second, ``None`` when the file does not hold one
        (image folders, TIFF stacks without metadata); pass ``fps=`` to set it.
    channels : int
        1 for grey, 3 for RGB.
    bit_depth : int
        Significant bits per sample as the camera stored them (10, 12, 14 for many
        high-speed cameras), which may be fewer than the array's ``dtype`` holds.
    dtype : str
        numpy dtype of the frames (``"uint8"`` or ``"uint16"``).
    fps_source : str
        Where ``fps`` came from: ``"file"``, ``"user"`` or ``"none"``.
    fps_note : str
        How a file's frame rate was derived, where it is not simply stored (e.g.
        ``"record rate 50000 fps / save step 2500"`` for a Photron recording that saved
        one frame in 2500).
    record_fps : float or None
        The rate the camera recorded at, where the file says and it differs from the
        rate of the saved frames (a camera that saved one frame in ``n``).
    colour : str
        How colour is stored: ``"grey"``, ``"rgb"``, or the raw Bayer pattern that
        was demosaiced (``"bayer RGGB, demosaiced"``).
    camera : str
        Camera model and serial number where the file says.
    warnings : tuple of str
        Anything doubtful about the file (time stamps that disagree with the header, a
        frame with a bad time stamp, a truncated file read in part), each with the fix;
        the analysis repeats them in its results.
    details : dict
        Format facts kept for provenance (trigger time, first frame number, flips,
        black and white levels, time stamp jitter...), JSON-ready.
    """

    path: str
    format: str
    width: int
    height: int
    n_frames: int
    fps: float | None
    channels: int
    bit_depth: int
    dtype: str
    fps_source: str = "file"
    fps_note: str = ""
    record_fps: float | None = None
    colour: str = ""
    camera: str = ""
    warnings: tuple[str, ...] = ()
    details: dict[str, object] = field(default_factory=dict)

    @property
    def predicts_frames(self) -> bool:
        """Whether the file's codec is a lossy one that predicts frames from others (H.264, HEVC, MPEG-4, VP9...):
        what it holds still and refreshes follows its group of pictures, a cadence of a few frames."""
        kind, _, codec = self.format.partition("/")
        return kind.startswith("video") and codec.strip().lower() in PREDICTING_CODECS

    @property
    def duration_s(self) -> float | None:
        """Duration in seconds, ``None`` when the frame rate is unknown."""
        if not self.fps:
            return None
        return self.n_frames / self.fps

    @property
    def frame_shape(self) -> tuple[int, ...]:
        """Shape of one frame array."""
        if self.channels == 1:
            return (self.height, self.width)
        return (self.height, self.width, self.channels)

    @property
    def frame_nbytes(self) -> int:
        """Bytes of one decoded frame."""
        return int(np.prod(self.frame_shape)) * np.dtype(self.dtype).itemsize

    def as_dict(self) -> dict[str, object]:
        """JSON-ready description, with duration."""
        return {
            "path": self.path,
            "format": self.format,
            "width": self.width,
            "height": self.height,
            "n_frames": self.n_frames,
            "fps": self.fps,
            "fps_source": self.fps_source,
            "fps_note": self.fps_note,
            "channels": self.channels,
            "bit_depth": self.bit_depth,
            "dtype": self.dtype,
            "duration_s": self.duration_s,
            "record_fps": self.record_fps,
            "colour": self.colour or ("grey" if self.channels == 1 else "rgb"),
            "camera": self.camera,
            "warnings": list(self.warnings),
            "details": dict(self.details),
        }


def map_file(path: str | Path, offset: int, shape: tuple[int, ...], dtype: np.dtype | str, *,
             sparse: bool = False) -> np.ndarray:
    """Read-only memory map of an array of ``shape`` and ``dtype`` at byte ``offset`` of ``path``.

    ``sparse``: the caller will touch a small part of the map, already asked for
    (:meth:`Movie._prefetch_only`); the kernel is told so (``MADV_RANDOM``), so that
    a page it must still read from the disk comes alone, not with the megabytes
    around it that its read-ahead would otherwise bring in.
    """
    if not sparse or not hasattr(mmap, "MADV_RANDOM"):
        return np.memmap(path, dtype=dtype, mode="r", offset=offset, shape=shape)
    dt = np.dtype(dtype)
    count = math.prod(shape)
    start = offset // mmap.ALLOCATIONGRANULARITY * mmap.ALLOCATIONGRANULARITY
    with open(path, "rb") as fh:
        mm = mmap.mmap(fh.fileno(), offset - start + count * dt.itemsize, offset=start, access=mmap.ACCESS_READ)
    mm.madvise(mmap.MADV_RANDOM)
    return np.frombuffer(mm, dt, count=count, offset=offset - start).reshape(shape)


def read_file(path: str | Path, offset: int, shape: tuple[int, ...], dtype: np.dtype | str, *,
              random_access: bool = False) -> np.ndarray:
    """An array of ``shape`` and ``dtype`` read (copied) from byte ``offset`` of ``path``.

    ``random_access``: one of a few reads here and there in the file (sampling
    frames spread over a movie): the kernel is told to fetch these bytes only,
    without the window its read-ahead would add (``POSIX_FADV_RANDOM`` on this
    read's own descriptor). Otherwise the usual read-ahead serves reads in order.
    """
    arr = np.empty(shape, np.dtype(dtype))
    buf = memoryview(arr.reshape(-1)).cast("B")
    got = 0
    with open(path, "rb", buffering=0) as fh:
        if random_access and hasattr(os, "posix_fadvise"):  # these bytes, not a read-ahead window
            os.posix_fadvise(fh.fileno(), 0, 0, os.POSIX_FADV_RANDOM)
        fh.seek(offset)
        while got < len(buf):
            n = fh.readinto(buf[got:])
            if not n:
                raise MovieError(f"{path}: the file ends before the frame at byte {offset} — it is truncated")
            got += n
    return arr


class Movie(abc.ABC):
    """A movie opened for streaming.

    Frames come out one at a time as numpy arrays (``H x W`` or ``H x W x 3``,
    ``uint8`` or ``uint16``); memory use does not depend on the movie's length.
    Use as a context manager so the file is closed.
    """

    def __init__(self, path: Path, info: MovieInfo) -> None:
        self.path = path
        self.info = info

    # -- streaming -----------------------------------------------------------
    @abc.abstractmethod
    def _iter(self, start: int, stop: int, step: int) -> Iterator[np.ndarray]:
        """Yield frames ``start, start+step, ... < stop``."""

    def frames(self, start: int = 0, stop: int | None = None, step: int = 1) -> Iterator[np.ndarray]:
        """Iterate over frames ``start:stop:step`` in order.

        Parameters
        ----------
        start, stop, step : int
            Frame range, as for a Python slice (non-negative, ``step >= 1``).
        """
        n = self.info.n_frames
        stop = n if stop is None else min(stop, n)
        if start < 0 or step < 1:
            raise ValueError("start must be >= 0 and step >= 1")
        if start >= stop:
            return iter(())
        return self._iter(start, stop, step)

    def prefetch(self) -> None:
        """Hint that the whole movie will be read soon: start reading it into the cache.

        Returns at once; a background thread owned by this movie asks the kernel
        for the file chunk by chunk (:class:`grainplug._system.ReadAhead`), so the
        reads overlap whatever the caller does next (finding the tube) and
        :meth:`read_band` then finds the data in memory. At most half of the free
        memory is asked for: a larger movie is read ahead in a window that moves
        with the stream. Stopped when the movie is closed; a no-op for folders
        and in-memory arrays.
        """
        if getattr(self, "_readahead", None) is not None or not self.path.is_file():
            return
        self._readahead = ReadAhead(self.path, free_memory_bytes() * READAHEAD_MEMORY_SHARE)

    def _advise_ahead(self, position: int) -> None:
        """The stream is at byte ``position`` of the file: move the read-ahead window."""
        ra = getattr(self, "_readahead", None)
        if ra is not None:
            ra.advance(position)

    def _prefetch_only(self, lo: int, hi: int) -> bool:
        """Restrict the read-ahead to bytes ``[lo, hi)`` of every frame.

        Offsets count from the lowest-addressed byte of a frame as
        :meth:`_block_reader` returns it (:meth:`_frame_offsets`). :meth:`read_band`
        calls it with the bytes its band touches: where the tube crosses a
        wide frame (a horizontal tube in a landscape frame) most of the file is
        then never read. Returns whether the read-ahead took it
        (:meth:`grainplug._system.ReadAhead.restrict`: only when it skips enough).
        """
        ra = getattr(self, "_readahead", None)
        offsets = self._frame_offsets()
        if ra is None or offsets is None:
            return False
        return ra.restrict(offsets, lo, hi)

    @property
    def _sparse(self) -> bool:
        """Whether the read-ahead asks for part of each frame only (:meth:`_prefetch_only`):
        then maps must not pull in the rest (:func:`map_file` with ``sparse``)."""
        ra = getattr(self, "_readahead", None)
        return ra is not None and ra.restricted

    def _frame_offsets(self) -> np.ndarray | None:
        """File offset of each frame's first byte, for frames stored uncompressed at
        known places (those :meth:`_block_reader` maps), else None."""
        return None

    def _stop_prefetch(self) -> None:
        ra = getattr(self, "_readahead", None)
        if ra is not None:
            ra.close()
            ra.join()
            self._readahead = None

    def _block_reader(self) -> Callable[[int, int], np.ndarray] | None:
        """A function ``(start, count) -> frames`` that any thread may call, or None.

        Readers whose frames can be reached independently (memory-mapped
        uncompressed stacks) return one, so that blocks of frames are read by
        several threads at once; the arrays may be views (memory maps), valid
        as long as they are referenced, and in any channel order.
        """
        return None

    def _analysis_frames(self) -> Iterator[np.ndarray]:
        """All frames, in order, in whatever layout is cheapest to read.

        For grey-level analysis only: colour channels may come in any order (or
        as luma alone, for YUV video), and an array may be a view that is only
        valid until the next one is produced.
        """
        return self.frames()

    def _analysis_levels(self) -> tuple[float, float] | None:
        """``(offset, gain)`` that put the grey levels of :meth:`_analysis_frames` on those of :meth:`frames`
        (``(v - offset) * gain``), or None when they are the same: limited-range ("TV") luma, for YUV video."""
        return None

    def read_band(self, band: Band, *, threads: int | None = None,
                  progress: Callable[[int], None] | None = None) -> np.ndarray:
        """The band's profile of every frame: the one streaming call the analysis makes.

        Parameters
        ----------
        band : Band
            Which pixels to average at each position along the tube.
        threads : int, optional
            Threads reading frames where the format allows it (memory-mapped
            uncompressed frames); default one per core. Results do not depend on it.
        progress : callable, optional
            Called with the number of frames done, now and then.

        Returns
        -------
        ndarray, shape (n_frames, band.n_positions), float32
            Fewer rows if the stream ended early.

        Notes
        -----
        Each reader serves it the fastest way it can: uncompressed frames at
        known places are memory-mapped in blocks read by several threads, and the
        read-ahead (:meth:`prefetch`) is restricted to the bytes the band
        touches where that skips most of each frame; other formats are decoded
        once, in order, in their native layout. All give the numbers of
        :meth:`grainplug.band.Band.profile` of the frames :meth:`frames` hands out,
        except YUV-coded video (H.264, MJPEG...), whose profiles are of the luma plane as
        decoded, with no colour conversion, put on the full range of grey levels (limited-range
        luma, 16-235, stretched to 0-255 as a conversion to grey does): for grey scenes the grey
        levels themselves, which the light's ratios (the compactness, the references) need; for
        tinted scenes the luma rather than the channels' mean.
        """
        from .band import BandGather, profiles_from_blocks, profiles_from_frames

        n = self.info.n_frames
        if band.frame_shape != (self.info.height, self.info.width):
            raise ValueError(f"the band was made for {band.frame_shape} frames, not "
                             f"{(self.info.height, self.info.width)}")
        read_block = self._block_reader()
        if read_block is None:
            out = profiles_from_frames(self._analysis_frames(), band, n_frames=n, progress=progress)
            levels = self._analysis_levels()
            if levels is not None:  # an affine map commutes with the band's weighted means
                out -= np.float32(levels[0])
                out *= np.float32(levels[1])
            return out
        lo, hi = BandGather(band).byte_span(read_block(0, 1)[0])
        if self._prefetch_only(lo, hi):  # e.g. a horizontal tube: most of each frame is never read
            stride = int(np.diff(self._frame_offsets()[:2])[0])
            log.info("reading %.1f%% of each frame from the disk (the tube's band)", 100.0 * (hi - lo) / stride)
        n_threads = max(1, threads if threads is not None else (os.cpu_count() or 1))
        return profiles_from_blocks(read_block, band, n_frames=n, threads=n_threads, progress=progress)

    def __iter__(self) -> Iterator[np.ndarray]:
        return self.frames()

    def __len__(self) -> int:
        return self.info.n_frames

    def read(self, index: int) -> np.ndarray:
        """One frame by its index (may be slow for compressed video: it decodes from a key frame).

        Parameters
        ----------
        index : int
            The frame's index, ``0 <= index < info.n_frames``.

        Returns
        -------
        ndarray
            ``H x W`` (grey) or ``H x W x 3`` (RGB), in the movie's own dtype.
        """
        if not 0 <= index < self.info.n_frames:
            raise IndexError(f"frame {index} out of range 0..{self.info.n_frames - 1}")
        return next(iter(self.frames(index, index + 1)))

    def sample(self, n: int) -> tuple[np.ndarray, list[np.ndarray]]:
        """About ``n`` frames spread over the movie, read the cheapest way.

        Parameters
        ----------
        n : int
            How many frames to sample (all of them in a shorter movie).

        Returns
        -------
        indices : ndarray
            Frame indices of the sample.
        frames : list of ndarray
            The frames.
        """
        idx = self._spread(n)
        return idx, [self._read_sampled(int(i)) for i in idx]

    def _spread(self, n: int) -> np.ndarray:
        """Indices of about ``n`` frames spread evenly over the movie, first and last included."""
        total = self.info.n_frames
        return np.unique(np.linspace(0, total - 1, min(n, total)).round().astype(int))

    def _read_sampled(self, index: int) -> np.ndarray:
        """One frame of :meth:`sample`; readers that can read it alone, with no read-ahead
        window around it, do so."""
        return self.read(index)

    @property
    def first_frame_index(self) -> int:
        """Index, in the recording, of this movie's first frame (0; a :class:`FrameWindow` later)."""
        return 0

    def timestamps_s(self) -> np.ndarray:
        """Per-frame time stamps in seconds from the first frame.

        Where the file records presentation times they are used; otherwise the
        times are ``index / fps``. Raises ``ValueError`` when neither exists.
        """
        if not self.info.fps:
            raise ValueError("the frame rate is unknown: pass fps=")
        return np.arange(self.info.n_frames) / self.info.fps

    @property
    def has_file_timestamps(self) -> bool:
        """Whether :meth:`timestamps_s` comes from times stored in the file."""
        return False

    def file_timestamps_upto(self, stop: int) -> np.ndarray | None:
        """The file's time stamps of frames ``0 .. stop - 1`` (s, first frame at 0), or None when the file
        records none or they are not known yet (a video's, before those frames were read): what a window of
        the movie (:class:`~grainplug.readers.window.FrameWindow`) is timed by."""
        return np.asarray(self.timestamps_s())[:stop] if self.has_file_timestamps else None

    # -- context manager ----------------------------------------------------
    def close(self) -> None:
        """Stop the read-ahead (joining its thread) and release the file."""
        self._stop_prefetch()
        self._close()

    def _close(self) -> None:  # noqa: B027 - optional hook
        """Release the reader's own resources (files, decoders)."""

    def __enter__(self) -> Movie:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        i = self.info
        return f"<{type(self).__name__} {i.path!r} {i.width}x{i.height}x{i.channels} n={i.n_frames}>"
