"""Streaming movie writers for every format grainplug reads.

Each writer takes frames one at a time, so a movie of any length is written in
constant memory. Output is deterministic: the same frames give the same bytes.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ParameterError


@dataclass(frozen=True)
class FormatSpec:
    """A writable format: its name, file suffix (or folder) and whether it is lossless."""

    name: str
    suffix: str  # "" for folders
    lossless: bool
    description: str

    @property
    def needs_pyav(self) -> bool:
        """Whether writing it needs PyAV (the ``video`` extra)."""
        return self.name in PYAV_FORMATS


#: formats written through PyAV (not in the default install: its wheels bundle GPL encoders)
PYAV_FORMATS = ("avi", "mjpeg", "ffv1", "mov", "h264")


def require_writer(fmt: str) -> None:
    """Raise the one-line fix when format ``fmt`` cannot be written here (PyAV missing)."""
    from ..readers import pyav_available

    if fmt in PYAV_FORMATS and not pyav_available():
        raise ParameterError(f"writing {fmt} video needs PyAV: pip install \"grainplug[video]\", or write tiff, png, "
                             "mraw, cine or seq", param="fmt")


FORMATS: dict[str, FormatSpec] = {f.name: f for f in (
    FormatSpec("tiff", ".tif", True, "multi-page TIFF stack (8/16-bit, grey or RGB)"),
    FormatSpec("png", "", True, "folder of numbered PNG images"),
    FormatSpec("tiff-folder", "", True, "folder of numbered TIFF images"),
    FormatSpec("bmp", "", True, "folder of numbered BMP images (8-bit)"),
    FormatSpec("jpeg", "", False, "folder of numbered JPEG images (8-bit, quality 95)"),
    FormatSpec("avi", ".avi", True, "AVI, uncompressed (rawvideo)"),
    FormatSpec("mjpeg", ".avi", False, "AVI, Motion-JPEG"),
    FormatSpec("ffv1", ".mkv", True, "Matroska, FFV1 lossless (8/16-bit)"),
    FormatSpec("mov", ".mov", True, "QuickTime, uncompressed (rawvideo)"),
    FormatSpec("h264", ".mp4", False, "MP4, H.264 (lossy, libx264 crf 20)"),
    FormatSpec("mraw", ".mraw", True, "Photron .mraw + .cih (grey)"),
    FormatSpec("cine", ".cine", True, "Phantom .cine (8/16-bit grey)"),
    FormatSpec("seq", ".seq", True, "NorPix StreamPix 6 .seq (8/16-bit grey or 24-bit colour), time-stamped"),
)}


def movie_path(out_dir: Path, fmt: str, stem: str = "movie") -> Path:
    """Where a movie of format ``fmt`` is written inside ``out_dir``."""
    spec = FORMATS[fmt]
    return out_dir / (f"{stem}_frames" if not spec.suffix else stem + spec.suffix)


class MovieWriter:
    """Write frames one by one to ``path`` in format ``fmt``.

    Parameters
    ----------
    path : Path
        Destination file (or folder for image formats).
    fmt : str
        One of :data:`FORMATS`.
    fps : float
        Frame rate recorded in the file where the format holds one.
    metadata : dict, optional
        JSON-able description stored where the format allows (TIFF, containers).
    n_frames : int, optional
        Frames to come, when known: a TIFF stack beyond 4 GB is then written as BigTIFF.
    """

    def __init__(self, path: Path, fmt: str, *, fps: float, metadata: dict | None = None,
                 n_frames: int | None = None) -> None:
        if fmt not in FORMATS:
            raise ParameterError(f"unknown movie format {fmt!r}; choose one of {', '.join(FORMATS)}")
        self.path, self.fmt, self.fps = Path(path), fmt, float(fps)
        self.metadata = dict(metadata or {})
        self.n_frames = n_frames
        self.count = 0
        self._impl: object | None = None
        self._shape: tuple[int, ...] | None = None
        self._dtype: np.dtype | None = None

    # -- public --------------------------------------------------------------
    def write(self, frame: np.ndarray) -> None:
        if self._shape is None:
            self._shape, self._dtype = frame.shape, frame.dtype
            self._open(frame)
        elif frame.shape != self._shape or frame.dtype != self._dtype:
            raise ValueError("all frames must share one shape and dtype")
        getattr(self, f"_write_{self.fmt.replace('-', '_')}", self._write_av)(frame)
        self.count += 1

    def close(self) -> None:
        impl = self._impl
        if impl is None:
            return
        if self.fmt == "tiff":
            impl.close()
        elif self.fmt in ("mraw",):
            impl.close()
            self._write_cih()
        elif self.fmt == "cine":
            self._finish_cine()
        elif self.fmt == "seq":
            self._finish_seq()
        elif self.fmt in ("avi", "mjpeg", "ffv1", "mov", "h264"):
            container, stream = impl
            for packet in stream.encode():
                container.mux(packet)
            container.close()
        self._impl = None

    def __enter__(self) -> MovieWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- opening -------------------------------------------------------------
    def _open(self, frame: np.ndarray) -> None:
        fmt = self.fmt
        if FORMATS[fmt].suffix == "":
            self.path.mkdir(parents=True, exist_ok=True)
            self._impl = True
            return
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if fmt == "tiff":
            import tifffile

            # classic TIFF addresses 4 GiB: larger stacks are written as BigTIFF
            big = self.n_frames is not None and self.n_frames * frame.nbytes > 4.0e9
            self._impl = tifffile.TiffWriter(str(self.path), bigtiff=big)
        elif fmt == "mraw":
            if frame.ndim != 2:
                raise ParameterError("the .mraw writer takes grey frames — render with rgb=False")
            self._impl = open(self.path, "wb")
        elif fmt == "cine":
            if frame.ndim != 2:
                raise ParameterError("the .cine writer takes grey frames — render with rgb=False")
            self._cine_frames: list[int] = []
            self._impl = open(self.path.with_suffix(".cine.part"), "wb")
        elif fmt == "seq":
            if frame.ndim == 3 and frame.dtype != np.uint8:
                raise ParameterError("the .seq writer stores colour as 8 bits per channel — use bit_depth=8")
            self._impl = open(self.path, "wb")
            self._impl.write(bytes(self.SEQ_HEADER))  # rewritten with the frame count at the end
        else:
            self._open_av(frame)

    def _open_av(self, frame: np.ndarray) -> None:
        require_writer(self.fmt)
        import av

        h, w = frame.shape[:2]
        grey = frame.ndim == 2
        deep = frame.dtype == np.uint16
        codec, pix = {
            "avi": ("rawvideo", "gray" if grey else "bgr24"),
            "mov": ("rawvideo", "rgb24"),  # QuickTime tags grey raw as a palette: store RGB
            "mjpeg": ("mjpeg", "yuvj444p"),
            "ffv1": ("ffv1", ("gray16le" if deep else "gray") if grey else ("gbrp16le" if deep else "bgr0")),
            "h264": ("libx264", "yuv420p"),
        }[self.fmt]
        if deep and self.fmt not in ("ffv1",):
            raise ParameterError(f"format {self.fmt} stores 8-bit frames only — use tiff, png or ffv1 for 16-bit")
        if self.fmt in ("avi", "mov") and deep:
            raise ParameterError("16-bit raw video is not supported — use ffv1")
        container = av.open(str(self.path), mode="w", options={"fflags": "+bitexact"})
        from fractions import Fraction

        rate = Fraction(self.fps).limit_denominator(1001)
        stream = container.add_stream(codec, rate=rate)
        stream.width, stream.height, stream.pix_fmt = w, h, pix
        stream.codec_context.flags |= av.codec.context.Flags.bitexact
        if self.fmt == "h264":
            stream.options = {"crf": "20", "preset": "veryfast", "threads": "1"}
        elif self.fmt == "mjpeg":
            stream.codec_context.qmin = stream.codec_context.qmax = 2
        elif self.fmt == "ffv1":
            stream.options = {"level": "3", "slices": "4", "threads": "1"}
        for key, value in self.metadata.items():
            container.metadata[str(key)] = str(value)
        self._impl = (container, stream)
        self._grey = grey

    # -- per format ----------------------------------------------------------
    def _frame_name(self, ext: str) -> Path:
        # deliberately not zero-padded: readers must sort naturally (frame_2 < frame_10)
        return self.path / f"frame_{self.count + 1}{ext}"

    def _write_png(self, frame: np.ndarray) -> None:
        from PIL import Image

        if frame.dtype == np.uint16 and frame.ndim == 3:
            raise ParameterError("16-bit RGB PNG is not supported — use tiff or ffv1")
        Image.fromarray(frame).save(self._frame_name(".png"), compress_level=1)

    def _write_bmp(self, frame: np.ndarray) -> None:
        from PIL import Image

        if frame.dtype != np.uint8:
            raise ParameterError("BMP stores 8-bit frames only — use tiff or png for 16-bit")
        Image.fromarray(frame).save(self._frame_name(".bmp"))

    def _write_jpeg(self, frame: np.ndarray) -> None:
        from PIL import Image

        if frame.dtype != np.uint8:
            raise ParameterError("JPEG stores 8-bit frames only — use tiff or png for 16-bit")
        Image.fromarray(frame).save(self._frame_name(".jpg"), quality=95, subsampling=0)

    def _write_tiff_folder(self, frame: np.ndarray) -> None:
        import tifffile

        tifffile.imwrite(str(self._frame_name(".tif")), frame,
                         photometric="rgb" if frame.ndim == 3 else "minisblack")

    def _write_tiff(self, frame: np.ndarray) -> None:
        meta = None
        if self.count == 0:
            meta = {"fps": self.fps, **self.metadata}
        self._impl.write(frame, contiguous=True, metadata=meta,
                         photometric="rgb" if frame.ndim == 3 else "minisblack")

    def _write_av(self, frame: np.ndarray) -> None:
        import av

        container, stream = self._impl
        if frame.ndim == 2 and self.fmt == "mov":
            frame = np.repeat(frame[..., None], 3, axis=2)
        if frame.ndim == 2:
            vf = av.VideoFrame.from_ndarray(frame, format="gray16le" if frame.dtype == np.uint16 else "gray")
        else:
            vf = av.VideoFrame.from_ndarray(frame, format="rgb48le" if frame.dtype == np.uint16 else "rgb24")
        vf.pts = self.count
        for packet in stream.encode(vf):
            container.mux(packet)

    def _write_mraw(self, frame: np.ndarray) -> None:
        self._impl.write(np.ascontiguousarray(frame).tobytes())

    def _write_cih(self) -> None:
        # same header layout as pyMRAW.save_mraw writes
        bits = 8 * self._dtype.itemsize
        info = {
            "Record Rate(fps)": f"{round(self.fps):d}",
            "Shutter Speed(s)": f"{1 / self.fps:.6f}",
            "Total Frame": f"{self.count:d}",
            "Original Total Frame": f"{self.count:d}",
            "Start Frame": "0",
            "Image Width": f"{self._shape[1]:d}",
            "Image Height": f"{self._shape[0]:d}",
            "Color Type": "Mono",
            "Color Bit": bits,
            "File Format": "MRaw",
            "EffectiveBit Depth": bits if bits < 16 else 16,
            "Comment Text": "grainplug synthetic movie",
            "EffectiveBit Side": "Lower",
        }
        with open(self.path.with_suffix(".cih"), "w") as fh:
            fh.write("#Camera Information Header\n")
            for key, value in info.items():
                fh.write(f"{key} : {value}\n")

    #: StreamPix 6 (.seq version 5): header size, and each frame padded to whole 512-byte sectors
    SEQ_HEADER = 8192

    def _seq_sizes(self) -> tuple[int, int]:
        image_bytes = int(np.prod(self._shape)) * self._dtype.itemsize
        return image_bytes, -(-(image_bytes + 8) // 512) * 512

    def _write_seq(self, frame: np.ndarray) -> None:
        """Pixels (colour as B, G, R), then the time stamp (u32 s, u16 ms, u16 us), then padding."""
        import struct

        image_bytes, true_size = self._seq_sizes()
        t_us = round(self.count * 1e6 / self.fps)  # from an arbitrary start: 2026-01-01 00:00:00
        block = bytearray(true_size)
        block[:image_bytes] = np.ascontiguousarray(frame[..., ::-1] if frame.ndim == 3 else frame).astype(
            frame.dtype.newbyteorder("<")).tobytes()
        struct.pack_into("<IHH", block, image_bytes, 1_767_225_600 + t_us // 1_000_000, t_us % 1_000_000 // 1000,
                         t_us % 1000)
        self._impl.write(bytes(block))

    def _finish_seq(self) -> None:
        """The header, now that the frame count is known (NorPix's documented offsets)."""
        import struct

        image_bytes, true_size = self._seq_sizes()
        h, w = self._shape[:2]
        colour = len(self._shape) == 3
        bits = 8 * self._dtype.itemsize * (3 if colour else 1)
        head = bytearray(self.SEQ_HEADER)
        struct.pack_into("<I24sii", head, 0, 0xFEED, "Norpix seq".encode("utf-16-le")[:24], 5, self.SEQ_HEADER)
        struct.pack_into("<6I", head, 548, w, h, bits, 8 * self._dtype.itemsize, image_bytes, 200 if colour else 100)
        struct.pack_into("<IIId", head, 572, self.count, 0, true_size, self.fps)
        self._impl.seek(0)
        self._impl.write(bytes(head))
        self._impl.close()

    def _write_cine(self, frame: np.ndarray) -> None:
        data = np.flipud(frame.astype("<u2" if frame.dtype.itemsize > 1 else "u1")).tobytes()  # rows bottom-up
        self._cine_frames.append(len(data))
        self._impl.write(data)

    def _finish_cine(self) -> None:
        """Assemble an 8- or 16-bit grey .cine (the frames' depth) following Vision Research's published layout.

        CINEFILEHEADER (44 bytes), BITMAPINFOHEADER (40), a SETUP block of the current
        size (10412 bytes: marker ``ST``, its length, ``FrameRate``, ``RealBPP``, the rest
        zero), the image offsets, then each image: annotation (its size, 8, and the
        image size) and the rows bottom-up.
        """
        import struct

        self._impl.close()
        part = self.path.with_suffix(".cine.part")
        h, w = self._shape
        n = self.count
        bits = 8 if self._dtype.itemsize == 1 else 16
        setup = bytearray(10412)
        struct.pack_into("<H", setup, 0, min(int(round(self.fps)), 65535))  # FrameRate16
        struct.pack_into("<2sH", setup, 140, b"ST", len(setup))
        struct.pack_into("<I", setup, 768, int(round(self.fps)))  # FrameRate
        struct.pack_into("<I", setup, 896, bits)  # RealBPP
        struct.pack_into("<d", setup, 10400, float(self.fps))  # dFrameRate
        off_bih, off_setup = 44, 84
        off_offsets = off_setup + len(setup)
        first_image = off_offsets + 8 * n
        header = struct.pack("<2sHHHiIiIIIIII", b"CI", 44, 0, 1, 0, n, 0, n, off_bih, off_setup, off_offsets, 0, 0)
        bih = struct.pack("<IiiHHIIiiII", 40, w, h, 1, bits, 0, w * h * bits // 8, 0, 0, 0, 0)
        offsets, pos = [], first_image
        for size in self._cine_frames:
            offsets.append(pos)
            pos += 8 + size
        with open(self.path, "wb") as out, open(part, "rb") as src:
            out.write(header)
            out.write(bih)
            out.write(bytes(setup))
            out.write(np.asarray(offsets, dtype="<i8").tobytes())
            for size in self._cine_frames:
                out.write(np.asarray([8, size], dtype="<u4").tobytes())  # annotation size, image size
                out.write(src.read(size))
        os.remove(part)
