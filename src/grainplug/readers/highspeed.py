"""High-speed camera files: Phantom ``.cine`` (pycine) and Photron ``.mraw`` (pyMRAW).

Both readers are optional extras: ``pip install grainplug[highspeed]``.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from ..errors import MovieError
from .base import Movie, MovieInfo

_EXTRA_HINT = "install the high-speed readers with: pip install 'grainplug[highspeed]'"


class CineMovie(Movie):
    """Phantom ``.cine`` files through `pycine`, frames as 16-bit grey arrays.

    Notes
    -----
    pycine hands out the raw sensor values (Bayer mosaic for colour cameras),
    rescaled from the file's black/white levels to ``RealBPP`` bits.
    """

    def __init__(self, path: Path, *, fps: float | None = None) -> None:
        try:
            from pycine.file import read_header
        except ImportError:
            raise MovieError(f"cannot read {path}: pycine is not installed — {_EXTRA_HINT}") from None
        try:
            header = read_header(str(path))
            bih = header["bitmapinfoheader"]
            setup = header["setup"]
            n_frames = int(header["cinefileheader"].ImageCount)
            width, height = int(bih.biWidth), abs(int(bih.biHeight))
            file_fps = float(setup.FrameRate) or None
        except Exception as exc:  # pycine raises struct/ctypes errors on bad files
            raise MovieError(f"cannot read {path} as a Phantom .cine file ({exc})") from None
        if n_frames <= 0 or width <= 0 or height <= 0:
            raise MovieError(f"{path}: the .cine header describes no frames — the file is corrupt")
        use_fps, source = (fps, "user") if fps else (file_fps, "file" if file_fps else "none")
        info = MovieInfo(str(path), "cine", width, height, n_frames, use_fps, 1, 16, "uint16", source)
        super().__init__(path, info)

    def _iter(self, start: int, stop: int, step: int) -> Iterator[np.ndarray]:
        from pycine.raw import read_frames

        try:
            gen, _, _ = read_frames(str(self.path), start_frame=start + 1, count=stop - start)
            for k, img in enumerate(gen):
                if k % step == 0:
                    yield np.ascontiguousarray(img, dtype=np.uint16)
        except (OSError, ValueError, IndexError) as exc:
            raise MovieError(f"{self.path} is corrupt or truncated ({exc})") from None


def _cih_path(path: Path) -> Path:
    if path.suffix.lower() in (".cih", ".cihx"):
        return path
    for ext in (".cihx", ".cih", ".CIHX", ".CIH"):
        cand = path.with_suffix(ext)
        if cand.exists():
            return cand
    raise MovieError(f"{path}: no .cih/.cihx header beside the .mraw file — copy it along with the movie")


def photron_saved_rate(cih: Path, meta: dict) -> tuple[float | None, str]:
    """Frame rate of the *saved* frames of a Photron recording, and how it was derived.

    The camera records at ``Record Rate`` but may save one frame in ``Save Step``
    (``.cih``) or ``skipFrame`` (``.cihx``): the saved frames are then
    ``record rate / step`` apart. The step is read from the header itself (pyMRAW does
    not report it for ``.cihx``).
    """
    rate = meta.get("Record Rate(fps)")
    if not rate:
        return None, "none"
    step = meta.get("Save Step")
    if step is None and cih.suffix.lower() == ".cihx":
        import re

        text = cih.read_bytes().decode("utf-8", errors="ignore")
        found = re.search(r"<frameInfo>.*?<skipFrame>\s*(\d+)\s*</skipFrame>", text, flags=re.S)
        step = int(found.group(1)) if found else None
    step = int(step) if step else 1
    if step <= 1:
        return float(rate), f"record rate {float(rate):g} fps"
    return float(rate) / step, f"record rate {float(rate):g} fps / save step {step}"


class MrawMovie(Movie):
    """Photron ``.mraw`` + ``.cih``/``.cihx`` through `pyMRAW` (memory-mapped, lazy)."""

    def __init__(self, path: Path, *, fps: float | None = None) -> None:
        try:
            import pyMRAW
        except ImportError:
            raise MovieError(f"cannot read {path}: pyMRAW is not installed — {_EXTRA_HINT}") from None
        cih = _cih_path(path)
        data = cih.with_suffix(".mraw")
        if not data.exists() and not cih.with_suffix(".MRAW").exists():
            raise MovieError(f"{cih}: its image data {data.name} is not beside it — copy the .mraw file "
                             "along with its header")
        try:
            with warnings.catch_warnings():  # pyMRAW warns about any depth but 12 bits
                warnings.simplefilter("ignore")
                images, meta = pyMRAW.load_video(str(cih))
        except Exception as exc:  # pyMRAW raises plain Exceptions on unsupported files
            raise MovieError(f"cannot read {path} as a Photron .mraw movie ({exc})") from None
        self._images = images
        n_frames, height, width = images.shape[:3]
        channels = 3 if images.ndim == 4 else 1
        depth = 8 if images.dtype == np.uint8 else 16
        file_fps, how = photron_saved_rate(cih, meta)
        use_fps, source = (fps, "user") if fps else (file_fps, "file" if file_fps else "none")
        info = MovieInfo(str(path), "mraw", int(width), int(height), int(n_frames), use_fps,
                         channels, depth, "uint8" if depth == 8 else "uint16", source,
                         fps_note="" if fps else how)
        super().__init__(path, info)

    def _iter(self, start: int, stop: int, step: int) -> Iterator[np.ndarray]:
        for i in range(start, stop, step):
            yield self.read(i)

    def read(self, index: int) -> np.ndarray:
        arr = np.asarray(self._images[index])
        return np.ascontiguousarray(arr.astype(self.info.dtype, copy=False))

    def _close(self) -> None:
        self._images = None
