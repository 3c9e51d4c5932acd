"""Movie readers: one entry point, :func:`open_movie`, for every format.

Frames are streamed one at a time as numpy arrays, so memory use does not
depend on the movie's length.
"""

from __future__ import annotations

import logging
from pathlib import Path

from ..errors import MovieError, ParameterError
from .base import Movie, MovieInfo
from .folder import IMAGE_SUFFIXES, ImageFolderMovie, list_images, natural_key

log = logging.getLogger(__name__)

TIFF_SUFFIXES = (".tif", ".tiff")
VIDEO_SUFFIXES = (".avi", ".mp4", ".mkv", ".mov", ".m4v", ".webm", ".mj2", ".nut")


def open_movie(path: str | Path, *, glob: str | None = None, fps: float | None = None,
               verify: bool = False) -> Movie:
    """Open a movie of any supported kind for streaming.

    Parameters
    ----------
    path : str or Path
        A video file (AVI, MP4, MKV, MOV...), a multi-page TIFF, a folder of
        numbered images, a Phantom ``.cine`` or a Photron ``.mraw``/``.cih``.
    glob : str, optional
        For folders: only images matching this pattern (e.g. ``"cam1_*.png"``).
    fps : float, optional
        Frame rate to use instead of the file's (required for image folders
        and for files that do not record one, if times are needed).
    verify : bool
        For videos: demux the whole file to count frames and detect truncation.

    Returns
    -------
    Movie
        The opened movie; use it as a context manager.

    Raises
    ------
    MovieError
        With a one-line message when the path is missing, empty, corrupt or not a movie.
    """
    p = Path(path).expanduser()
    if fps is not None and not (fps > 0):
        raise ParameterError(f"fps must be positive, got {fps} — pass the camera's frame rate")
    if not p.exists():
        raise MovieError(f"no such file or folder: {p} — check the path")
    if p.is_dir():
        return ImageFolderMovie(p, glob=glob, fps=fps)
    if p.stat().st_size == 0:
        raise MovieError(f"{p} is empty (0 bytes) — copy the movie again")
    suffix = p.suffix.lower()
    if suffix in TIFF_SUFFIXES:
        from .tiffstack import TiffStackMovie

        return TiffStackMovie(p, fps=fps)
    if suffix == ".cine":
        from .highspeed import CineMovie

        return CineMovie(p, fps=fps)
    if suffix in (".mraw", ".cih", ".cihx"):
        from .highspeed import MrawMovie

        return MrawMovie(p, fps=fps)
    if suffix in IMAGE_SUFFIXES:
        raise MovieError(
            f"{p} is a single image — pass the folder that holds the numbered frames instead"
        )
    from .video import VideoMovie

    return VideoMovie(p, fps=fps, verify=verify)


__all__ = ["Movie", "MovieError", "MovieInfo", "list_images", "natural_key", "open_movie"]
