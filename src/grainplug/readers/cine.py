"""Phantom ``.cine`` files (Vision Research), decoded here from the published layout.

Layout, little-endian::

    CINEFILEHEADER (44 bytes) | BITMAPINFOHEADER (40) | SETUP (its Length) | tagged blocks
    | int64 offset of each image
    | per image: annotation (its size first, u32; the last u32 is the image's size) | pixels

Pixels are handed out as stored (unpacked to integers, never rescaled): the black and
white levels and the display settings of SETUP (gain, gamma, tone curve) are kept as
metadata only. The only transforms are those the layout requires: unpacking packed
pixels, putting rows top-down, and the flips the camera was set to (``bFlipH``,
``bFlipV``), so that frames look as the maker's viewer shows them.
"""

from __future__ import annotations

import datetime
import logging
import struct
from pathlib import Path

import numpy as np

from ..errors import MovieError
from ..warning_codes import code_of, coded
from .base import MovieInfo, choose_fps
from .raw import RawFramesMovie, RawLayout, complete_frames

log = logging.getLogger(__name__)

#: BITMAPINFOHEADER.biCompression: plain, packed 10-bit (P10), packed 12-bit (P12L)
BI_RGB, BI_PACKED, BI_PACKED_12L = 0, 256, 1024
#: CINEFILEHEADER.Compression: interpolated (grey or RGB), JPEG, raw Bayer ("uninterpolated")
CC_RGB, CC_JPEG, CC_UNINT = 0, 1, 2
#: SETUP.CFA (low 24 bits): grey sensor, and the Bayer layouts whose pattern is fixed
CFA_NONE, CFA_VRI, CFA_VRIV6, CFA_BAYER, CFA_BAYERFLIP = 0, 1, 2, 3, 4
#: Bayer pattern of each fixed layout, top-left cell of the image as displayed
CFA_PATTERNS = {CFA_BAYER: "GBRG", CFA_BAYERFLIP: "RGGB"}
#: tagged block holding one TIME64 time stamp per saved image
TAG_TIME_ONLY = 1002

#: SETUP fields read here: name -> (offset from the start of SETUP, struct format). A field
#: is read only when it lies within the block's own ``Length`` (old files have shorter blocks).
SETUP_FIELDS = {
    "FrameRate16": (0, "<H"),
    "Mark": (140, "2s"),
    "Length": (142, "<H"),
    "Serial": (743, "<I"),
    "bFlipH": (756, "<i"),
    "bFlipV": (760, "<i"),
    "FrameRate": (768, "<I"),
    "CameraVersion": (792, "<I"),
    "SoftwareVersion": (800, "<I"),
    "CFA": (808, "<I"),
    "RealBPP": (896, "<I"),
    "BlackLevel": (5732, "<i"),
    "WhiteLevel": (5736, "<i"),
    "fDecimation": (10388, "<f"),  # frames saved: one in fDecimation of those recorded
    "dFrameRate": (10400, "<d"),  # the recording rate, exactly
}


def parse_setup(raw: bytes) -> dict[str, object]:
    """The known SETUP fields that lie within the block (see :data:`SETUP_FIELDS`)."""
    if len(raw) < 144 or raw[140:142] != b"ST":
        return {"FrameRate16": struct.unpack_from("<H", raw, 0)[0]} if len(raw) >= 2 else {}
    length = min(struct.unpack_from("<H", raw, 142)[0], len(raw))
    out: dict[str, object] = {}
    for name, (off, fmt) in SETUP_FIELDS.items():
        if off + struct.calcsize(fmt) <= length:
            out[name] = struct.unpack_from(fmt, raw, off)[0]
    return out


def time64_s(raw: np.ndarray) -> np.ndarray:
    """Seconds from the first of TIME64 values (u32 fraction of a second, then u32 seconds).

    Whole seconds are subtracted as integers first: a float of seconds since 1970
    resolves only 2^-22 s, a quarter of the interval at a million frames per second.
    """
    pairs = raw.reshape(-1, 2).astype(np.int64)
    return (pairs[:, 1] - pairs[0, 1]).astype(np.float64) + pairs[:, 0] / 2.0**32


def stamp_rate(stamps_s: np.ndarray) -> tuple[float | None, float, list[int]]:
    """Frame rate of time stamps, their jitter, and the frames whose stamp is off.

    The rate is the mean interval over the intervals within 25 % of the median one
    (time stamps of old cameras are quantised to about a microsecond, a few per cent
    of a short interval); a frame whose interval from the previous frame is further
    off is listed as having a bad stamp.

    Returns
    -------
    fps : float or None
        None when fewer than two consistent intervals exist.
    jitter : float
        Relative standard deviation of the consistent intervals.
    bad : list of int
        Indices of frames with a doubtful time stamp.
    """
    if len(stamps_s) < 3:
        return None, 0.0, []
    steps = np.diff(stamps_s)
    median = float(np.median(steps))
    if not median > 0:
        return None, 0.0, []
    good = np.abs(steps - median) <= 0.25 * median
    if good.sum() < 2:
        return None, 0.0, []
    mean = float(steps[good].mean())
    jitter = float(steps[good].std() / mean)
    return 1.0 / mean, jitter, [int(k) + 1 for k in np.flatnonzero(~good)]


class CineMovie(RawFramesMovie):
    """A Phantom ``.cine`` movie: grey 8/16-bit, packed 10- and 12-bit, RGB, raw Bayer.

    Parameters
    ----------
    path : Path
        The ``.cine`` file.
    fps : float, optional
        Frame rate to use instead of the file's.
    allow_truncated : bool
        Read the complete frames of a file that ends early (with a warning) instead of
        refusing it.

    Notes
    -----
    Frame rate of the saved frames: the recording rate (``dFrameRate``, else
    ``FrameRate``, else the 16-bit field of old files) divided by the save decimation
    ``fDecimation`` where the file has it; checked against the per-image time stamps
    (tagged block 1002): where they disagree by more than 1 % the time stamps' rate is
    used, with a warning. Row order: plain images are stored bottom-up and packed ones
    top-down; ``bFlipV`` inverts that and ``bFlipH`` mirrors the columns, as the maker's
    viewer and FFmpeg's demuxer do. Raw Bayer files (``Compression = 2``) are
    demosaiced with the pattern of ``CFA`` (read in the image as displayed); the
    layouts whose pattern depends on the sensor (``CFA`` 1 and 2) are refused. JPEG
    cines are refused. P10 pixels are the camera's 10-bit codes as stored (the maker's
    software maps them to 12-bit linear values through a table that is not published).
    """

    def __init__(self, path: Path, *, fps: float | None = None, allow_truncated: bool = False) -> None:
        try:
            info, layout = _describe(path, fps=fps, allow_truncated=allow_truncated)
        except (struct.error, ValueError, OverflowError) as exc:
            raise MovieError(f"{path}: the .cine header cannot be read ({exc}) — the file is truncated or not a "
                             "Phantom .cine") from None
        super().__init__(path, info, layout)


def _describe(path: Path, *, fps: float | None, allow_truncated: bool) -> tuple[MovieInfo, RawLayout]:
    size = path.stat().st_size
    with open(path, "rb") as fh:
        head = fh.read(84)
        if len(head) < 44 or head[:2] != b"CI":
            raise MovieError(f"{path} is not a Phantom .cine file (it does not start with 'CI') — check the file")
        (_, _, compression, _, first_movie, total, first_no, count, off_bih, off_setup, off_offsets, trig_frac,
         trig_s) = struct.unpack_from("<2sHHHiIiIIIIII", head, 0)
        fh.seek(off_bih)
        bih = fh.read(40)
        (_, width, height, _, bits, bi_comp, image_size, *_rest) = struct.unpack("<IiiHHIIiiII", bih)
        fh.seek(min(off_setup, size))
        setup_raw = fh.read(max(0, min(off_offsets, size) - off_setup))
        setup = parse_setup(setup_raw)
        if off_offsets + 8 * count > size:
            raise MovieError(f"{path} is truncated: it ends inside its table of image offsets — copy the file again")
        fh.seek(off_offsets)
        image_offsets = np.frombuffer(fh.read(8 * count), "<i8").astype(np.int64)
        if count and not 0 < image_offsets[0] < size:
            raise MovieError(f"{path}: its first image lies outside the file (offset {image_offsets[0]}) — the file "
                             "is corrupt")
        annotation = 0
        if count:
            fh.seek(int(image_offsets[0]))
            ann = fh.read(4)
            if len(ann) == 4:
                annotation = struct.unpack("<I", ann)[0]
        stamps = _tagged_stamps(setup_raw, setup, count)
    height = abs(height)
    if count <= 0 or width <= 0 or height <= 0:
        raise MovieError(f"{path}: the .cine header describes no frames ({count} of {width} x {height}) — the file "
                         "is corrupt")
    if compression == CC_JPEG:
        raise MovieError(f"{path} is a JPEG-compressed .cine — export it uncompressed from the camera software")
    if not 8 <= annotation < 1 << 20:
        raise MovieError(f"{path}: the first image's annotation size ({annotation}) is impossible — the file is "
                         "corrupt")
    cfa = int(setup.get("CFA", 0)) & 0xFFFFFF
    flip_v, flip_h = bool(setup.get("bFlipV", 0)), bool(setup.get("bFlipH", 0))
    packed = bi_comp in (BI_PACKED, BI_PACKED_12L)
    if bi_comp == BI_PACKED:
        encoding, stored_bits = "p10", 10
    elif bi_comp == BI_PACKED_12L:
        encoding, stored_bits = "p12", 12
    elif bi_comp == BI_RGB and bits in (8, 24):
        encoding, stored_bits = "u8", 8
    elif bi_comp == BI_RGB and bits in (16, 48):
        encoding, stored_bits = "u16le", 16
    else:
        raise MovieError(f"{path}: pixels of {bits} bits with compression {bi_comp} are not a documented .cine "
                         "layout — export the movie as an uncompressed .cine or TIFF")
    rgb = bits in (24, 48) and not packed
    bayer = None
    if compression == CC_UNINT:
        if cfa not in CFA_PATTERNS:
            raise MovieError(f"{path}: raw colour (Bayer) data with sensor layout CFA={cfa}, whose pattern depends on "
                             "the sensor — export the movie as colour (interpolated) from the camera software")
        bayer = CFA_PATTERNS[cfa]
    shape = (height, width, 3) if rgb else (height, width)
    # the annotation's last 4 bytes hold the image size; the pixels follow it
    layout = RawLayout(offsets=image_offsets + annotation, shape=shape, encoding=encoding,
                       bottom_up=(not packed) != flip_v, mirrored=flip_h, bgr=rgb, bayer=bayer)
    if image_size and image_size < layout.nbytes:
        raise MovieError(f"{path}: each image holds {image_size} bytes, fewer than {width} x {height} pixels of this "
                         "layout need — the file is corrupt")
    n, truncated = complete_frames(path, layout, allow_truncated=allow_truncated, what=".cine")
    real_bpp = int(setup.get("RealBPP", 0) or 0)
    depth = real_bpp if stored_bits == 16 and 8 < real_bpp <= 16 else stored_bits  # RealBPP: bits the sensor gave
    rate, rate_note, record, warnings_, stamp_facts = _frame_rate(setup, stamps, n)
    if fps is not None:  # the user chose the rate: the stamps-or-header choice is not made (choose_fps says so)
        warnings_ = [w for w in warnings_ if code_of(w) != "movie.fps_stamps"]
    if truncated:
        warnings_.insert(0, truncated)
    use_fps, source, fps_doubts = choose_fps(fps, rate)
    warnings_.extend(fps_doubts)
    colour = f"bayer {bayer}, demosaiced" if bayer else ("rgb" if rgb else "grey")
    serial = setup.get("Serial")
    camera = f"Phantom (camera version {setup.get('CameraVersion', '?')}, serial {serial})" if serial else "Phantom"
    # levels of 0/0 are unset (old software, files written by other tools)
    levels = {k: setup[k] for k in ("BlackLevel", "WhiteLevel") if k in setup} if setup.get("WhiteLevel") else {}
    details: dict[str, object] = {
        "layout": {"p10": "packed 10-bit (P10)", "p12": "packed 12-bit (P12L)"}.get(encoding, f"{bits}-bit"),
        "first_image_number": first_no,
        "first_movie_image": first_movie,
        "total_image_count": total,
        "trigger_time_utc": _utc(trig_s, trig_frac),
        "flip_vertical": flip_v,
        "flip_horizontal": flip_h,
        "software_version": setup.get("SoftwareVersion"),
        **({"levels": levels} if levels else {}),
        **stamp_facts,
    }
    if levels and not (0 <= levels.get("BlackLevel", 0) < levels.get("WhiteLevel", 1 << depth) <= (1 << depth)):
        warnings_.append(coded("movie.header_levels", f"the black/white levels {levels} are out of the {depth}-bit "
                               "range — ignored (pixels are used as stored)"))
    info = MovieInfo(
        path=str(path), format=f"cine:{details['layout']}", width=width, height=height, n_frames=n, fps=use_fps,
        channels=3 if (rgb or bayer) else 1, bit_depth=depth, dtype="uint8" if stored_bits == 8 else "uint16",
        fps_source=source, fps_note="" if fps else rate_note, record_fps=record, colour=colour, camera=camera,
        warnings=tuple(warnings_), details=details,
    )
    return info, layout


def _utc(seconds: int, fraction: int) -> str | None:
    if not seconds:
        return None
    when = datetime.datetime.fromtimestamp(seconds + fraction / 2.0**32, tz=datetime.UTC)
    return when.isoformat(timespec="microseconds")


def _tagged_stamps(setup_raw: bytes, setup: dict[str, object], count: int) -> np.ndarray | None:
    """Per-image time stamps (s) from tagged block 1002, if the file has one for every image."""
    length = int(setup.get("Length", 0) or 0)
    pos = length
    while length and pos + 8 <= len(setup_raw):
        block_size, kind = struct.unpack_from("<IH", setup_raw, pos)
        if block_size < 8 or pos + block_size > len(setup_raw):
            break
        if kind == TAG_TIME_ONLY and block_size - 8 >= 8 * count:
            raw = np.frombuffer(setup_raw, "<u4", count=2 * count, offset=pos + 8)
            return time64_s(raw)
        pos += block_size
    return None


def _frame_rate(setup: dict[str, object], stamps: np.ndarray | None,
                n: int) -> tuple[float | None, str, float | None, list[str], dict[str, object]]:
    """Saved-frame rate, how it was derived, recording rate, warnings, and time stamp facts."""
    record = float(setup.get("dFrameRate") or setup.get("FrameRate") or setup.get("FrameRate16") or 0) or None
    decimation = float(setup.get("fDecimation") or 1.0)
    decimation = decimation if decimation >= 1 else 1.0
    warnings_: list[str] = []
    facts: dict[str, object] = {}
    nominal = record / decimation if record else None
    if nominal and decimation > 1:
        note = f"record rate {record:g} fps / save decimation {decimation:g}"
    else:
        note = f"record rate {record:g} fps" if record else ""
    if stamps is None:
        return nominal, note, record if decimation > 1 else None, warnings_, facts
    stamp_fps, jitter, bad = stamp_rate(stamps[:n])
    facts["timestamp_fps"] = None if stamp_fps is None else round(stamp_fps, 3)
    facts["timestamp_jitter"] = round(jitter, 6)
    if bad:
        warnings_.append(coded("movie.frames_out_of_step", f"{frames_named(bad)} out of step with the others — check "
                               f"{'it' if len(bad) == 1 else 'them'} (a camera writes a bad stamp on a frame it did "
                               "not record whole)"))
        facts["frames_with_bad_timestamp"] = bad
    if stamp_fps is None:
        return nominal, note, record if decimation > 1 else None, warnings_, facts
    if nominal and abs(stamp_fps / nominal - 1) <= 0.01:
        note += f"; time stamps agree ({stamp_fps:.6g} fps)"
        return nominal, note, record if decimation > 1 else None, warnings_, facts
    if nominal:
        warnings_.append(coded("movie.fps_stamps", f"the frame time stamps say {stamp_fps:.6g} fps but the header "
                               f"says {nominal:g} fps — " + STAMPS_OVER_HEADER))
    return stamp_fps, f"time stamps ({stamp_fps:.6g} fps)", record if decimation > 1 else None, warnings_, facts


#: the end of a warning that the file's stamps were preferred to its header's rate
STAMPS_OVER_HEADER = "using the time stamps; give fps= if the header is right"


def frames_named(indices: list[int]) -> str:
    """``"frame 234's time stamp is"`` or ``"the time stamps of frames 3, 9 are"`` (five at most)."""
    if len(indices) == 1:
        return f"frame {indices[0]}'s time stamp is"
    shown = ", ".join(str(k) for k in indices[:5]) + (" ..." if len(indices) > 5 else "")
    return f"the time stamps of frames {shown} are"
