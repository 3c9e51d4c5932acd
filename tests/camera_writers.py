"""Camera files written by the tests, following the makers' published layouts.

Written independently of grainplug's readers: pixels are packed through bit strings
(``np.unpackbits``/``np.packbits``), not the readers' shifts, and every header field is
placed by its documented offset. Used for what no public sample covers: P12L and 8-bit
cines, flips, RGB and raw Bayer colour, 16-bit and colour .seq, damaged files.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np


def pack_bits(values: np.ndarray, bits: int) -> bytes:
    """Samples as a big-endian bit string of ``bits`` per sample (most significant bit first)."""
    v = np.asarray(values, dtype=">u2").ravel()
    as_bits = np.unpackbits(v.view(np.uint8)).reshape(-1, 16)[:, 16 - bits:]
    return np.packbits(as_bits.ravel()).tobytes()


def mosaic(rgb: np.ndarray, pattern: str) -> np.ndarray:
    """The raw Bayer image a sensor with ``pattern`` (top-left 2x2 cell, row by row) records of ``rgb``."""
    out = np.empty(rgb.shape[:2], rgb.dtype)
    for k, colour in enumerate(pattern):
        dy, dx = divmod(k, 2)
        out[dy::2, dx::2] = rgb[dy::2, dx::2, "RGB".index(colour)]
    return out


# -- Phantom .cine --------------------------------------------------------------------
def write_cine(path: Path, frames: np.ndarray, *, fps: float = 1000.0, layout: str = "16", real_bpp: int = 16,
               flip_v: bool = False, flip_h: bool = False, bayer_cfa: int | None = None, decimation: float = 1.0,
               stamps_s: np.ndarray | None = None, setup_length: int = 10412) -> Path:
    """A .cine of ``frames`` (as they should be read back: top-down, unflipped).

    ``layout``: ``"8"``, ``"16"``, ``"p10"``, ``"p12l"`` (grey or raw Bayer), ``"rgb24"``, ``"rgb48"``.
    The stored rows are put in the order the layout and ``flip_v`` call for, columns
    mirrored when ``flip_h``; ``bayer_cfa`` (3 or 4) writes ``frames`` (mosaics) as
    uninterpolated colour.
    """
    frames = np.asarray(frames)
    n, h, w = frames.shape[:3]
    packed = layout in ("p10", "p12l")
    bottom_up = (not packed) != flip_v
    images = []
    for f in frames:
        f = f[::-1] if bottom_up else f
        f = f[:, ::-1] if flip_h else f
        if layout == "8":
            images.append(f.astype(np.uint8).tobytes())
        elif layout == "16":
            images.append(f.astype("<u2").tobytes())
        elif layout == "p10":
            images.append(pack_bits(f, 10))
        elif layout == "p12l":
            images.append(pack_bits(f, 12))
        elif layout == "rgb24":
            images.append(f[..., ::-1].astype(np.uint8).tobytes())  # stored B, G, R
        else:
            images.append(f[..., ::-1].astype("<u2").tobytes())
    bits = {"8": 8, "16": 16, "p10": 16, "p12l": 16, "rgb24": 24, "rgb48": 48}[layout]
    bi_comp = {"p10": 256, "p12l": 1024}.get(layout, 0)
    setup = bytearray(setup_length)
    struct.pack_into("<H", setup, 0, min(int(fps * decimation), 65535))
    struct.pack_into("<2sH", setup, 140, b"ST", setup_length)
    struct.pack_into("<I", setup, 743, 4242)  # Serial
    struct.pack_into("<ii", setup, 756, int(flip_h), int(flip_v))
    if setup_length > 772:
        struct.pack_into("<I", setup, 768, int(round(fps * decimation)))
    if setup_length > 812:
        struct.pack_into("<I", setup, 808, bayer_cfa or 0)
    if setup_length > 900:
        struct.pack_into("<I", setup, 896, real_bpp)
    if setup_length >= 10408:
        struct.pack_into("<f", setup, 10388, decimation)
        struct.pack_into("<d", setup, 10400, fps * decimation)
    tags = b""
    if stamps_s is not None:
        t = np.asarray(stamps_s, float)
        seconds = np.floor(t)
        pairs = np.stack([np.round((t - seconds) * 2**32).astype(np.uint64), seconds.astype(np.uint64)], 1)
        payload = pairs.astype("<u4").tobytes()
        tags = struct.pack("<IHH", 8 + len(payload), 1002, 0) + payload
    off_setup = 84
    off_offsets = off_setup + setup_length + len(tags)
    pos = off_offsets + 8 * n
    offsets = []
    for img in images:
        offsets.append(pos)
        pos += 8 + len(img)
    header = struct.pack("<2sHHHiIiIIIIII", b"CI", 44, 2 if bayer_cfa else 0, 1, -5, n, -5, n, 44, off_setup,
                         off_offsets, 0, 1_600_000_000)
    bih = struct.pack("<IiiHHIIiiII", 40, w, h, 1, bits, bi_comp, len(images[0]), 0, 0, 0, 0)
    with open(path, "wb") as fh:
        fh.write(header + bih + bytes(setup) + tags + np.asarray(offsets, "<i8").tobytes())
        for img in images:
            fh.write(struct.pack("<II", 8, len(img)) + img)
    return path


# -- Photron .mraw ----------------------------------------------------------------------
def write_mraw(path: Path, frames: np.ndarray, *, bits: int = 16, fps: float = 5000.0, step: int = 1,
               cihx: bool = False, colour: str = "Mono", model: str = "FASTCAM test type 100K-M-8GB") -> Path:
    """A .mraw of ``frames`` with its .cih (text) or .cihx (XML) header; returns the header."""
    frames = np.asarray(frames)
    n, h, w = frames.shape
    if bits == 12:
        data = pack_bits(frames, 12)
    else:
        data = frames.astype(np.uint8 if bits == 8 else "<u2").tobytes()
    path.with_suffix(".mraw").write_bytes(data)
    if cihx:
        xml = (f"<cih><fileInfo><date>2026/1/2</date><time>3:04</time></fileInfo>"
               f"<imageFileInfo><fileFormat>Mraw</fileFormat></imageFileInfo>"
               f"<imageDataInfo><resolution><width>{w}</width><height>{h}</height></resolution>"
               f"<colorInfo><type>{colour}</type><bit>{bits}</bit></colorInfo>"
               f"<effectiveBit><depth>{bits}</depth><side>Lower</side></effectiveBit></imageDataInfo>"
               f"<frameInfo><recordedFrame>{n * step}</recordedFrame><totalFrame>{n}</totalFrame>"
               f"<startFrame>0</startFrame><skipFrame>{step}</skipFrame></frameInfo>"
               f"<recordInfo><recordRate>{fps * step:g}</recordRate></recordInfo>"
               f"<deviceInfo><deviceName>{model}</deviceName></deviceInfo></cih>")
        header = path.with_suffix(".cihx")
        header.write_bytes(b"!!! This file can not be edited. !!!" + b"\0" * 20 + b"\n" + xml.encode())
        return header
    lines = ["#Camera Information Header", f"Camera Type : {model}", f"Record Rate(fps) : {fps * step:g}",
             f"Total Frame : {n}", f"Save Step : {step}", f"Image Width : {w}", f"Image Height : {h}",
             f"Color Type : {colour}", f"Color Bit : {bits}", "File Format : MRaw",
             f"EffectiveBit Depth : {bits}", "EffectiveBit Side : Lower", ""]
    header = path.with_suffix(".cih")
    header.write_text("\n".join(lines))
    return header


# -- NorPix .seq --------------------------------------------------------------------------
def write_seq(path: Path, frames: np.ndarray, *, stamps_s: np.ndarray, suggested_fps: float = 0.0,
              version: int = 5, image_format: int = 100) -> Path:
    """A StreamPix .seq (version 5 = StreamPix 6: 8192-byte header, u32 s + u16 ms + u16 us stamps).

    ``image_format`` 100 (grey, 8- or 16-bit frames), 200 (B-G-R) or 400 (R-G-B) for RGB frames.
    """
    frames = np.asarray(frames)
    n, h, w = frames.shape[:3]
    bits = 8 * frames.dtype.itemsize * (3 if frames.ndim == 4 else 1)
    header_size = 8192 if version >= 5 else 1024
    stored = frames[..., ::-1] if image_format == 200 else frames
    image_bytes = stored[0].astype(stored.dtype.newbyteorder("<")).nbytes
    true_size = -(-(image_bytes + 8) // 512) * 512
    head = bytearray(header_size)
    struct.pack_into("<I24sii", head, 0, 0xFEED, "Norpix seq".encode("utf-16-le")[:24], version, header_size)
    struct.pack_into("<6I", head, 548, w, h, bits, bits // (3 if frames.ndim == 4 else 1), image_bytes,
                     image_format)
    struct.pack_into("<IIId", head, 572, n, 0, true_size, suggested_fps)
    with open(path, "wb") as fh:
        fh.write(bytes(head))
        for f, t in zip(stored, stamps_s, strict=True):
            seconds = int(np.floor(t))
            rest_us = int(round((t - seconds) * 1e6))
            block = bytearray(true_size)
            pixels = f.astype(f.dtype.newbyteorder("<")).tobytes()
            block[: len(pixels)] = pixels
            struct.pack_into("<IHH", block, image_bytes, seconds, rest_us // 1000, rest_us % 1000)
            fh.write(bytes(block))
    return path
