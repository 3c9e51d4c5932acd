"""Video files through OpenCV's FFmpeg, for installs without PyAV.

Notes
-----
grainplug's default install holds no GPL code. PyAV's binary wheels bundle an FFmpeg
built with the GPL encoders x264 and x265, so PyAV is an extra (``pip install
"grainplug[video]"``) and, without it, videos are read through the FFmpeg that
``opencv-python-headless`` bundles (built without GPL parts). It decodes the same
pixels (checked frame for frame against PyAV in the tests), with these limits:

- grey video is read as it is stored when it is 8-bit (``gray``) or 16-bit
  (``gray16le``); every other deep format (10/12-bit grey, 16-bit RGB, 10-bit YUV) is
  converted to 8 bits by OpenCV, and the movie's ``info.warnings`` say so, with the fix;
- frame times are the container's time stamps once the movie has been read through (the
  analysis does), ``index / fps`` before;
- a frame is reached by OpenCV's seek (key frame, then decoding forward) in containers that
  index their frames (MP4, MOV, AVI, Matroska, WebM), and the frame's time stamp is checked
  against the one expected: where the seek landed elsewhere (an MPEG transport stream, a
  variable frame rate) the frame is decoded forward from the start instead.

Frame counts come from the container (MP4, MOV, AVI index them); Matroska, WebM and
others record a duration only, so their frames are counted by decoding them once when
the movie is opened. A file that decodes fewer frames than it announced is refused
as truncated, as PyAV's reader does (OpenCV 4.8 has no ``CAP_PROP_PTS``: there, a Matroska
file whose first frame is not at time 0 may be called truncated). What FFmpeg and OpenCV print while a file is opened
(``moov atom not found``, ``File ended prematurely``) is kept off the terminal: the reader
says what is wrong in one line.

Checked on opencv-python-headless 4.8.1 (with numpy 1.26, which it needs) and 5.0.0: the same
pixels (8- and 16-bit grey as stored, colour, 12-bit grey and 16-bit RGB converted to 8 bits),
the same pixel-format tags, time stamps and seeks, and the VP8 writer of the overlay.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from ..errors import MovieError
from ..warning_codes import coded
from .base import Movie, MovieInfo, choose_fps

log = logging.getLogger(__name__)

#: containers whose frame count OpenCV reads from an index (others: estimated from the duration, so counted)
INDEXED_SUFFIXES = (".mp4", ".mov", ".m4v", ".avi")
#: containers in which OpenCV's seek lands on the frame asked for (checked, all the same, by its time stamp)
SEEKABLE_SUFFIXES = (".mp4", ".mov", ".m4v", ".avi", ".mkv", ".webm")
#: codecs whose every frame decodes alone: a seek costs one frame's decoding
INTRA_CODECS = ("mjpg", "mjpa", "mjpb", "rawvideo", "png", "tiff", "jpeg", "bmp")
#: a frame at most this far ahead of the last one read is reached by decoding forward, not by a seek (which
#: decodes from the key frame before it: up to 250 frames apart in H.264 as x264 writes it)
FORWARD_FRAMES = 100
#: FFmpeg's raw pixel-format tags of formats deeper than 8 bits end in their depth as a byte
#: (``Y1 0 12`` is 12-bit grey, ``G3 0 16`` planar 16-bit RGB, ``Y3 11 10`` 10-bit YUV), except
#: packed 16-bit RGB(A), whose tags end in the bits per pixel (``RGB 48``, ``RBA 64``)
_DEEP_DEPTHS = (9, 10, 12, 14, 16)
_DEEP_PACKED = {b"RGB": 48, b"BGR": 48, b"RBA": 64, b"BRA": 64}
GREY8, GREY16 = b"Y800", b"Y1\x00\x10"
FIX = 'install PyAV to read every bit: pip install "grainplug[video]"'


def deep_warning(pixel_format: str, *, yuv: bool, reader: str) -> str:
    """The warning for a video whose samples are deeper than the 8 bits it is read with."""
    if yuv:  # PyAV converts YUV to 8-bit RGB too: the fix is another export
        return coded("movie.deep_read_shallow",
                     f"the video stores more than 8 bits per sample ({pixel_format}, YUV) but is read as 8 bits — "
                     "export the movie as 16-bit TIFF images or grey FFV1 to keep every bit")
    return coded("movie.deep_read_shallow",
                 f"the video stores more than 8 bits per sample ({pixel_format}) but {reader} reads it as 8 bits — "
                 f"{FIX}")


def _tag(value: float) -> bytes:
    return int(value).to_bytes(4, "little", signed=False) if 0 <= value < 2**32 else b"\0\0\0\0"


def _pixel_format(tag: bytes) -> str:
    """A readable name for FFmpeg's raw pixel-format tag (``Y1 0 12`` -> ``12-bit grey``)."""
    depth = tag[3]
    kinds = {b"Y1": "grey", b"G3": "planar RGB", b"Y3": "YUV", b"Y4": "YUV with alpha"}
    if tag[:2] in kinds and depth in _DEEP_DEPTHS:
        return f"{depth}-bit {kinds[tag[:2]]}"
    if _DEEP_PACKED.get(tag[:3]) == depth:
        return f"16-bit {tag[:3].decode('ascii')}"
    return _describe(tag)


def _describe(tag: bytes) -> str:
    return tag.decode("ascii", "replace").rstrip("\0") if all(32 <= b < 127 for b in tag) else tag.hex()


class OpenCVVideoMovie(Movie):
    """A video (AVI, MP4, MKV, MOV, WebM...) read through OpenCV's FFmpeg.

    Used by :func:`grainplug.readers.open_movie` when PyAV is not installed; see the
    module's notes for what it reads and how.

    Parameters
    ----------
    path : Path
        The video file.
    fps : float, optional
        Frame rate to use instead of the file's.
    verify : bool
        Count the frames by decoding them all, whatever the container says.
    """

    def __init__(self, path: Path, *, fps: float | None = None, verify: bool = False) -> None:
        import cv2

        from .._system import quiet_stderr

        self._cv2 = cv2
        with quiet_stderr():  # FFmpeg's own lines about a bad file: the error below says it in one
            cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
        try:
            if not cap.isOpened():
                raise MovieError(
                    f"cannot read {path} — is it a complete movie file? grainplug reads AVI/MP4/MKV/MOV/WebM "
                    "videos, TIFF stacks, image folders, .cine, .mraw and .seq")
            width = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH))
            height = int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
            if width <= 0 or height <= 0:
                raise MovieError(f"{path}: the video stream has no frame size — the file is corrupt")
            pix = _tag(cap.get(cv2.CAP_PROP_CODEC_PIXEL_FORMAT))
            fourcc = _tag(cap.get(cv2.CAP_PROP_FOURCC))
            codec = "rawvideo" if fourcc == b"\0\0\0\0" else _describe(fourcc).strip().lower() or "?"
            file_fps = float(cap.get(cv2.CAP_PROP_FPS)) or None
            announced = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        finally:
            cap.release()
        warnings: list[str] = []
        self._native = pix in (GREY8, GREY16)  # read as stored, without OpenCV's conversion to BGR
        if self._native:
            channels, depth = 1, 16 if pix == GREY16 else 8
        else:
            channels, depth = (1 if pix[:2] == b"Y1" else 3), 8
            if pix[3] in _DEEP_DEPTHS or _DEEP_PACKED.get(pix[:3]) == pix[3]:
                yuv = pix[:2] not in (b"Y1", b"G3") and pix[:3] not in _DEEP_PACKED
                warnings.append(deep_warning(_pixel_format(pix), yuv=yuv, reader="OpenCV"))
        self._grey_from_bgr = not self._native and channels == 1
        suffix = path.suffix.lower()
        if verify or announced <= 0 or suffix not in INDEXED_SUFFIXES:
            with quiet_stderr():
                counted, last_ms, offset = self._count(path)
            # as PyAV's reader: a count estimated from the duration may be 1 over, counts the time before the
            # first frame (``offset``, in frame periods), and is too high for a variable frame rate, whose frames
            # still span the duration (a truncated file's stop short of it)
            announced = max(announced - offset, 0)
            whole = bool(file_fps) and last_ms + 2000.0 / file_fps >= 1000.0 * announced / file_fps
            if announced > 0 and counted < announced - 1 and not whole:
                raise MovieError(f"{path} is truncated: its header announces {announced} frames but it holds "
                                 f"only {counted} — copy the file again from the camera or recorder")
            announced = counted
        if announced <= 0:
            raise MovieError(f"{path} holds no video frames — pass a movie with frames")
        use_fps, source, fps_doubts = choose_fps(fps, file_fps)
        warnings.extend(fps_doubts)
        info = MovieInfo(
            path=str(path), format=f"video-opencv:{suffix.lstrip('.')}/{codec}", width=width,
            height=height, n_frames=announced, fps=use_fps, channels=channels, bit_depth=depth,
            dtype="uint16" if depth == 16 else "uint8", fps_source=source, warnings=tuple(warnings),
            details={"reader": "opencv", "pixel_format": _pixel_format(pix)},
        )
        super().__init__(path, info)
        self._seekable = suffix in SEEKABLE_SUFFIXES
        self._intra = codec in INTRA_CODECS
        self._seeker = None  # a capture kept open for read(), positioned after the last frame read
        self._next = -1
        # the stamps (ms) OpenCV reported for frames 0, 1, ... of the longest pass that read on from the first
        # frame: every frame's once read through, the first ones' after a window's pass (--end)
        self._head_stamps_ms: list[float] = []
        self._stamps_cache: tuple[int, np.ndarray | None] = (0, None)
        self._file_fps = file_fps
        # frames seen unevenly spaced: a seek to a frame whose stamp is not known yet cannot be checked by the rate
        self._irregular = False

    def _open(self):
        cap = self._cv2.VideoCapture(str(self.path), self._cv2.CAP_FFMPEG)
        if not cap.isOpened():
            raise MovieError(f"cannot reopen {self.path} — was it moved or deleted?")
        if self._native:
            cap.set(self._cv2.CAP_PROP_CONVERT_RGB, 0)
        return cap

    def _count(self, path: Path) -> tuple[int, float, int]:
        """How many frames decode, the last one's time stamp from the first (ms), and the first one's time
        from the file's start in frame periods (OpenCV's ``CAP_PROP_PTS``; 0 where it has none)."""
        cap = self._cv2.VideoCapture(str(path), self._cv2.CAP_FFMPEG)
        pts_prop = getattr(self._cv2, "CAP_PROP_PTS", None)
        n, last_ms, offset = 0, 0.0, 0
        try:
            while cap.grab():
                if n == 0 and pts_prop is not None:
                    offset = max(int(round(cap.get(pts_prop))), 0)
                n += 1
                last_ms = cap.get(self._cv2.CAP_PROP_POS_MSEC)
        finally:
            cap.release()
        return n, last_ms, offset

    def _convert(self, frame: np.ndarray, *, any_order: bool = False) -> np.ndarray:
        """OpenCV's frame as the reader hands it out: grey as it is, colour as RGB
        (``any_order``: BGR left as it is, for the grey-level analysis)."""
        if self._native:
            return frame
        if self._grey_from_bgr:
            return np.ascontiguousarray(frame[..., 0])
        return frame if any_order else self._cv2.cvtColor(frame, self._cv2.COLOR_BGR2RGB)

    def _stamp_check(self, index: int) -> tuple[float, float] | None:
        """``(expected, tolerance)``, in ms, of frame ``index``'s time stamp as OpenCV reports it, or None when
        a seek to it cannot be checked (no frame rate in the file).

        Once the frame was read in order from the first, the stamp recorded for it, within a quarter of the
        interval to its nearer neighbour (frames may be unevenly spaced); before, the file's frame rate's
        ``index / fps``, within a quarter of a period (the user's ``fps`` says nothing of the file's stamps).
        """
        raw = self._raw_stamps_ms
        if raw is not None and index < len(raw):
            gaps = [raw[index] - raw[index - 1] if index > 0 else np.inf,
                    raw[index + 1] - raw[index] if index + 1 < len(raw) else np.inf]
            return float(raw[index]), 0.25 * float(min(gaps))
        if self._file_fps and not self._irregular:
            return 1000.0 * index / self._file_fps, 250.0 / self._file_fps
        return None

    def _seek(self, cap, index: int) -> tuple[bool, np.ndarray | None]:
        """Frame ``index`` read from ``cap`` by seeking, where the container allows it and the frame read
        has the time stamp expected; ``(False, None)`` otherwise (``cap`` is then at an unknown place, if a
        seek was tried: :meth:`_seekable_to`)."""
        check = self._stamp_check(index) if self._seekable else None
        if check is None:
            return False, None
        expected, tolerance = check
        # checked by the rate alone (the frame's own stamp not known yet): in a variable-rate file a seek lands on
        # the frame at index / fps, another frame, whose stamp passes. The frame before must also be one period
        # earlier; where it is not, the frames are not evenly spaced, and frames not yet read in order are reached
        # by decoding from then on.
        raw = self._raw_stamps_ms
        by_rate = raw is None or index >= len(raw)
        if by_rate and index == 0:
            return False, None
        cap.set(self._cv2.CAP_PROP_POS_FRAMES, index - 1 if by_rate else index)
        before = None
        if by_rate:
            ok, _ = cap.read()
            before = cap.get(self._cv2.CAP_PROP_POS_MSEC) if ok else None
        ok, frame = cap.read()
        if not ok or (by_rate and before is None):
            return False, None
        at = cap.get(self._cv2.CAP_PROP_POS_MSEC)
        if by_rate and abs(at - before - 1000.0 / self._file_fps) > tolerance:
            self._irregular = True
            return False, None
        return (True, frame) if abs(at - expected) <= tolerance else (False, None)

    def _seekable_to(self, index: int) -> bool:
        """Whether :meth:`_seek` tries a seek to frame ``index`` (and so may move the capture)."""
        return self._seekable and self._stamp_check(index) is not None

    def _walk_to(self, cap, count: int, *, at: int = 0) -> None:
        """Decode (without converting) the next ``count`` frames of a capture at frame ``at``."""
        for k in range(count):
            if not cap.grab():
                raise MovieError(f"{self.path} is truncated: only {at + k} of {self.info.n_frames} frames decode — "
                                 "copy the file again from the camera or recorder")

    def _decode(self, start: int, stop: int, step: int, *, any_order: bool) -> Iterator[np.ndarray]:
        cap = self._open()
        index = start
        stamps: list[float] = []
        head = start == 0 and step == 1  # its stamps are kept as the frames come: a window's pass stops early
        try:
            first = None
            if start > 0:
                ok, first = self._seek(cap, start)
                if not ok:
                    cap.release()
                    cap = self._open()
                    self._walk_to(cap, start)
            while index < stop:
                if (index - start) % step == 0:
                    if first is not None:
                        ok, frame, first = True, first, None
                    else:
                        ok, frame = cap.read()
                    if not ok:
                        break
                    if head:
                        stamps.append(cap.get(self._cv2.CAP_PROP_POS_MSEC))
                        if len(stamps) > len(self._head_stamps_ms):
                            self._head_stamps_ms = stamps
                    yield self._convert(frame, any_order=any_order)
                elif not cap.grab():
                    break
                index += 1
        finally:
            cap.release()
        if index < stop:
            raise MovieError(f"{self.path} is truncated: only {index} of {self.info.n_frames} frames decode — "
                             "copy the file again from the camera or recorder")

    def _iter(self, start: int, stop: int, step: int) -> Iterator[np.ndarray]:
        return self._decode(start, stop, step, any_order=False)

    def _analysis_frames(self) -> Iterator[np.ndarray]:
        return self._decode(0, self.info.n_frames, 1, any_order=True)

    def read(self, index: int) -> np.ndarray:
        """One frame: decoded on from the last one read when it is a little ahead, else reached by a seek
        checked by the frame's time stamp, else decoded forward from the start."""
        n = self.info.n_frames
        if not 0 <= index < n:
            raise IndexError(f"frame {index} out of range 0..{n - 1}")
        # self._next: the frame the capture gives next; -1 while it moves, so that an error on the way
        # (a truncated file) leaves it unknown, and the next read starts again from a fresh capture
        if self._seeker is None or self._next < 0 or (index < self._next and not self._seekable_to(index)):
            self._reopen()
        at, self._next = self._next, -1
        ok, frame = False, None
        if at < index <= at + FORWARD_FRAMES and not self._intra:
            self._walk_to(self._seeker, index - at, at=at)  # cheaper than a seek back to a key frame
        elif index != at:
            tried = self._seekable_to(index)
            ok, frame = self._seek(self._seeker, index)
            if not ok:  # the seek landed elsewhere (the capture is lost), or cannot be checked: decode forward
                if tried or index < at:
                    self._reopen()
                    at, self._next = 0, -1
                self._walk_to(self._seeker, index - at, at=at)
        if not ok:
            ok, frame = self._seeker.read()
        if not ok:
            raise MovieError(f"{self.path}: frame {index} does not decode — the file is corrupt or truncated")
        self._next = index + 1
        return self._convert(frame)

    def _reopen(self) -> None:
        if self._seeker is not None:
            self._seeker.release()
        self._seeker = None
        self._seeker, self._next = self._open(), 0

    @property
    def _raw_stamps_ms(self) -> np.ndarray | None:
        """The stamps known, of every frame or of the first ones (in order), or None."""
        n = len(self._head_stamps_ms)
        if self._stamps_cache[0] != n:
            stamps = np.asarray(self._head_stamps_ms[:n], dtype=float)
            self._stamps_cache = (n, stamps if n >= 2 and np.all(np.diff(stamps) > 0) else None)
        return self._stamps_cache[1]

    @property
    def has_file_timestamps(self) -> bool:
        raw = self._raw_stamps_ms
        return raw is not None and len(raw) == self.info.n_frames

    def timestamps_s(self) -> np.ndarray:
        """The container's time stamps (first frame at 0) once the movie was read through, else ``index / fps``."""
        if self.has_file_timestamps:
            return self.file_timestamps_upto(self.info.n_frames)  # type: ignore[return-value]
        return super().timestamps_s()

    def file_timestamps_upto(self, stop: int) -> np.ndarray | None:
        """The container's stamps of the first ``stop`` frames once they were read in order from the first (a
        window's pass reads no further than its end)."""
        raw = self._raw_stamps_ms
        if raw is None or len(raw) < stop:
            return None
        return (raw[:stop] - raw[0]) / 1000.0

    def _close(self) -> None:
        if self._seeker is not None:
            self._seeker.release()
            self._seeker = None
