"""Folders of numbered still images (PNG, TIFF, BMP, JPEG)."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import tifffile
from PIL import Image, UnidentifiedImageError

from ..errors import MovieError
from .base import Movie, MovieInfo

IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".bmp", ".jpg", ".jpeg")
_DIGITS = re.compile(r"(\d+)")


def natural_key(name: str) -> tuple[object, ...]:
    """Sort key that orders embedded numbers numerically (``img_2`` before ``img_10``)."""
    parts = _DIGITS.split(name.lower())
    return tuple((0, int(p), "") if p.isdigit() else (1, 0, p) for p in parts)


def list_images(folder: Path, glob: str | None = None) -> list[Path]:
    """Image files of ``folder`` (optionally matching ``glob``) in natural order."""
    pattern = glob or "*"
    files = [p for p in folder.glob(pattern) if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES]
    return sorted(files, key=lambda p: natural_key(p.name))


def read_image(path: Path) -> np.ndarray:
    """Read one still image as ``uint8``/``uint16``, H x W or H x W x 3."""
    try:
        if path.suffix.lower() in (".tif", ".tiff"):
            arr = tifffile.imread(str(path))
        else:
            with Image.open(path) as img:
                if img.mode in ("I;16", "I;16B", "I;16L"):
                    arr = np.array(img, dtype=np.uint16)
                elif img.mode == "I":
                    arr = np.array(img).astype(np.uint16)
                elif img.mode in ("L", "RGB"):
                    arr = np.array(img)
                elif img.mode == "P" or img.mode == "1":
                    arr = np.array(img.convert("L"))
                else:
                    arr = np.array(img.convert("RGB"))
    except (OSError, UnidentifiedImageError, ValueError, tifffile.TiffFileError) as exc:
        raise MovieError(f"cannot read image {path} ({exc}) — remove or replace the file") from None
    if arr.ndim == 3 and arr.shape[-1] == 4:
        arr = arr[..., :3]
    if arr.dtype not in (np.uint8, np.uint16):
        raise MovieError(f"{path}: {arr.dtype} images are not supported — export 8- or 16-bit images")
    return arr


class ImageFolderMovie(Movie):
    """Numbered images in a folder, in natural numeric order (``img_2`` before ``img_10``).

    Image folders hold no frame rate: pass ``fps=``.
    """

    def __init__(self, path: Path, *, glob: str | None = None, fps: float | None = None) -> None:
        files = list_images(path, glob)
        if not files:
            what = f"matching {glob!r} " if glob else ""
            raise MovieError(
                f"folder {path} holds no images {what}— expected PNG, TIFF, BMP or JPEG files"
            )
        self.files = files
        first = read_image(files[0])
        channels = 1 if first.ndim == 2 else 3
        self._shape = first.shape
        info = MovieInfo(
            path=str(path), format=f"image-folder:{files[0].suffix.lower().lstrip('.')}",
            width=first.shape[1], height=first.shape[0], n_frames=len(files), fps=fps,
            channels=channels, bit_depth=8 * first.dtype.itemsize, dtype=first.dtype.name,
            fps_source="user" if fps else "none",
        )
        super().__init__(path, info)

    def _load(self, index: int) -> np.ndarray:
        arr = read_image(self.files[index])
        if arr.shape != self._shape:
            raise MovieError(
                f"{self.files[index]} is {arr.shape}, unlike the first image {self._shape} — "
                "the folder must hold frames of one size"
            )
        return arr

    def _iter(self, start: int, stop: int, step: int) -> Iterator[np.ndarray]:
        for i in range(start, stop, step):
            yield self._load(i)

    def read(self, index: int) -> np.ndarray:
        if not 0 <= index < self.info.n_frames:
            raise IndexError(f"frame {index} out of range 0..{self.info.n_frames - 1}")
        return self._load(index)
