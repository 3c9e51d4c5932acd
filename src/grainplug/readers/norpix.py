"""NorPix StreamPix ``.seq`` sequences (uncompressed), decoded here from the documented layout.

Layout, little-endian: a header (1024 bytes before StreamPix 6, 8192 since), then
each frame at ``header + k * TrueImageSize``: its pixels (``ImageSizeBytes``), then
its time stamp (u32 seconds since 1970, u16 milliseconds, and since StreamPix 6 u16
microseconds), then padding.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from ..errors import MovieError
from ..warning_codes import coded
from .base import MovieInfo, choose_fps, map_file
from .cine import STAMPS_OVER_HEADER, frames_named, stamp_rate
from .raw import RawFramesMovie, RawLayout

MAGIC = 0xFEED
#: ImageFormat values read: grey, B-G-R, R-G-B
FORMAT_MONO, FORMAT_BGR, FORMAT_RGB = 100, 200, 400


class SeqMovie(RawFramesMovie):
    """A NorPix ``.seq`` movie, uncompressed grey (8/16-bit) or 24-bit colour.

    Parameters
    ----------
    path : Path
        The ``.seq`` file.
    fps : float, optional
        Frame rate to use instead of the file's.
    allow_truncated : bool
        Read the complete frames of a file that ends inside a frame, with a warning.

    Notes
    -----
    The frame rate is that of the frames' time stamps (StreamPix writes the rate it
    was asked for in the header, not always the one it recorded at); a warning says
    when the two differ by more than 1 %. Compressed sequences (JPEG...) are refused.
    """

    def __init__(self, path: Path, *, fps: float | None = None, allow_truncated: bool = False) -> None:
        with open(path, "rb") as fh:
            head = fh.read(1024)
        if len(head) < 632 or struct.unpack_from("<I", head, 0)[0] != MAGIC:
            raise MovieError(f"{path} is not a NorPix .seq file (no 0xFEED mark at its start) — check the file")
        version, = struct.unpack_from("<i", head, 28)
        width, height, bits, bits_real, image_bytes, image_format = struct.unpack_from("<6I", head, 548)
        allocated, = struct.unpack_from("<I", head, 572)
        true_size, = struct.unpack_from("<I", head, 580)
        suggested, = struct.unpack_from("<d", head, 584)
        compression, = struct.unpack_from("<I", head, 620)
        header = 8192 if version >= 5 else 1024
        if compression != 0:
            raise MovieError(f"{path} is a compressed .seq (compression format {compression}) — export it "
                             "uncompressed from StreamPix")
        if image_format == FORMAT_MONO and bits in (8, 16):
            shape, channels = (height, width), 1
        elif image_format in (FORMAT_BGR, FORMAT_RGB) and bits == 24:
            shape, channels = (height, width, 3), 3
        else:
            raise MovieError(f"{path}: .seq image format {image_format} with {bits}-bit pixels is not supported — "
                             "export grey 8/16-bit or 24-bit colour frames")
        encoding = "u16le" if bits == 16 else "u8"
        pixel_bytes = width * height * bits // 8
        if width <= 0 or height <= 0 or image_bytes < pixel_bytes or true_size < image_bytes:
            raise MovieError(f"{path}: the .seq header's sizes are inconsistent ({width} x {height}, {image_bytes} "
                             f"bytes per image, {true_size} per frame) — the file is damaged")
        stamp_bytes = 8 if version >= 5 else 6
        size = path.stat().st_size
        # the frames the header says were recorded (AllocatedFrames), or those the file has begun
        n_listed = max(allocated, -(-max(0, size - header) // true_size))
        if n_listed == 0:
            raise MovieError(f"{path} holds a .seq header but no frame — the recording is empty or was cut short")
        # a frame is whole when its pixels and its time stamp are (the padding after them may be missing)
        room = size - header - image_bytes - stamp_bytes
        n = min(n_listed, room // true_size + 1) if room >= 0 else 0
        offsets = header + np.arange(n, dtype=np.int64) * true_size
        truncated = ""
        if n < n_listed:
            if not allow_truncated or n == 0:
                raise MovieError(f"{path} is truncated: it holds {n} of the {n_listed} frames its header describes — "
                                 "copy the file again" + (f", or give allow_truncated=True to read "
                                                          f"the {n} complete frames" if n else ""))
            truncated = coded("movie.truncated",
                              f"the file is truncated: reading the first {n} of the {n_listed} frames its header "
                              "describes")
        stamps = _stamps(path, header, true_size, image_bytes, n, micro=version >= 5)
        layout = RawLayout(offsets=offsets[:n], shape=shape, encoding=encoding, bgr=image_format == FORMAT_BGR)
        stamp_fps, jitter, bad = stamp_rate(stamps)
        warnings_ = [truncated] if truncated else []
        rate, note = (stamp_fps, f"time stamps ({stamp_fps:.6g} fps)") if stamp_fps else (
            (suggested, "header's suggested rate") if suggested > 0 else (None, ""))
        if fps is None and stamp_fps and suggested > 0 and abs(stamp_fps / suggested - 1) > 0.01:
            warnings_.append(coded("movie.fps_stamps", f"the frame time stamps say {stamp_fps:.4g} fps but the "
                                   f"header suggests {suggested:g} fps — " + STAMPS_OVER_HEADER))
        if bad:
            warnings_.append(coded("movie.frames_out_of_step", f"{frames_named(bad)} out of step with the others "
                                   "— frames may have been dropped while recording"))
        use_fps, source, fps_doubts = choose_fps(fps, rate)
        warnings_.extend(fps_doubts)
        info = MovieInfo(
            path=str(path), format=f"seq:{bits}-bit", width=width, height=height, n_frames=n,
            fps=use_fps, channels=channels, bit_depth=bits_real if 0 < bits_real <= bits else bits // channels,
            dtype="uint16" if bits == 16 else "uint8", fps_source=source, fps_note="" if fps else note,
            colour="rgb" if channels == 3 else "grey", camera="NorPix StreamPix", warnings=tuple(warnings_),
            details={"version": version, "suggested_fps": suggested, "timestamp_jitter": round(jitter, 6),
                     **({"frames_with_bad_timestamp": [int(k) for k in bad]} if bad else {}),
                     "first_timestamp_s": _first_stamp(path, header + image_bytes)},
        )
        super().__init__(path, info, layout)


def _stamps(path: Path, header: int, stride: int, image_bytes: int, n: int, *, micro: bool) -> np.ndarray:
    """Each frame's time stamp in seconds from the whole second of the first one."""
    if n == 0:
        return np.zeros(0)
    width = 8 if micro else 6
    flat = map_file(path, header + image_bytes, ((n - 1) * stride + width,), np.uint8)
    raw = np.lib.stride_tricks.as_strided(flat, shape=(n, width), strides=(stride, 1), writeable=False)
    raw = np.ascontiguousarray(raw)
    seconds = raw[:, :4].copy().view("<u4")[:, 0].astype(np.int64)
    ms = raw[:, 4:6].copy().view("<u2")[:, 0].astype(np.int64)
    us = raw[:, 6:8].copy().view("<u2")[:, 0].astype(np.int64) if micro else 0
    # in whole microseconds from the first frame's second: a float of seconds since 1970 resolves 0.2 us only
    return ((seconds - seconds[0]) * 1_000_000 + ms * 1000 + us).astype(np.float64) / 1e6


def _first_stamp(path: Path, offset: int) -> float:
    """The first frame's time stamp, seconds since 1970 (local time of the recording PC)."""
    with open(path, "rb") as fh:
        fh.seek(offset)
        seconds, ms = struct.unpack("<IH", fh.read(6))
    return seconds + ms / 1e3
