"""Campaign manifests: one row per run (CSV, or TOML for those who prefer it).

Columns (CSV header, or keys of each ``[[run]]`` table in TOML; a TOML
``[defaults]`` table fills keys a run does not give):

============================  =========================================================
``run``                        identifier (default: the row number)
``movie``                      path of the movie, relative to the manifest's folder
``fps``                        frame rate, when the file holds none or it is wrong
``mm_per_px``                  scale, or
``calibration``                a calibration.json (``grainplug calibrate``), relative to the
                               manifest's folder: the scale, e.g. one per day of experiments
``background``                 a light calibration (the tube empty, nothing moving: a picture or
                               short movie), relative to the manifest's folder
``tube_diameter_mm``           inner diameter of the tube (scale from the tube; 3 mm)
``tube_outer_diameter_mm``     outer diameter of the tube (scale from its silhouette)
``glass_index``                refractive index of the tube's glass (1.47)
``flow_direction``             down, up, left or right
``glob``                       for image folders
``start_frame``, ``end_frame``  analyse these frames only (or ``start_s``, ``end_s`` in seconds)
``roi``                        analyse this rectangle only: ``x0,y0,x1,y1`` in pixels (one tube of
                               several)
``min_plug_mm``, ``min_gap_mm``  shortest plug and gap counted (3 and 0.6 mm)
``sample_frames``              frames sampled to find the tube (32)
``allow_truncated``            true: analyse a camera file that ends early
``mass_flow_rate_g_s``         mass flow rate
``humidity_pct``               relative humidity
``surface``                    grain surface state (e.g. rough, smooth)
``group``                      grouping for the fits (default: regime/surface)
anything else                  kept as metadata in the campaign table; one whose name looks
                               like a column above misspelt (``mm_per_pix``) is warned about,
                               as the run is analysed without it
============================  =========================================================
"""

from __future__ import annotations

import csv
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import ParameterError
from ..params import AnalysisParams
from ..warning_codes import coded

if TYPE_CHECKING:
    from ..calibration.background import Background
    from ..calibration.pattern import Calibration


def yes_or_no(value: object) -> bool:
    """``true``/``false`` (TOML), or ``true``, ``yes``, ``1``, ``false``, ``no``, ``0`` (CSV)."""
    if isinstance(value, bool):
        return value
    text = str(value).strip().lower()
    if text in ("true", "yes", "1"):
        return True
    if text in ("false", "no", "0"):
        return False
    raise ValueError("is not true or false")


def pixel_box(value: object) -> tuple[int, ...]:
    """``x0,y0,x1,y1`` (CSV, quoted) or a list of four numbers (TOML)."""
    parts = value if isinstance(value, list | tuple) else str(value).replace(";", ",").split(",")
    try:
        box = tuple(int(str(v).strip()) for v in parts)
    except ValueError:
        box = ()
    if len(box) != 4:
        raise ValueError("is not four pixel numbers x0,y0,x1,y1 (quote them in CSV: \"40,0,120,1024\")")
    return box


ANALYSIS_KEYS = {"fps": float, "mm_per_px": float, "tube_diameter_mm": float, "tube_outer_diameter_mm": float,
                 "glass_index": float, "flow_direction": str, "glob": str, "min_plug_mm": float,
                 "min_gap_mm": float, "sample_frames": int, "allow_truncated": yes_or_no, "roi": pixel_box,
                 "start_frame": int, "end_frame": int, "start_s": float, "end_s": float,
                 "packed_compactness": float, "grain_density_kg_m3": float}
KNOWN_META = {"mass_flow_rate_g_s": float, "humidity_pct": float, "surface": str, "group": str}
#: the columns with a meaning (the others are metadata)
#: what ``grainplug manifest`` copies from each movie's header beside ``fps``: kept as metadata, never taken for a
#: misspelt column
HEADER_META = ("record_fps", "n_frames", "duration_s", "width", "height", "bit_depth", "camera", "trigger_time_utc")
KNOWN_COLUMNS = (*ANALYSIS_KEYS, *KNOWN_META, "run", "movie", "calibration", "background", "packed")


@dataclass(frozen=True)
class RunSpec:
    """One run of a campaign."""

    run: str
    movie: Path
    params: AnalysisParams
    meta: dict[str, object] = field(default_factory=dict)
    #: what the manifest's row leaves unsure (a column that looks like a known one misspelt)
    warnings: tuple[str, ...] = ()


def run_folder_name(run: str) -> str:
    """The folder of a run under ``runs/``: its name with anything but letters, digits, '-', '_', '.' as '_'."""
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in run) or "run"


def _convert(key: str, value: object, kinds: dict[str, type], where: str) -> object:
    if value is None or (isinstance(value, str) and value.strip() == ""):
        return None
    kind = kinds[key]
    try:
        return kind(value)
    except (TypeError, ValueError) as exc:
        what = exc.args[0] if kind in (yes_or_no, pixel_box) else f"is not a {kind.__name__}"
        raise ParameterError(f"{where}, column {key}: {value!r} {what}") from None


#: names people give the analysis settings, and the column meant
ALIASES = {"start": "start_frame or start_s", "end": "end_frame or end_s", "scale": "mm_per_px",
           "frame_rate": "fps", "path": "movie", "file": "movie"}


def _misspelt(columns: object) -> list[str]:
    """Warnings for columns whose name looks like a known column's misspelt (``mm_per_pix``): kept as metadata, the
    run is analysed without the setting they may mean. A name that extends a known one (``group2``,
    ``calibration_date``) is a column of its own and passes unsaid."""
    import difflib

    out = []
    for column in columns:  # type: ignore[attr-defined]
        if column is None or column in KNOWN_COLUMNS or column in HEADER_META:
            continue
        name = str(column).strip().lower().replace("-", "_").replace(" ", "_")
        if name in ALIASES:
            meant = ALIASES[name]
        elif name in KNOWN_COLUMNS:
            meant = name
        else:
            close = difflib.get_close_matches(name, KNOWN_COLUMNS, n=1, cutoff=0.8)
            meant = close[0] if close and close[0] not in name and name not in close[0] else None
        if meant:
            out.append(coded("manifest.column_unknown",
                f"column {column!r} is not one grainplug knows: it was kept as metadata and the run analysed "
                f"without it — if it means {meant!r}, name it so"))
    return out


def _spec(row: dict[str, object], index: int, base: Path, where: str) -> RunSpec:
    if not row.get("movie"):
        raise ParameterError(f"{where}: no movie given — every run needs a 'movie' path")
    if None in row:
        raise ParameterError(f"{where}: more values than the header has columns — quote values that hold commas")
    run = str(row.get("run") or index).strip()
    if run in (".", "..") or any(sep in run for sep in ("/", "\\")) or not run:
        raise ParameterError(f"{where}, column run: {run!r} cannot name a run's folder — use letters, digits, "
                             "'-', '_' or '.' (no '/', not '.' or '..')")
    movie = Path(str(row["movie"])).expanduser()
    if not movie.is_absolute():
        movie = base / movie
    if movie.exists() and not (movie.is_file() or movie.is_dir()):
        raise ParameterError(f"{where}, column movie: {movie} is not a regular file (a pipe or a device) — "
                             "give a movie file or an image folder")
    kw = {k: _convert(k, row.get(k), ANALYSIS_KEYS, where) for k in ANALYSIS_KEYS if k in row}
    kw = {k: v for k, v in kw.items() if v is not None}
    if row.get("calibration"):
        kw["calibration"] = _calibration(str(row["calibration"]), base, where)
    if row.get("background"):
        kw["background"] = _background(str(row["background"]), base, where)
    if row.get("packed"):
        kw["packed"] = _background(str(row["packed"]), base, where, "packed")
    try:
        params = AnalysisParams(**kw)
    except ParameterError as exc:
        column = f", column {exc.param}" if exc.param else ""
        raise ParameterError(f"{where}{column}: {exc.message}") from None
    meta: dict[str, object] = {}
    for k, v in row.items():
        if k in KNOWN_COLUMNS and k not in KNOWN_META:
            continue
        meta[k] = _convert(k, v, KNOWN_META, where) if k in KNOWN_META else v
    return RunSpec(run, movie, params, meta, tuple(_misspelt(row)))


def _background(value: str, base: Path, where: str, column: str = "background") -> Background:
    from ..calibration_files import read_background
    from ..errors import GrainplugError

    path = Path(value).expanduser()
    try:
        return read_background(path if path.is_absolute() else base / path)
    except GrainplugError as exc:
        raise ParameterError(f"{where}: {column}: {exc}") from None


def _calibration(value: str, base: Path, where: str) -> Calibration:
    from ..calibration.pattern import CalibrationError
    from ..calibration_files import load_calibration

    path = Path(value).expanduser()
    try:
        return load_calibration(path if path.is_absolute() else base / path)
    except CalibrationError as exc:
        raise ParameterError(f"{where}: calibration: {exc}") from None


def read_manifest(path: str | Path) -> list[RunSpec]:
    """Read a CSV or TOML manifest.

    Raises
    ------
    ParameterError
        With a one-line message naming the file, the row and the problem.
    """
    p = Path(path)
    if not p.exists():
        raise ParameterError(f"no such manifest: {p} — check the path")
    if p.is_dir():
        raise ParameterError(f"{p} is a folder — give the manifest file (CSV or TOML)")
    if not p.is_file():
        raise ParameterError(f"{p} is not a regular file (a pipe or a device) — give the manifest file")
    raw = p.read_bytes()
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise ParameterError(f"{p}, line {line}: not UTF-8 text (byte 0x{raw[exc.start]:02x}) — save the manifest "
                             "as UTF-8") from None
    base = p.parent
    specs: list[RunSpec] = []
    if p.suffix.lower() == ".toml":
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ParameterError(f"{p} is not valid TOML ({exc})") from None
        defaults = data.get("defaults", {})
        if not isinstance(defaults, dict):
            raise ParameterError(f"{p}: 'defaults' must be a table ([defaults] with key = value lines)")
        rows = data.get("run", [])
        if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
            raise ParameterError(f"{p}: runs must be given as [[run]] tables")
        for i, row in enumerate(rows, 1):
            specs.append(_spec({**defaults, **row}, i, base, f"{p.name}, run {i}"))
    else:
        import io

        # comment rows ("# ..."; grainplug manifest's for files it could not read) are skipped, lines kept counted
        text = "\n".join("" if line.lstrip().startswith("#") else line for line in text.split("\n"))
        reader = csv.DictReader(io.StringIO(text, newline=""), strict=True)
        start = 1  # the line where the record being read starts (a quoted field may span lines)
        try:
            if not reader.fieldnames or "movie" not in reader.fieldnames:
                raise ParameterError(f"{p}: the header has no 'movie' column — see `grainplug batch --help`")
            start = reader.line_num + 1
            for row in reader:
                specs.append(_spec(dict(row), len(specs) + 1, base, f"{p.name}, line {start}"))
                start = reader.line_num + 1
        except csv.Error as exc:
            raise ParameterError(f"{p}, line {start}: not valid CSV ({exc}) — check the quotes") from None
    if not specs:
        raise ParameterError(f"{p} lists no runs")
    names = [s.run for s in specs]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise ParameterError(f"{p}: run names repeat ({', '.join(sorted(dup))}) — give each run its own name")
    folders: dict[str, str] = {}
    for n in names:  # two names that make one folder name would overwrite each other
        key = run_folder_name(n).lower()
        if key in folders:
            raise ParameterError(f"{p}: runs {folders[key]!r} and {n!r} would share the folder runs/{key} — "
                                 "rename one")
        folders[key] = n
    return specs
