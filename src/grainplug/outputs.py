"""Write an analysis to disk: summary, tables, diagram, the whole result, figures, report.

Everything goes through one atomic writer (:func:`grainplug._atomic.atomic_directory`),
so an interrupted run never leaves half-written files and previous results stay intact.
"""

from __future__ import annotations

import csv
import io
import json
import logging
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from . import jsonio
from ._atomic import atomic_directory
from .plotting.files import FIGURE_FILES, draw_figures, figure_files, figures_of, save_figure  # noqa: F401 - re-exported
from .plotting.options import FIGURE_FORMATS, PUBLICATION, FigureOptions  # noqa: F401 - PUBLICATION re-exported
from .store import RESULT_FILE, write_result
from .summary import EDGE_LONG_SCHEMA, EDGE_SCHEMA, TRACK_COLUMNS, track_rows

if TYPE_CHECKING:
    from .params import AnalysisParams
    from .plotting.worker import FigureWorker
    from .result import AnalysisResult

log = logging.getLogger(__name__)

FILES = {
    "summary": "summary.json",
    "edges": "plug_edges.csv",
    "tracks": "tracks.csv",
    "grain_velocity": "grain_velocity.csv",
    "diagram": "diagram.npz",
    "diagram_tif": "diagram.tif",
    "edges_long": "edges_long.csv",
    **FIGURE_FILES,
    "result": RESULT_FILE,
}
#: the grains' fields over time and position, written when a field beyond the diagram was measured
FIELDS_FILE = "fields.nc"


def edges_table(res: AnalysisResult) -> str:
    """CSV of the plug edges per frame (:data:`grainplug.summary.EDGE_SCHEMA`)."""

    r = res.runs
    t = res.diagram.time_s[r.frame]

    def col(x: np.ndarray, fmt: str) -> np.ndarray:
        out = np.char.mod(fmt, x)
        out[~np.isfinite(x)] = ""
        return out

    rows = np.stack([r.frame.astype(str), (r.frame.astype(np.int64) + res.first_movie_frame).astype(str),
                     np.char.mod("%.6f", t), res.links.run_track.astype(str),
                     col(r.top_mm, "%.4f"), col(r.bottom_mm, "%.4f")], axis=1) if len(r) else np.empty((0, 6), str)
    lines = [",".join(row) for row in rows.tolist()]
    return ",".join(EDGE_SCHEMA) + "\n" + "".join(line + "\n" for line in lines)


def edges_long_table(res: AnalysisResult) -> str:
    """CSV with one row per plug edge per frame, trackpy's long layout (:data:`grainplug.summary.EDGE_LONG_SCHEMA`)."""
    r, track = res.runs, res.links.run_track
    t = res.diagram.time_s
    parts = []
    for kind, pos in enumerate((r.top_mm, r.bottom_mm)):  # 0: upstream, 1: downstream
        seen = np.flatnonzero(np.isfinite(pos))
        sel = seen[np.lexsort((r.frame[seen], track[seen]))]  # by track, then frame
        f, x, k = r.frame[sel].astype(np.int64), pos[sel], track[sel]
        ts = t[f]
        # the edge's velocity: centred where the frames before and after hold it (in the same track), one-sided at
        # a track's ends, none where it is seen alone
        step = (np.diff(f) == 1) & (np.diff(k) == 0)
        nxt, prv = np.r_[step, False], np.r_[False, step]
        v = np.full(f.size, np.nan)
        i = np.flatnonzero(nxt & prv)
        v[i] = (x[i + 1] - x[i - 1]) / (ts[i + 1] - ts[i - 1])
        i = np.flatnonzero(nxt & ~prv)
        v[i] = (x[i + 1] - x[i]) / (ts[i + 1] - ts[i])
        i = np.flatnonzero(prv & ~nxt)
        v[i] = (x[i] - x[i - 1]) / (ts[i] - ts[i - 1])
        parts.append((f, ts, k, np.full(f.size, kind), x, v / 1000.0))  # mm/s -> m/s
    f, ts, k, kind, x, v = (np.concatenate(c) for c in zip(*parts, strict=True))
    order = np.lexsort((kind, k, f))  # by frame, then track, upstream edge first
    names = ("upstream", "downstream")
    lines = [f"{a},{b:.6f},{c},{names[d]},{e:.4f},{'' if g != g else f'{g:.6f}'}\n"
             for a, b, c, d, e, g in zip(f[order].tolist(), ts[order].tolist(), k[order].tolist(),
                                         kind[order].tolist(), x[order].tolist(), v[order].tolist(), strict=True)]
    return ",".join(EDGE_LONG_SCHEMA) + "\n" + "".join(lines)


def write_diagram_tif(res: AnalysisResult, path: Path) -> None:
    """The diagram as a float32 TIFF that Fiji opens in mm along the tube (x) and seconds (y): rows are frames,
    columns positions, with ImageJ's calibration (``unit`` mm, ``yunit`` s, the origin at position 0)."""
    import tifffile

    d = res.diagram
    dx = float(d.mm_per_px)
    dt = float(np.median(np.diff(d.time_s))) if d.n_frames > 1 else 1.0 / float(res.info.fps)
    tifffile.imwrite(path, np.ascontiguousarray(d.values, dtype=np.float32), imagej=True,
                     resolution=(1.0 / dx, 1.0 / dt),
                     metadata={"unit": "mm", "yunit": "s", "xorigin": -float(d.position_mm[0]) / dx,
                               "yorigin": -float(d.time_s[0]) / dt, "axes": "YX"})


def tracks_table(res: AnalysisResult) -> str:
    """CSV with one row per plug track (:func:`grainplug.summary.track_rows`), empty where NaN; columns
    and types in :data:`grainplug.summary.TRACK_SCHEMA`."""

    formats = {"first_time_s": "{:.6f}", "last_time_s": "{:.6f}", "celerity_m_s": "{:.6f}",
               "mean_length_mm": "{:.4f}", "median_length_mm": "{:.4f}"}

    def cell(key: str, v: object) -> object:
        if isinstance(v, float) and not np.isfinite(v):
            return ""
        if isinstance(v, (bool, np.bool_)):
            return "True" if v else "False"  # as pandas writes and reads a bool column
        return formats[key].format(v) if key in formats else v

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(TRACK_COLUMNS)
    for row in track_rows(res):
        w.writerow([cell(k, row[k]) for k in TRACK_COLUMNS])
    return buf.getvalue()


#: the columns of ``grain_velocity.csv``: one row per correlation window inside a plug
GRAIN_VELOCITY_COLUMNS = ("frame", "movie_frame", "lag_frames", "time_s", "position_mm", "track",
                          "grain_velocity_m_s", "correlation")


def grain_velocity_table(res: AnalysisResult) -> str:
    """CSV of the packed grains' velocity inside the plugs, per window: the pair's first frame (of the
    analysis and of the movie), the lag, the pair's mid-time, the window's centre along the tube, the plug's
    track as found (before a reviewer's corrections), the velocity (downstream positive) and the window's
    correlation peak
    (:mod:`grainplug.measures.creep`); the header alone when not measured."""
    g = res.grain_velocity
    head = ",".join(GRAIN_VELOCITY_COLUMNS) + "\n"
    if g is None or not len(g.frame):
        return head
    # measured on the plugs as found: a reviewer's corrections renumber the runs, not the windows
    links = res.detected[1] if res.detected is not None else res.links
    track = links.run_track[g.run] if np.all(g.run < len(links.run_track)) else np.full(len(g.run), -1)
    lags = (g.lag if g.lag is not None else np.full(len(g.frame), g.lag_frames)).tolist()
    lines = [f"{k},{k + res.first_movie_frame},{lag},{t:.6f},{z:.4f},{tr},{v:.7f},{c:.4f}\n"
             for k, lag, t, z, tr, v, c in zip(g.frame.tolist(), lags, g.time_s.tolist(), g.position_mm.tolist(),
                                              track.tolist(), g.velocity_m_s.tolist(), g.peak.tolist(), strict=True)]
    return head + "".join(lines)


def input_files(movie: str | Path | None, p: AnalysisParams) -> list[str]:
    """The files an analysis reads: the movie, the calibration file and the background of ``p`` (an output
    folder replaced whole must hold none of them)."""
    files: list[object] = [movie]
    if p.calibration is not None:
        files.append(getattr(p.calibration, "source", None))
    for picture in (p.background, p.packed):
        identity = getattr(picture, "identity", None)
        files.append(identity.get("path") if isinstance(identity, dict) else None)
    return [str(f) for f in files if f]


def write_outputs(res: AnalysisResult, out_dir: str | Path, *, figures: bool = True,
                  report: bool = True, extra: dict | None = None,
                  figure_worker: FigureWorker | None = None,
                  figure_options: FigureOptions | None = None, carry: bool = False) -> dict[str, Path]:
    """Write every output of ``res`` into ``out_dir``, atomically; returns the paths written.

    ``extra`` is merged into ``summary.json`` (e.g. the campaign's run key).
    ``carry``: what grainplug did not write in ``out_dir`` (a user's notes) is kept in the new folder
    rather than refused (:func:`grainplug._atomic.atomic_directory`): for a result rewritten in place.
    ``figure_worker`` draws the figures in a helper process meanwhile
    (:class:`grainplug.plotting.worker.FigureWorker`); by default they are drawn here.
    """
    t_write = time.perf_counter()
    written: dict[str, Path] = {}
    from .corrections import CORRECTIONS_FILE

    source = res.input.get("path") if isinstance(res.input, dict) else None
    keeps = (CORRECTIONS_FILE,) if res.corrections is not None else ()
    with atomic_directory(out_dir, written, replace=True, inputs=input_files(source, res.params), keeps=keeps,
                          carry=carry, kind="analysis") as tmp:
        summary = res.summary
        summary.update(extra or {})
        options = figure_options or FigureOptions()
        summary["outputs"] = {k: v for k, v in FILES.items() if not k.startswith("fig_")}
        if figures:
            summary["outputs"].update(figure_files(res, options))
            summary["figures"] = options.as_record()
        pending = None
        if figures and figure_worker is not None:  # drawn while the tables are written
            pending = figure_worker.submit(res, tmp, options)
        (tmp / FILES["edges"]).write_text(edges_table(res))
        (tmp / FILES["tracks"]).write_text(tracks_table(res))
        (tmp / FILES["grain_velocity"]).write_text(grain_velocity_table(res))
        with open(tmp / FILES["diagram"], "wb") as fh:
            np.savez(  # uncompressed: float noise barely compresses, and this is fast
                fh, values=res.diagram.values, contrast=res.normalized.z, time_s=res.diagram.time_s,
                position_mm=res.diagram.position_mm, mm_per_px=res.mm_per_px,
                provenance=json.dumps({"grainplug_version": summary["grainplug_version"],
                                       "input": summary["input"], "parameters": summary["parameters"]},
                                      default=jsonio.default),
            )
        if res.compactness_field is not None:  # the grains' fields, beside the simulation's (fields.nc)
            res.fields().to_netcdf(tmp / FIELDS_FILE, engine="scipy")
            summary["outputs"]["fields"] = FIELDS_FILE
        write_diagram_tif(res, tmp / FILES["diagram_tif"])
        (tmp / FILES["edges_long"]).write_text(edges_long_table(res))
        write_result(res, tmp / FILES["result"])
        if res.corrections is not None:
            (tmp / CORRECTIONS_FILE).write_text(jsonio.dumps(res.corrections.as_dict()))
        if pending is not None:
            pending()
        elif figures:
            draw_figures(res, tmp, options)
        if report:
            from .reports import run_report

            (tmp / "report.html").write_text(run_report(res, tmp, summary=summary))
        summary["timings_s"]["write_s"] = round(time.perf_counter() - t_write, 4)
        (tmp / FILES["summary"]).write_text(jsonio.dumps(summary))
    return {_output_key(name): path for name, path in written.items()}


def _output_key(name: str) -> str:
    """The key :func:`write_outputs` returns a file under, as in ``summary.json``'s ``outputs``:
    ``plug_edges.csv`` -> ``edges``, ``diagram.png`` -> ``fig_diagram``, ``diagram.svg`` -> ``fig_diagram_svg``;
    other files (``report.html``, ``corrections.json``) under their stem."""
    keys = {file: key for key, file in FILES.items()}
    path = Path(name)
    if name in keys:
        return keys[name]
    png = path.with_suffix(".png").name
    if path.suffix.lstrip(".") in FIGURE_FORMATS and png in keys:
        return f"{keys[png]}_{path.suffix.lstrip('.')}"
    return path.stem
