"""Calibration files: read a calibration image or a background, write and read ``calibration.json`` and
draw its figure.

The only I/O of calibration: :mod:`grainplug.calibration` works on arrays and never sees a file.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from ._atomic import atomic_file
from ._version import __version__
from .calibration.background import MOVING_SHARE, Background, grey_background, moving_share
from .calibration.pattern import Calibration, CalibrationError, calibrate_image
from .errors import MovieError

#: frames of a movie given as a calibration image that are averaged (less noise)
MOVIE_FRAMES_AVERAGED = 10

logger = logging.getLogger(__name__)


def image_identity(path: Path) -> dict[str, object]:
    """Name, size and SHA-256 of a file."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            digest.update(chunk)
    return {"name": path.name, "path": str(path), "bytes": path.stat().st_size, "sha256": digest.hexdigest()}


def read_calibration_image(path: str | Path) -> np.ndarray:
    """A calibration image as an array: a picture file (PNG, TIFF, JPEG, BMP), or a movie
    of the pattern (any format grainplug reads), whose first frames are averaged.

    Raises
    ------
    MovieError
        When the file cannot be read as an image or a movie.
    """
    from .readers import IMAGE_SUFFIXES, open_movie

    p = Path(path).expanduser()
    if not p.is_file():
        raise MovieError(f"no such calibration image: {p} — check the path")
    if p.suffix.lower() in IMAGE_SUFFIXES and p.suffix.lower() not in (".tif", ".tiff"):
        from PIL import Image, UnidentifiedImageError

        try:
            with Image.open(p) as im:
                return np.asarray(im)
        except (UnidentifiedImageError, OSError) as exc:
            raise MovieError(f"cannot read {p} as an image ({exc}) — is the file complete?") from None
    try:
        with open_movie(p) as movie:
            n = min(movie.info.n_frames, MOVIE_FRAMES_AVERAGED)
            frames = [movie.read(k).astype(np.float64) for k in range(n)]
    except MovieError as exc:
        if p.suffix.lower() not in (".tif", ".tiff"):
            raise
        image = _opencv_picture(p)
        if image is None:
            if "imagecodecs" not in str(exc):
                raise
            raise MovieError(f"{exc} — install imagecodecs (pip install imagecodecs), or save the calibration "
                             "image as an uncompressed TIFF or a PNG") from None
        logger.info("%s: read by OpenCV (tifffile could not: %s); its first page only", p, exc)
        return image
    return np.mean(frames, axis=0)


def _opencv_picture(path: Path) -> np.ndarray | None:
    """A TIFF's first page read by OpenCV (its libtiff decodes the LZW, Deflate and PackBits that tifffile
    needs the optional imagecodecs package for), grey or RGB, at its bit depth; None when OpenCV cannot."""
    import cv2

    quiet = getattr(getattr(cv2, "utils", None), "logging", None)
    level = quiet.getLogLevel() if quiet is not None else None
    if quiet is not None:  # OpenCV's libtiff prints its own errors on stderr: grainplug says one line
        quiet.setLogLevel(quiet.LOG_LEVEL_SILENT)
    try:
        image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    finally:
        if quiet is not None:
            quiet.setLogLevel(level)
    if image is None or image.ndim not in (2, 3):
        return None
    if image.ndim == 3:  # OpenCV gives BGR(A)
        image = image[..., 2::-1] if image.shape[2] >= 3 else image[..., 0]
    return np.ascontiguousarray(image)


#: frames of a background movie that are averaged
BACKGROUND_FRAMES_AVERAGED = 50


def read_background(path: str | Path) -> Background:
    """A light calibration (the tube empty or full, nothing moving): a picture, or a movie whose first
    frames are averaged.

    Raises
    ------
    MovieError
        When the file cannot be read as an image or a movie.
    """
    from .readers import IMAGE_SUFFIXES, open_movie

    p = Path(path).expanduser()
    if not p.is_file():
        raise MovieError(f"no such background file: {p} — check the path")
    identity = image_identity(p)
    if p.suffix.lower() in IMAGE_SUFFIXES and p.suffix.lower() not in (".tif", ".tiff"):
        return grey_background([read_calibration_image(p)], identity=identity)
    with open_movie(p) as movie:
        n = min(movie.info.n_frames, BACKGROUND_FRAMES_AVERAGED)
        frames = [movie.read(k) for k in np.unique(np.linspace(0, movie.info.n_frames - 1, n).round().astype(int))]
    share = moving_share(frames)
    if share > MOVING_SHARE:
        raise MovieError(f"the background {p} moves: {share:.1%} of its pixels change from frame to frame far above "
                         "its noise (a plug-flow movie?) — give a picture or a movie of the tube with nothing moving "
                         "in it (empty, or full and still)")
    return grey_background(frames, identity=identity)


def calibrate_file(path: str | Path, *, pitch_mm: float, pattern: str = "auto") -> Calibration:
    """:func:`calibrate_image` on a file, its identity kept with the result."""
    p = Path(path).expanduser()
    return calibrate_image(read_calibration_image(p), pitch_mm=pitch_mm, pattern=pattern,
                           identity=image_identity(p))


def calibration_figure_path(path: str | Path) -> Path:
    """Where ``grainplug calibrate`` draws the points it found, beside the calibration file ``path``:
    ``calibration.json`` -> ``calibration_points.png`` (a name no calibration photo is likely to have)."""
    p = Path(path)
    return p.with_name(f"{p.stem}_points.png")


def _image_path(cal: Calibration) -> str | None:
    """The calibration image's path as it was read (None when the calibration came from an array)."""
    identity = cal.image if isinstance(cal.image, dict) else {}
    path = identity.get("path")
    return str(path) if path else None


def save_calibration(cal: Calibration, path: str | Path, *, inputs: Iterable[str | Path] = ()) -> Path:
    """Write ``calibration.json`` atomically (with the grainplug version); returns its path.

    Refused (:class:`grainplug._atomic.OutputPlaceError`) when ``path`` is the calibration image or one of
    ``inputs``: a calibration never replaces the photo it was measured on.
    """
    dest = Path(path)
    data = {**cal.as_dict(), "grainplug_version": __version__}
    with atomic_file(dest, inputs=[_image_path(cal), *inputs]) as tmp:
        tmp.write_text(json.dumps(data, indent=2) + "\n")
    return dest


def load_calibration(path: str | Path) -> Calibration:
    """Read a ``calibration.json`` written by :func:`save_calibration` (``grainplug calibrate``); its
    absolute path is kept as the calibration's ``source`` (recorded in an analysis's provenance).

    Raises
    ------
    CalibrationError
        When the file is missing, not JSON, or not a calibration.
    """
    p = Path(path).expanduser()
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise CalibrationError(f"no such calibration file: {p} — make one with `grainplug calibrate IMAGE`") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CalibrationError(f"{p} is not a calibration JSON ({exc}) — make one with `grainplug calibrate`") \
            from None
    if not isinstance(data, dict):
        raise CalibrationError(f"{p} is not a calibration JSON — make one with `grainplug calibrate`")
    try:
        cal = Calibration.from_dict(data)
    except CalibrationError as exc:
        raise CalibrationError(f"{p}: {exc}") from None
    return dataclasses.replace(cal, source=str(p.resolve()))


def draw_calibration(image: np.ndarray, cal: Calibration, path: str | Path, *,
                     inputs: Iterable[str | Path] = ()) -> Path:
    """The image with the points found and the scale (:func:`grainplug.plotting.calibration.plot_calibration`),
    for the user to check: a PNG written atomically, never over the calibration image or one of ``inputs``."""
    from ._atomic import refuse_overwriting_inputs
    from .plotting.calibration import plot_calibration

    refuse_overwriting_inputs([path], [_image_path(cal), *inputs])  # before the figure is drawn
    fig = plot_calibration(image, cal)
    dest = Path(path)
    with atomic_file(dest, inputs=[_image_path(cal), *inputs]) as tmp:
        fig.savefig(tmp, dpi=110, bbox_inches="tight")
    return dest
