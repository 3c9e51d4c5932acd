"""Photron ``.mraw`` movies with their ``.cih`` (text) or ``.cihx`` (XML) header.

The ``.mraw`` holds the frames one after the other, with no header: 8-bit, 16-bit
little-endian, or 12-bit packed 2 pixels in 3 bytes (most significant bits first).
Frames are memory-mapped a block at a time and unpacked there, so a 12-bit movie
streams in constant memory like every other format.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..errors import MovieError
from ..warning_codes import coded
from .base import MovieInfo, choose_fps
from .raw import RawFramesMovie, RawLayout, complete_frames

#: .cihx XML elements read: key -> path below <cih>
CIHX_FIELDS = {
    "Record Rate(fps)": "recordInfo/recordRate",
    "Total Frame": "frameInfo/totalFrame",
    "Original Total Frame": "frameInfo/recordedFrame",
    "Start Frame": "frameInfo/startFrame",
    "Save Step": "frameInfo/skipFrame",
    "Image Width": "imageDataInfo/resolution/width",
    "Image Height": "imageDataInfo/resolution/height",
    "Color Type": "imageDataInfo/colorInfo/type",
    "Color Bit": "imageDataInfo/colorInfo/bit",
    "EffectiveBit Depth": "imageDataInfo/effectiveBit/depth",
    "EffectiveBit Side": "imageDataInfo/effectiveBit/side",
    "File Format": "imageFileInfo/fileFormat",
    "Camera Type": "deviceInfo/deviceName",
    "Date": "fileInfo/date",
    "Time": "fileInfo/time",
}


def read_cih(path: Path) -> dict[str, str]:
    """The header's ``key : value`` pairs (``.cih``), or the same keys from a ``.cihx``.

    Raises
    ------
    MovieError
        When the header cannot be parsed.
    """
    text = path.read_bytes().decode("utf-8", errors="replace")
    if path.suffix.lower() == ".cihx":
        found = re.search(r"<cih>.*</cih>", text, flags=re.S)
        if not found:
            raise MovieError(f"{path}: no <cih> block in this .cihx header — the file is damaged")
        try:
            root = ET.fromstring(found.group(0))
        except ET.ParseError as exc:
            raise MovieError(f"{path}: the .cihx header is not valid XML ({exc}) — the file is damaged") from None
        out = {}
        for key, where in CIHX_FIELDS.items():
            node = root.find(where)
            if node is not None and node.text is not None:
                out[key] = node.text.strip()
        return out
    out = {}
    for line in text.splitlines():
        key, sep, value = line.partition(" : ")
        if sep:
            out[key.strip()] = value.strip()
    return out


def _int(meta: dict[str, str], key: str, path: Path) -> int:
    try:
        return int(float(meta[key]))
    except (KeyError, ValueError):
        raise MovieError(f"{path}: the header has no valid '{key}' — the file is damaged or not a Photron header") \
            from None


def _optional_int(meta: dict[str, str], key: str, default: int) -> int:
    """An informative header field, or ``default`` where it is missing or garbled."""
    try:
        return int(float(meta[key]))
    except (KeyError, ValueError, OverflowError):
        return default


def photron_saved_rate(meta: dict[str, str]) -> tuple[float | None, str, float | None]:
    """Frame rate of the *saved* frames, how it was derived, and the recording rate.

    The camera records at ``Record Rate`` but may save one frame in ``Save Step``
    (``.cih``) or ``skipFrame`` (``.cihx``): the saved frames are then
    ``record rate / step`` apart.
    """
    try:
        rate = float(meta.get("Record Rate(fps)", "0"))
    except ValueError:
        rate = 0.0
    if not rate > 0:
        return None, "", None
    try:
        step = int(float(meta.get("Save Step", "1")))
    except ValueError:
        step = 1
    if step <= 1:
        return rate, f"record rate {rate:g} fps", None
    return rate / step, f"record rate {rate:g} fps / save step {step}", rate


def header_and_data(path: Path) -> tuple[Path, Path]:
    """The ``.cih``/``.cihx`` header and the ``.mraw`` data of a movie given by either."""
    if path.suffix.lower() in (".cih", ".cihx"):
        cih = path
        for ext in (".mraw", ".MRAW", ".Mraw"):
            if cih.with_suffix(ext).exists():
                return cih, cih.with_suffix(ext)
        raise MovieError(f"{cih}: its image data {cih.with_suffix('.mraw').name} is not beside it — copy the .mraw "
                         "file along with its header")
    for ext in (".cihx", ".cih", ".CIHX", ".CIH"):
        if path.with_suffix(ext).exists():
            return path.with_suffix(ext), path
    raise MovieError(f"{path}: no .cih/.cihx header beside the .mraw file — copy it along with the movie")


def _colour_type(meta: dict[str, str]) -> str:
    """``"grey"``, or what kind of colour a Photron header describes.

    ``Color Type`` is ``Mono``, ``Color``, or ``Raw`` (sensor data before the camera's
    image processing); for ``Raw`` the model name tells a monochrome sensor
    (``...-M-...``, e.g. "FASTCAM Nova S16 type 1100K-M-64GB") from a colour one
    (``...-C-...``), whose raw data is a Bayer mosaic.
    """
    kind = meta.get("Color Type", "Mono").strip().lower()
    if kind == "mono":
        return "grey"
    model = meta.get("Camera Type", "")
    if kind == "raw" and re.search(r"-M(-|\b)", model):
        return "grey"
    if kind == "raw":
        sensor = "a colour" if re.search(r"-C(-|\b)", model) else "an unknown"
        return f"raw sensor data of {sensor} sensor"
    return meta.get("Color Type", "colour")


class MrawMovie(RawFramesMovie):
    """A Photron ``.mraw`` movie, mono 8-, 12- (packed) or 16-bit.

    Parameters
    ----------
    path : Path
        The ``.mraw`` file or its ``.cih``/``.cihx`` header.
    fps : float, optional
        Frame rate to use instead of the file's.
    allow_truncated : bool
        Read the complete frames of a ``.mraw`` that ends early, with a warning.

    Notes
    -----
    The bit depth reported is the number of significant bits in the values handed
    out: ``EffectiveBit Depth`` when the effective bits are the low ones of a wider
    sample (``Side: Lower``), else the stored sample size (an 8-bit file holding the
    upper 8 of 12 effective bits has 8). Colour files (RGB, or raw data of a colour
    sensor) are refused: no public sample documents their layout.
    """

    def __init__(self, path: Path, *, fps: float | None = None, allow_truncated: bool = False) -> None:
        cih, data = header_and_data(path)
        meta = read_cih(cih)
        fmt = meta.get("File Format", "MRaw")
        if fmt.lower() != "mraw":
            raise MovieError(f"{cih}: the frames were saved as {fmt}, not MRaw — open the saved images instead")
        colour = _colour_type(meta)
        if colour != "grey":
            raise MovieError(f"{cih}: colour Photron files ({colour}) are not supported — save the movie as "
                             "monochrome MRaw, or export RGB TIFF frames")
        width, height = _int(meta, "Image Width", cih), _int(meta, "Image Height", cih)
        n_frames, bits = _int(meta, "Total Frame", cih), _int(meta, "Color Bit", cih)
        if bits not in (8, 12, 16):
            raise MovieError(f"{cih}: {bits}-bit samples are not an MRaw layout grainplug reads (8, 12, 16)")
        if n_frames <= 0 or width <= 0 or height <= 0:
            raise MovieError(f"{cih}: the header describes no frames — the file is damaged")
        encoding = {8: "u8", 12: "p12", 16: "u16le"}[bits]
        frame_bytes = width * height * bits // 8
        size = data.stat().st_size
        listed = min(n_frames, size // frame_bytes + 1)  # a header's count is not trusted with memory
        layout = RawLayout(offsets=np.arange(listed, dtype=np.int64) * frame_bytes, shape=(height, width),
                           encoding=encoding)
        n, truncated = complete_frames(data, layout, allow_truncated=allow_truncated, what=".cih",
                                       described=n_frames)
        warnings_ = [truncated] if truncated else []
        if size > n_frames * frame_bytes:
            warnings_.append(coded("movie.extra_bytes", f"{data.name} holds {size - n_frames * frame_bytes} bytes "
                                   f"more than the {n_frames} frames its header describes — is {cih.name} the header "
                                   "of this file?"))
        effective = _optional_int(meta, "EffectiveBit Depth", bits)
        side = meta.get("EffectiveBit Side", "Lower")
        depth = min(effective, bits) if side.lower() == "lower" else bits
        rate, note, record = photron_saved_rate(meta)
        use_fps, source, fps_doubts = choose_fps(fps, rate)
        warnings_.extend(fps_doubts)
        details: dict[str, object] = {
            "header": cih.name,
            "layout": f"{bits}-bit" + (" packed" if bits == 12 else ""),
            "effective_bits": effective,
            "effective_side": side,
            "start_frame": _optional_int(meta, "Start Frame", 0),
            "recorded_frames": _optional_int(meta, "Original Total Frame", n_frames),
            "recorded_on": " ".join(meta[k] for k in ("Date", "Time") if meta.get(k)) or None,
        }
        info = MovieInfo(
            path=str(path), format=f"mraw:{details['layout']}", width=width, height=height, n_frames=n,
            fps=use_fps, channels=1, bit_depth=depth, dtype="uint8" if bits == 8 else "uint16", fps_source=source,
            fps_note="" if fps else note, record_fps=record, colour="grey",
            camera=f"Photron {meta['Camera Type']}" if meta.get("Camera Type") else "Photron",
            warnings=tuple(warnings_), details=details,
        )
        super().__init__(data, info, layout)
