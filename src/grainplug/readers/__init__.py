"""All movie I/O: one protocol (:class:`Movie`), one entry point (:func:`open_movie`).

Every format is a :class:`Movie`: it describes itself (:class:`MovieInfo`), hands
out frames as numpy arrays, and serves the analysis's one streaming call,
:meth:`Movie.read_band`, the fastest way the format allows. Frames already in
memory (numpy or dask arrays) are a movie too (:class:`ArrayMovie`). To add a
format: subclass :class:`Movie` (``_iter`` at least; ``_block_reader`` for frames
that can be memory-mapped), and add it to :func:`open_movie`.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

from ..errors import MovieError
from ..params import checked_fps
from .base import TIFF_SIGNATURES, Movie, MovieInfo

log = logging.getLogger(__name__)

TIFF_SUFFIXES = (".tif", ".tiff")


def open_movie(path: str | Path | object, *, glob: str | None = None, fps: float | None = None,
               verify: bool = False, allow_truncated: bool = False) -> Movie:
    """Open a movie of any supported kind for streaming.

    Parameters
    ----------
    path : str or Path or array
        A video file (AVI, MP4, MKV, MOV...; through PyAV when it is installed, else
        through OpenCV), a multi-page TIFF, a folder of
        numbered images, a Phantom ``.cine``, a Photron ``.mraw`` (or its
        ``.cih``/``.cihx`` header), a NorPix ``.seq``; or frames in memory,
        ``T x H x W`` or ``T x H x W x 3`` (numpy, dask).
    glob : str, optional
        For folders: only images matching this pattern (e.g. ``"cam1_*.png"``).
    fps : float, optional
        Frame rate to use instead of the file's (required for image folders
        and for files that do not record one, if times are needed).
    verify : bool
        For videos: demux the whole file to count frames and detect truncation.
    allow_truncated : bool
        For camera files (``.cine``, ``.mraw``, ``.seq``) that end early: read the
        complete frames, with a warning in ``info.warnings``, instead of refusing.

    Returns
    -------
    Movie
        The opened movie; use it as a context manager.

    Raises
    ------
    MovieError
        With a one-line message when the path is missing, empty, corrupt or not a movie.
    """
    fps = checked_fps(fps)
    if not isinstance(path, (str, os.PathLike)):
        if isinstance(path, (list, tuple)) and path and all(isinstance(p, (str, os.PathLike)) for p in path):
            raise MovieError(f"a list of {len(path)} file names is not a movie — give the folder that holds them "
                             "(and glob= to choose among its files), or one movie file")
        if hasattr(path, "shape") or isinstance(path, (list, tuple)):
            from .array import ArrayMovie

            return ArrayMovie(path, fps=fps)
        raise MovieError(f"cannot open a {type(path).__name__} as a movie — pass a path, a Movie or an array "
                         "of frames")
    from .folder import IMAGE_SUFFIXES, ImageFolderMovie  # with tifffile and Pillow: only when opening

    p = Path(path).expanduser()
    if not p.exists():
        if p.is_symlink():
            raise MovieError(f"{p} is a symbolic link to nothing (or a loop of links) — give the movie's own path")
        raise MovieError(f"no such file or folder: {p} — check the path")
    if p.is_dir():
        return ImageFolderMovie(p, glob=glob, fps=fps)
    if not p.is_file():
        raise MovieError(f"{p} is not a regular file (a pipe or a device?) — give a movie file")
    if p.stat().st_size == 0:
        raise MovieError(f"{p} is empty (0 bytes) — copy the movie again")
    suffix = p.suffix.lower()
    kind = _sniff(p)
    expected = {"cine": (".cine",), "seq": (".seq",), "tiff": TIFF_SUFFIXES}
    if kind and suffix not in expected[kind]:
        raise MovieError(f"{p} is a {CAMERA_NAMES[kind]} file despite its '{suffix}' extension — rename it to "
                         f"'{expected[kind][0]}'")
    if suffix in TIFF_SUFFIXES:
        from .tiffstack import TiffStackMovie

        return TiffStackMovie(p, fps=fps)
    if suffix == ".cine":
        from .cine import CineMovie

        return CineMovie(p, fps=fps, allow_truncated=allow_truncated)
    if suffix in (".mraw", ".cih", ".cihx"):
        from .photron import MrawMovie

        return MrawMovie(p, fps=fps, allow_truncated=allow_truncated)
    if suffix == ".seq":
        from .norpix import SeqMovie

        return SeqMovie(p, fps=fps, allow_truncated=allow_truncated)
    if suffix in IMAGE_SUFFIXES:
        raise MovieError(
            f"{p} is a single image — pass the folder that holds the numbered frames instead"
        )
    if not pyav_available():
        from .cvvideo import OpenCVVideoMovie

        return OpenCVVideoMovie(p, fps=fps, verify=verify)
    from .video import VideoMovie

    return VideoMovie(p, fps=fps, verify=verify)


def pyav_available() -> bool:
    """Whether PyAV (the ``video`` extra) is installed: videos are then read and written through
    it; without it, through OpenCV (see :mod:`grainplug.readers.cvvideo`)."""
    try:
        import av  # noqa: F401
    except ImportError:
        return False
    return True


#: formats recognised by their first bytes, whatever the file's extension
CAMERA_NAMES = {"cine": "Phantom .cine", "seq": "NorPix .seq", "tiff": "TIFF"}


def _sniff(path: Path) -> str | None:
    """The format the file's first bytes announce, for those that announce one."""
    with open(path, "rb") as fh:
        head = fh.read(8)
    if head[:2] == b"CI" and len(head) >= 8 and int.from_bytes(head[2:4], "little") >= 0x2C:
        return "cine"
    if head[:4] == (0xFEED).to_bytes(4, "little"):
        return "seq"
    if head[:4] in TIFF_SIGNATURES:
        return "tiff"
    return None


def as_movie(source: object, *, fps: float | None = None, glob: str | None = None,
             allow_truncated: bool = False) -> Movie:
    """``source`` as a :class:`Movie`: a Movie as it is, anything else through :func:`open_movie`."""
    if isinstance(source, Movie):
        return source
    return open_movie(source, fps=fps, glob=glob, allow_truncated=allow_truncated)


def __getattr__(name: str) -> object:
    """The readers' own names, imported when first used (``readers.base`` alone, as the figure worker
    needs it to unpickle a result, then costs no TIFF or image library)."""
    if name == "ArrayMovie":
        from .array import ArrayMovie

        return ArrayMovie
    if name in ("IMAGE_SUFFIXES", "ImageFolderMovie", "list_images", "natural_key"):
        from . import folder

        return getattr(folder, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["ArrayMovie", "Movie", "MovieError", "MovieInfo", "as_movie", "list_images", "natural_key",
           "open_movie", "pyav_available"]
