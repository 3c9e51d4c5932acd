"""A campaign's manifest from a folder of movies: what their headers say, and empty columns for the lab's own.

Every movie file in the folder (camera files, TIFF stacks, videos; not image sequences, whose folders
are listed as they are) is opened with grainplug's readers, headers only (no frame is decoded), and
gives one row: the run's name (from the file's), the movie's path relative to the manifest, its
saved-frame rate (``fps``: the rate the frames were saved at, which times them; a camera's record rate
when it saved every n-th frame is in ``record_fps``), frames, duration, size, bit depth, camera and
trigger time. The lab's metadata columns (mass flow rate, humidity, surface, group) are left empty to
fill in. A file that cannot be read gives a comment row (``# name: why``), which ``grainplug batch``
skips: the lab sees it and decides.
"""

from __future__ import annotations

import csv
import io
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import GrainplugError, ParameterError
from .manifest import HEADER_META, KNOWN_META

#: the suffixes of the files looked at (every format grainplug reads a movie from, one file each)
MOVIE_SUFFIXES = (".cine", ".mraw", ".cih", ".cihx", ".seq", ".tif", ".tiff", ".avi", ".mp4", ".mkv", ".mov",
                  ".webm", ".mj2")
#: the header's facts, in the manifest's columns (metadata for batch: kept with each run, not parameters)
HEADER_COLUMNS = ("fps", *HEADER_META)
COLUMNS = ("run", "movie", *HEADER_COLUMNS, *KNOWN_META)


@dataclass(frozen=True)
class ScannedMovie:
    """One file of the folder: its row, or why it could not be read."""

    path: Path
    row: dict[str, object] = field(default_factory=dict)
    error: str = ""


def _run_name(path: Path, taken: set[str]) -> str:
    """The run's name from the movie's path within the folder (``s1/movie.cine``: ``s1_movie``), made unique."""
    base = re.sub(r"[^A-Za-z0-9_.-]+", "_", path.with_suffix("").as_posix()).strip("._") or "run"
    name, k = base, 2
    while name.lower() in taken:
        name, k = f"{base}_{k}", k + 1
    taken.add(name.lower())
    return name


def scan_folder(folder: str | Path, *, glob: str | None = None) -> list[ScannedMovie]:
    """The movies of ``folder`` (files matching ``glob``, by default every movie suffix grainplug reads), each
    with its manifest row from its header, in name order.

    Raises
    ------
    ParameterError
        When ``folder`` is not a folder, or holds no movie.
    """
    from ..readers import open_movie

    top = Path(folder).expanduser()
    if not top.is_dir():
        raise ParameterError(f"{top} is not a folder — give the folder that holds the campaign's movies")
    found = sorted(p for p in (top.glob(glob) if glob else top.iterdir())
                   if p.is_file() and (glob or p.suffix.lower() in MOVIE_SUFFIXES))
    # a Photron recording is its header (.cih, .cihx) and its frames (.mraw): listed once, by its header
    headers = {p.with_suffix("").name for p in found if p.suffix.lower() in (".cih", ".cihx")}
    files = [p for p in found if not (p.suffix.lower() == ".mraw" and p.with_suffix("").name in headers)]
    if not files:
        what = f"matching {glob!r}" if glob else f"with a movie suffix ({', '.join(MOVIE_SUFFIXES)})"
        raise ParameterError(f"{top} holds no file {what} — check the folder, or give --glob")
    out: list[ScannedMovie] = []
    taken: set[str] = set()
    for p in files:
        where = p.relative_to(top)  # a file in a subfolder (a --glob such as */*) keeps its subfolder
        try:
            with open_movie(p) as movie:
                info = movie.info
        except GrainplugError as exc:
            out.append(ScannedMovie(p, error=str(exc)))
            continue
        except Exception as exc:  # a reader's own failure on a damaged file: said in the row, the scan goes on
            out.append(ScannedMovie(p, error=f"{type(exc).__name__}: {exc}"))
            continue
        details = dict(info.details)
        row: dict[str, object] = {
            "run": _run_name(where, taken), "movie": where.as_posix(), "fps": info.fps, "record_fps": info.record_fps,
            "n_frames": info.n_frames,
            "duration_s": None if not info.fps else round(info.n_frames / info.fps, 6),
            "width": info.width, "height": info.height, "bit_depth": info.bit_depth, "camera": info.camera,
            "trigger_time_utc": details.get("trigger_time_utc"),
        }
        out.append(ScannedMovie(p, row))
    return out


def manifest_text(scanned: list[ScannedMovie]) -> str:
    """The manifest as CSV: a header of :data:`COLUMNS`, one row per movie read, a comment row per file not."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(COLUMNS)
    for s in scanned:
        if s.error:
            buf.write("# " + f"{s.path.name}: not read — {s.error}".replace("\n", " ") + "\n")
            continue
        w.writerow(["" if s.row.get(c) is None else s.row.get(c) for c in COLUMNS])
    return buf.getvalue()
