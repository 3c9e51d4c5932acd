"""Compressed and raw video containers through PyAV (FFmpeg)."""

from __future__ import annotations

import logging
import re
from collections.abc import Callable, Iterator
from fractions import Fraction
from pathlib import Path
from typing import ClassVar

import av
import numpy as np

from ..errors import MovieError
from .base import Movie, MovieInfo, choose_fps, map_file, read_file

log = logging.getLogger(__name__)

_GRAY8 = {"gray", "gray8", "pal8"}
_GRAY16 = {"gray16le", "gray16be", "gray10le", "gray12le", "gray10be", "gray12be", "y16"}
#: codecs whose every frame is a key frame: a frame can be sought and decoded alone
#: (not FFV1, whose frames between key frames carry the coder state)
INTRA_ONLY = {"rawvideo", "mjpeg", "png", "tiff", "bmp", "prores", "dnxhd", "huffyuv", "ffvhuff",
              "utvideo", "v210", "r210", "qtrle", "jpeg2000", "cfhd"}

_RGB16 = {"rgb48le", "rgb48be", "bgr48le", "bgr48be", "rgba64le", "rgba64be", "gbrp16le",
          "gbrp12le", "gbrp10le", "yuv444p16le", "yuv420p16le"}


def _native_luma(pix_fmt: str) -> bool:
    """Whether the analysis reads frames of pixel format ``pix_fmt`` as their 8-bit luma plane, as decoded."""
    name = pix_fmt.lower()
    return name.startswith(("yuv", "yuvj", "nv12", "nv21")) and not any(
        d in name for d in ("9", "10", "12", "14", "16"))


def _output_format(pix_fmt: str | None) -> tuple[str, int, int]:
    """Map a stream pixel format to (ffmpeg target format, channels, bit depth)."""
    name = (pix_fmt or "").lower()
    if name in _GRAY8 or (name.startswith("gray") and "16" not in name and "1" not in name[4:]):
        return "gray", 1, 8
    if name in _GRAY16 or name.startswith(("gray1", "gray9")):
        return "gray16le", 1, 16
    if name in _RGB16 or "48" in name or "64" in name:
        return "rgb48le", 3, 16
    return "rgb24", 3, 8


#: FFmpeg's demuxers of text, which it renders as video: a README or a .txt file is not a movie
TEXT_FORMATS = frozenset({"tty", "ansi", "bin", "xbin", "adf", "idf", "ass", "srt", "webvtt", "subviewer",
                          "microdvd", "jacosub", "sami", "realtext", "mpl2", "vplayer", "pjs", "stl", "lrc"})


class VideoMovie(Movie):
    """A movie in any container FFmpeg reads (AVI, MP4, MKV, MOV; MJPEG, H.264, FFV1, raw).

    Decoding uses FFmpeg's frame and slice threads on every core.
    """

    def __init__(self, path: Path, *, fps: float | None = None, threads: int = 0,
                 verify: bool = False) -> None:
        self._threads = threads
        try:
            container = av.open(str(path), mode="r")
        except av.error.FFmpegError as exc:  # not a movie, truncated header, ...
            raise MovieError(
                f"cannot read {path}: {exc.strerror or exc} — is it a complete movie file? "
                "grainplug reads AVI/MP4/MKV/MOV/WebM videos, TIFF stacks, image folders, .cine and .mraw"
            ) from None
        try:
            if not container.streams.video:
                raise MovieError(f"{path} holds no video stream — pass a movie file")
            if container.format.name.split(",")[0] in TEXT_FORMATS:  # FFmpeg "plays" any text as a terminal's screen
                raise MovieError(f"{path} is text, not a movie (FFmpeg would draw it as a terminal's screen: "
                                 f"{container.format.name}) — pass a movie file")
            stream = container.streams.video[0]
            ctx = stream.codec_context
            width, height = ctx.width, ctx.height
            if not width or not height:
                raise MovieError(f"{path}: the video stream has no frame size — the file is corrupt")
            pix_name = (ctx.format.name if ctx.format else "") or ""
            self._target, channels, depth = _output_format(pix_name or None)
            # luma read as decoded (the analysis's frames) is limited range unless the stream says full (yuvj*,
            # color_range 2 = JPEG): 16-235 for 8 bits, put on 0-255 as a conversion to grey does
            self._levels = (16.0, 255.0 / 219.0) if (
                _native_luma(pix_name) and not pix_name.startswith("yuvj")
                and int(getattr(ctx, "color_range", 0) or 0) != 2) else None
            rate = stream.average_rate or stream.guessed_rate or stream.base_rate
            file_fps = float(rate) if rate else None
            n_frames = int(stream.frames or 0)
            self._pts: np.ndarray | None = None
            self._keys: list[int] | None = None  # indices of the key frames, once the packets were walked
            self._blocks: Callable | bool | None = None
            self._raw_frame: Callable[[int], np.ndarray] | None = None
            self._offsets: np.ndarray | None = None
            self._time_base = stream.time_base or Fraction(1, 1)
            announced = n_frames
            if announced <= 0 and container.duration and file_fps:
                # containers without a frame count (Matroska) still record a duration
                announced = int(round(container.duration / 1e6 * file_fps))
            if verify or n_frames <= 0:
                counted, pts, self._keys = self._demux_count(container)
                # a count estimated from the duration is too high for a variable frame rate: then the frames
                # still span the duration, where a truncated file's stop short of it
                # (the duration runs from the file's time 0, which may be before the first frame)
                end_s = float(pts[-1] * self._time_base) if pts is not None and len(pts) else None
                whole = (end_s is not None and container.duration and file_fps
                         and end_s + 2.0 / file_fps >= container.duration / 1e6)
                if announced > 0 and counted < announced - 1 and not whole:
                    raise MovieError(
                        f"{path} is truncated: its header announces {announced} frames but it "
                        f"holds only {counted} — copy the file again from the camera or recorder"
                    )
                n_frames = counted
                self._pts = pts
            if n_frames <= 0:
                raise MovieError(f"{path} holds no video frames — pass a movie with frames")
            codec = ctx.name
            self._codec = codec
            fmt_name = container.format.name.split(",")[0]
        finally:
            container.close()
        use_fps, source, fps_doubts = choose_fps(fps, file_fps)
        warnings: tuple[str, ...] = tuple(fps_doubts)
        if depth == 8 and re.match(r"(yuv|yuva|yuvj|nv|p0|p2|p4).*(9|1[0246])(le|be)$", pix_name):  # deep YUV
            from .cvvideo import deep_warning

            warnings = (*warnings, deep_warning(pix_name, yuv=True, reader="PyAV"))
        info = MovieInfo(
            path=str(path), format=f"video:{fmt_name}/{codec}", width=width, height=height,
            n_frames=n_frames, fps=use_fps, channels=channels, bit_depth=depth,
            dtype="uint16" if depth == 16 else "uint8", fps_source=source, warnings=warnings,
        )
        super().__init__(path, info)

    @staticmethod
    def _demux_count(container: av.container.InputContainer) -> tuple[int, np.ndarray | None, list[int]]:
        """One walk over the packets: how many frames, their presentation times (None
        unless every packet has one) and which are key frames (in decoding order)."""
        stream = container.streams.video[0]
        pts: list[int] = []
        keys: list[int] = []
        count = 0
        try:
            for packet in container.demux(stream):
                if packet.size == 0:
                    continue  # flush packet
                if packet.is_keyframe:
                    keys.append(count)
                count += 1
                if packet.pts is not None:
                    pts.append(packet.pts)
        except av.error.FFmpegError as exc:
            log.warning("demuxing stopped early: %s", exc)
        arr = np.sort(np.asarray(pts, dtype=np.int64)) if len(pts) == count and pts else None
        return count, arr, keys

    @property
    def has_file_timestamps(self) -> bool:
        return True

    def timestamps_s(self) -> np.ndarray:
        """Presentation time of every frame from the container, first frame at 0."""
        if self._pts is None:
            with av.open(str(self.path)) as container:
                _, self._pts, self._keys = self._demux_count(container)
        if self._pts is None or len(self._pts) != self.info.n_frames:
            return super().timestamps_s()
        return (self._pts - self._pts[0]) * float(self._time_base)

    def sample(self, n: int) -> tuple[np.ndarray, list[np.ndarray]]:
        """About ``n`` frames spread over the movie, decoding only key frames.

        Raw video whose layout :meth:`_block_reader` has proven is copied straight
        from the file (no decoding, no decoder buffers). Intra-only codecs (MJPEG,
        ...) have every frame a key frame, so the sample spans the whole movie;
        inter-coded video (H.264) with too few key frames falls back to every k-th
        frame of a prefix.
        """
        total = self.info.n_frames
        if total <= n:
            return np.arange(total), list(self.frames())
        if self._block_reader() is not None:  # raw video: copied from the file, nothing decoded
            wanted = self._spread(n)
            return wanted, [self._raw_frame(int(k)) for k in wanted]
        if self._codec in INTRA_ONLY:
            got = self._seek_sample(self._spread(n))
            if got is not None:
                return got
        try:
            keys = self._keys
            if keys is None:  # the packets were not walked when the movie was opened
                with av.open(str(self.path)) as container:
                    keys = [k for k, pkt in enumerate(p for p in container.demux(video=0) if p.size)
                            if pkt.is_keyframe]
                self._keys = keys
            if len(keys) >= min(n, 24):
                pick = sorted({keys[k] for k in np.linspace(0, len(keys) - 1, n).round().astype(int)})
                frames: list[np.ndarray] = []
                with av.open(str(self.path)) as container:
                    stream = container.streams.video[0]
                    ctx = stream.codec_context
                    wanted = set(pick)
                    k = 0
                    for pkt in container.demux(stream):
                        if not pkt.size:
                            continue
                        if k in wanted:
                            for frame in ctx.decode(pkt):
                                frames.append(frame.to_ndarray(format=self._target))
                        k += 1
                    for frame in ctx.decode(None):
                        frames.append(frame.to_ndarray(format=self._target))
                if len(frames) == len(pick):
                    return np.asarray(pick), frames
        except av.error.FFmpegError:
            pass
        # inter-coded video with few key frames: decode a prefix and keep every k-th frame
        prefix = min(total, max(4 * n, 240))
        step = max(1, prefix // n)
        idx = np.arange(0, prefix, step)
        return idx, list(self.frames(0, prefix, step))

    def _seek_sample(self, wanted: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]] | None:
        """Decode only the wanted frames of an intra-only video.

        Each frame is reached by seeking, then skipping packets without decoding
        them; where seeking lands too far back (no index), one pass over the
        packets decodes only the wanted ones. Returns None if that fails too.
        """
        frames: list[np.ndarray] = []
        try:
            with av.open(str(self.path)) as container:
                stream = container.streams.video[0]
                stream.thread_type = "SLICE"  # frame threads would delay each frame's output
                ctx = stream.codec_context
                tb = float(stream.time_base)
                start = stream.start_time or 0
                rate = float(stream.average_rate or self.info.fps or 1.0)
                targets = [start + int(round(i / rate / tb)) for i in wanted.tolist()]
                seek_ok = True
                for pts in targets:
                    got = None
                    if seek_ok:
                        container.seek(pts, stream=stream, backward=True, any_frame=False)
                        skipped = 0
                        for pkt in container.demux(stream):
                            if pkt.pts is None or not pkt.size:
                                continue
                            if pkt.pts < pts:
                                skipped += 1
                                if skipped > 64:  # the container does not seek precisely
                                    seek_ok = False
                                    break
                                continue
                            if pkt.pts == pts:
                                decoded = ctx.decode(pkt)
                                got = decoded[0].to_ndarray(format=self._target) if decoded else None
                            break
                    if got is None and not seek_ok:
                        return self._one_pass_sample(wanted, targets)
                    if got is None:
                        return None
                    frames.append(got)
        except av.error.FFmpegError:
            return None
        return wanted, frames

    def _one_pass_sample(self, wanted: np.ndarray, targets: list[int]) -> tuple[np.ndarray, list[np.ndarray]] | None:
        """One pass over the packets, decoding only the wanted (intra-coded) ones."""
        want = {p: k for k, p in enumerate(targets)}
        out: list[np.ndarray | None] = [None] * len(targets)
        with av.open(str(self.path)) as container:
            stream = container.streams.video[0]
            stream.thread_type = "SLICE"
            ctx = stream.codec_context
            for pkt in container.demux(stream):
                if pkt.pts in want and pkt.size:
                    decoded = ctx.decode(pkt)
                    if decoded:
                        out[want[pkt.pts]] = decoded[0].to_ndarray(format=self._target)
        if any(f is None for f in out):
            return None
        return wanted, out  # type: ignore[return-value]

    #: packed uncompressed layouts that can be read straight from the file: channels per pixel
    _PACKED: ClassVar[dict[str, int]] = {"gray": 1, "rgb24": 3, "bgr24": 3, "rgba": 4, "bgra": 4, "rgb0": 4, "bgr0": 4}

    def _block_reader(self) -> Callable[[int, int], list[np.ndarray]] | None:
        """Frames of uncompressed video read straight from the file (memory maps), or None.

        For raw video whose container indexes every frame (AVI, MOV...): the byte
        position of each frame comes from the index, and the layout is checked
        once against PyAV's own decoding of three frames (first, middle, last),
        so that row order, padding and offsets are proven, not assumed. Anything
        else (compressed video, no index, a mismatch) gets None and is decoded.
        """
        if self._blocks is None:
            self._blocks = self._make_block_reader() or False
        return self._blocks or None

    def _make_block_reader(self) -> Callable[[int, int], list[np.ndarray]] | None:
        if self._codec != "rawvideo":
            return None
        n, h, w = self.info.n_frames, self.info.height, self.info.width
        try:
            with av.open(str(self.path)) as container:
                stream = container.streams.video[0]
                fmt = stream.codec_context.format.name if stream.codec_context.format else ""
                entries = stream.index_entries
                if fmt not in self._PACKED or len(entries) != n:
                    return None
                pos = np.array([e.pos for e in entries], dtype=np.int64)
                size = np.array([e.size for e in entries], dtype=np.int64)
                stamps = np.array([e.timestamp for e in entries], dtype=np.int64)
        except (av.error.FFmpegError, AttributeError, TypeError, ValueError):
            return None
        ch = self._PACKED[fmt]
        frame_bytes = int(size[0])
        if not (size == frame_bytes).all() or frame_bytes % h or frame_bytes // h < w * ch or np.any(np.diff(pos) <= 0):
            return None
        line = frame_bytes // h
        file_size = self.path.stat().st_size

        def view(mm: np.ndarray, at: int, flip: bool) -> np.ndarray:
            """Frame whose data start at byte ``at`` of ``mm``, in the decoder's native layout."""
            rows = mm[at: at + frame_bytes].reshape(h, line)[:, : w * ch].reshape(h, w, ch)
            rows = rows[::-1] if flip else rows
            return rows[..., 0] if ch == 1 else rows[..., :3] if ch == 4 and fmt[-1] in "a0" else rows

        # the index may point at each chunk's header or at its data; rows may run bottom-up
        probe = sorted({0, n // 2, n - 1})
        decoded = [self._seek_frame(k, lambda f: np.array(self._native(f, self._target))) for k in probe]
        if any(d is None for d in decoded):
            return None

        def matches(skip: int, flip: bool) -> bool:
            for k, ref in zip(probe, decoded, strict=True):
                at = int(pos[k]) + skip
                if at + frame_bytes > file_size:
                    return False
                if not np.array_equal(view(np.memmap(self.path, np.uint8, "r", offset=at, shape=(frame_bytes,)),
                                           0, flip), ref):
                    return False
            return True

        layout = next(((skip, flip) for skip in (0, 8, 16) for flip in (False, True) if matches(skip, flip)), None)
        if layout is None:
            log.debug("%s: raw frames not found where the index says; decoding them instead", self.path)
            return None
        skip, flip = layout
        if (stamps >= 0).all() and len(np.unique(stamps)) == n:
            self._pts = np.sort(stamps)  # presentation times from the index: no pass over the packets

        def read_block(start: int, count: int) -> list[np.ndarray]:
            lo, hi = int(pos[start]) + skip, int(pos[start + count - 1]) + skip + frame_bytes
            self._advise_ahead(lo)
            mm = map_file(self.path, lo, (hi - lo,), np.uint8, sparse=self._sparse)
            return [view(mm, int(pos[k] - pos[start]), flip) for k in range(start, start + count)]

        bgr = fmt.startswith("bgr")

        def raw_frame(k: int) -> np.ndarray:
            """Frame ``k`` copied from the file in the layout :meth:`read` returns (RGB or grey)."""
            raw = read_file(self.path, int(pos[k]) + skip, (frame_bytes,), np.uint8, random_access=True)
            frame = np.ascontiguousarray(view(raw, 0, flip))
            if bgr:  # swap two channels in place: several times faster than copying a reversed view
                red = frame[..., 2].copy()
                frame[..., 2] = frame[..., 0]
                frame[..., 0] = red
            return frame

        self._raw_frame = raw_frame
        self._offsets = pos + skip
        return read_block

    def _frame_offsets(self) -> np.ndarray | None:
        """File offset of each raw frame's first stored byte (its lowest address, also
        for rows stored bottom-up); None for compressed video."""
        return self._offsets if self._block_reader() is not None else None

    def read(self, index: int) -> np.ndarray:
        """One frame by index: a seek to the key frame before it, then a few frames decoded.

        The frame is found by its presentation time (from the container's packets
        when they were counted, else from the frame rate); where the container
        cannot seek to it, the movie is decoded from the start.
        """
        n = self.info.n_frames
        if not 0 <= index < n:
            raise IndexError(f"frame {index} out of range 0..{n - 1}")
        if index > 0:
            got = self._read_by_seeking(index)
            if got is not None:
                return got
        return super().read(index)

    def _read_by_seeking(self, index: int) -> np.ndarray | None:
        return self._seek_frame(index, lambda f: f.to_ndarray(format=self._target))

    def _seek_frame(self, index: int, convert: Callable[[av.VideoFrame], np.ndarray]) -> np.ndarray | None:
        """``convert(frame k)``, reached by seeking; None where the container cannot seek to it."""
        try:
            with av.open(str(self.path)) as container:
                stream = container.streams.video[0]
                stream.thread_type = "SLICE"
                tb = float(stream.time_base or 0) or 1.0
                rate = float(stream.average_rate or self.info.fps or 0)
                if self._pts is not None and len(self._pts) == self.info.n_frames:
                    target = int(self._pts[index])
                elif rate > 0:
                    target = (stream.start_time or 0) + int(round(index / rate / tb))
                else:
                    return None
                half = 0.5 / rate / tb if rate > 0 else 0.5
                container.seek(target, stream=stream, backward=True, any_frame=False)
                for frame in container.decode(stream):
                    if frame.pts is None:
                        return None
                    if frame.pts >= target - half:
                        if abs(frame.pts - target) <= half:
                            return convert(frame)
                        return None  # the seek landed past the frame
        except av.error.FFmpegError:
            return None
        return None

    def _analysis_levels(self) -> tuple[float, float] | None:
        return self._levels

    def _analysis_frames(self) -> Iterator[np.ndarray]:
        """Decoded frames in their native layout: packed RGB/BGR as they are, luma only for
        YUV, planar RGB and 16-bit through a conversion to RGB. No colour
        conversion is done, so analysis runs at the speed of decoding."""
        return self._iter(0, self.info.n_frames, 1, native=True)

    @staticmethod
    def _native(frame: av.VideoFrame, fallback: str) -> np.ndarray:
        name = frame.format.name
        w, h = frame.width, frame.height
        if any(p.line_size <= 0 for p in frame.planes):
            # rows stored bottom-up (an AVI's DIB): PyAV's own conversion reads them in order
            try:
                return frame.to_ndarray()
            except ValueError:
                return frame.to_ndarray(format=fallback)
        if name in ("gray", "rgb24", "bgr24"):
            plane = frame.planes[0]
            ch = 1 if name == "gray" else 3
            arr = np.frombuffer(plane, np.uint8).reshape(h, plane.line_size)[:, : w * ch]
            return arr if ch == 1 else arr.reshape(h, w, 3)
        if name in ("bgr0", "rgb0", "bgra", "rgba", "0rgb", "0bgr", "argb", "abgr"):
            plane = frame.planes[0]
            arr = np.frombuffer(plane, np.uint8).reshape(h, plane.line_size)[:, : w * 4].reshape(h, w, 4)
            return arr[..., 1:] if name[0] in "0a" else arr[..., :3]
        if _native_luma(name):
            plane = frame.planes[0]
            return np.frombuffer(plane, np.uint8).reshape(h, plane.line_size)[:, :w]
        return frame.to_ndarray(format=fallback)

    def _iter(self, start: int, stop: int, step: int, native: bool = False) -> Iterator[np.ndarray]:
        try:
            container = av.open(str(self.path))
        except av.error.FFmpegError as exc:
            raise MovieError(f"cannot reopen {self.path}: {exc}") from None
        index = 0
        seen: list[int] = []
        try:
            stream = container.streams.video[0]
            stream.thread_type = "AUTO"
            if self._threads:
                stream.codec_context.thread_count = self._threads
            for frame in container.decode(stream):
                if index >= stop:
                    break
                if native:
                    seen.append(-1 if frame.pts is None else int(frame.pts))
                if index >= start and (index - start) % step == 0:
                    yield self._native(frame, self._target) if native else frame.to_ndarray(format=self._target)
                index += 1
        except av.error.FFmpegError as exc:
            raise MovieError(
                f"{self.path} is corrupt or truncated: decoding failed at frame {index} ({exc}) — "
                "re-export or copy the movie again"
            ) from None
        finally:
            container.close()
        if native and len(seen) == self.info.n_frames and min(seen) >= 0:
            self._pts = np.sort(np.asarray(seen, dtype=np.int64))  # time stamps, without another pass
        if index < stop and stop <= self.info.n_frames and index < self.info.n_frames:
            raise MovieError(
                f"{self.path} is truncated: only {index} of {self.info.n_frames} frames decode — "
                "copy the file again from the camera or recorder"
            )
