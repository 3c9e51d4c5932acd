"""Write an analysis to disk: summary, edges, tracks, diagram, figures, report.

Everything is written into a temporary folder inside the destination and moved
into place at the end, so an interrupted run never leaves half-written files.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import logging
import multiprocessing
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from pathlib import Path
from types import TracebackType

import numpy as np

from . import jsonio
from .analysis import AnalysisResult
from .diagram.extract import display_stride

log = logging.getLogger(__name__)

FILES = {
    "summary": "summary.json",
    "edges": "plug_edges.csv",
    "tracks": "tracks.csv",
    "diagram": "diagram.npz",
    "fig_diagram": "diagram.png",
    "fig_spectrum": "spectrum.png",
    "fig_frame": "frame.png",
}


def edges_table(res: AnalysisResult) -> str:
    """CSV of the plug edges per frame: frame, time_s, plug_id, top_mm, bottom_mm."""
    r = res.runs
    t = res.diagram.time_s[r.frame]

    def col(x: np.ndarray, fmt: str) -> np.ndarray:
        out = np.char.mod(fmt, x)
        out[~np.isfinite(x)] = ""
        return out

    rows = np.stack([r.frame.astype(str), np.char.mod("%.6f", t), res.tracks.run_track.astype(str),
                     col(r.top_mm, "%.4f"), col(r.bottom_mm, "%.4f")], axis=1) if len(r) else np.empty((0, 5), str)
    lines = [",".join(row) for row in rows.tolist()]
    return "frame,time_s,plug_id,top_mm,bottom_mm\n" + "".join(line + "\n" for line in lines)


def tracks_table(res: AnalysisResult) -> str:
    """CSV with one row per plug track."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["plug_id", "first_frame", "last_frame", "first_time_s", "last_time_s", "n_frames",
                "n_frames_whole", "celerity_m_s", "mean_length_mm", "median_length_mm",
                "started_by", "ended_by", "composite"])
    r, tr = res.runs, res.tracks
    t = res.diagram.time_s
    for tid in range(len(tr)):
        sel = tr.run_track == tid
        frames = r.frame[sel]
        top, bot = r.top_mm[sel], r.bottom_mm[sel]
        whole = np.isfinite(top) & np.isfinite(bot)
        edge = top if np.isfinite(top).sum() >= 2 else bot
        ok = np.isfinite(edge)
        cel = ""
        if ok.sum() >= 2 and np.ptp(t[frames[ok]]) > 0:
            cel = f"{np.polyfit(t[frames[ok]], edge[ok], 1)[0] / 1000:.6f}"
        lengths = (bot - top)[whole]
        w.writerow([
            tid, int(tr.first_frame[tid]), int(tr.last_frame[tid]), f"{t[tr.first_frame[tid]]:.6f}",
            f"{t[tr.last_frame[tid]]:.6f}", int(sel.sum()), int(whole.sum()), cel,
            f"{lengths.mean():.4f}" if lengths.size else "",
            f"{np.median(lengths):.4f}" if lengths.size else "",
            tr.started_by[tid], tr.ended_by[tid], int(tr.composite(tid)),
        ])
    return buf.getvalue()


def draw_figures(res: AnalysisResult, folder: str | Path) -> list[Path]:
    """Draw the figures of ``res`` as PNG files in ``folder`` (in this process)."""
    import matplotlib.pyplot as plt

    from .plotting import plot_annotated_frame, plot_diagram, plot_spectrum

    figs = {"fig_diagram": plot_diagram, "fig_frame": plot_annotated_frame}
    if res.motion is not None and res.motion.oscillation_frequency_hz:
        figs["fig_spectrum"] = plot_spectrum
    paths = []
    for key, plot in figs.items():
        fig = plot(res)
        paths.append(Path(folder) / FILES[key])
        # zlib level 1: a fraction of the default's time, files ~15% larger
        fig.savefig(paths[-1], dpi=110, pil_kwargs={"compress_level": 1})
        plt.close(fig)
    return paths


def figure_payload(res: AnalysisResult) -> AnalysisResult:
    """A copy of ``res`` holding only what the figures draw: the diagram thinned to
    display size (:func:`grainplug.diagram.extract.display_stride`), no contrast image.
    Small to send to another process, whatever the record's length."""
    st, ss = display_stride(res.diagram.values.shape)
    thin = dataclasses.replace(res.diagram, values=np.ascontiguousarray(res.diagram.values[::st, ::ss]))
    return dataclasses.replace(res, diagram=thin, normalized=None)


def _warm_up() -> None:
    """Helper process start-up: import matplotlib and render some text once (font cache)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from . import plotting  # noqa: F401

    fig, ax = plt.subplots(figsize=(1, 1))
    ax.set_title("grainplug")
    fig.savefig(io.BytesIO(), format="png", dpi=20)
    plt.close(fig)


def _ready() -> bool:
    return True


def _draw_remote(res: AnalysisResult, folder: str) -> list[str]:
    return [str(p) for p in draw_figures(res, folder)]


class FigureWorker:
    """Draws a run's figures in a helper process started before the analysis.

    matplotlib's import and first rendering (~0.5 s) then happen on another core
    while the frames stream, and the drawing overlaps the writing of the tables.
    Any failure of the helper (no process allowed, a crash, a result that cannot
    be sent) falls back to drawing in this process. Use as a context manager.

    Examples
    --------
    >>> with FigureWorker() as fw:                      # doctest: +SKIP
    ...     res = analyze("run.tif")
    ...     write_outputs(res, "out", figure_worker=fw)
    """

    def __init__(self) -> None:
        self._pool: ProcessPoolExecutor | None = None
        self._warm: Future | None = None
        try:
            self._pool = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"),
                                             initializer=_warm_up)
            self._warm = self._pool.submit(_ready)
        except (OSError, RuntimeError, ValueError) as exc:  # no helper: draw here
            log.debug("figure helper not started (%s); figures are drawn in this process", exc)
            self.close()

    def submit(self, res: AnalysisResult, folder: str | Path) -> Callable[[], list[Path]]:
        """Start drawing the figures of ``res`` into ``folder``; call the result to wait for them."""
        if self._pool is not None:
            try:
                fut = self._pool.submit(_draw_remote, figure_payload(res), str(folder))
            except Exception as exc:  # a helper that cannot take work: draw here
                return self._fallback(exc, res, folder)

            def wait() -> list[Path]:
                try:
                    return [Path(p) for p in fut.result()]
                except Exception as exc:  # any helper failure: draw here instead
                    return self._fallback(exc, res, folder)()

            return wait
        return lambda: draw_figures(res, folder)

    def _fallback(self, exc: Exception, res: AnalysisResult, folder: str | Path) -> Callable[[], list[Path]]:
        log.warning("figure helper failed (%s: %s); drawing in this process", type(exc).__name__, exc)
        self.close()
        return lambda: draw_figures(res, folder)

    def draw(self, res: AnalysisResult, folder: str | Path) -> list[Path]:
        """Draw the figures of ``res`` into ``folder``; returns when they are written."""
        return self.submit(res, folder)()

    def close(self) -> None:
        """Stop the helper (at once if it is still starting)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None

    def __enter__(self) -> FigureWorker:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


def write_outputs(res: AnalysisResult, out_dir: str | Path, *, figures: bool = True,
                  report: bool = True, extra: dict | None = None,
                  figure_worker: FigureWorker | None = None) -> dict[str, Path]:
    """Write every output of ``res`` into ``out_dir``; returns the paths written.

    ``extra`` is merged into ``summary.json`` (e.g. the campaign's run key).
    ``figure_worker`` draws the figures in a helper process (see :class:`FigureWorker`).
    """
    t_write = time.perf_counter()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".grainplug-", dir=out))
    written: dict[str, Path] = {}
    figures_done: Callable[[], list[Path]] | None = None
    try:
        summary = res.summary
        summary.update(extra or {})
        summary["outputs"] = {k: v for k, v in FILES.items()
                              if k != "fig_spectrum" or (res.motion and res.motion.oscillation_frequency_hz)}
        if figures:  # drawn meanwhile in the helper process, if any
            figures_done = (figure_worker.submit(res, tmp) if figure_worker is not None
                            else lambda: draw_figures(res, tmp))
        (tmp / FILES["edges"]).write_text(edges_table(res))
        (tmp / FILES["tracks"]).write_text(tracks_table(res))
        with open(tmp / FILES["diagram"], "wb") as fh:
            np.savez(  # uncompressed: float noise barely compresses, and this is fast
                fh, values=res.diagram.values, contrast=res.normalized.z, time_s=res.diagram.time_s,
                position_mm=res.diagram.position_mm, mm_per_px=res.mm_per_px,
                provenance=json.dumps({"grainplug_version": summary["grainplug_version"],
                                       "input": summary["input"], "parameters": summary["parameters"]},
                                      default=jsonio.default),
            )
        if figures_done is not None:
            pending, figures_done = figures_done, None
            pending()
        if report:
            from .reports import run_report

            (tmp / "report.html").write_text(run_report(res, tmp))
        summary["timings_s"]["write_s"] = round(time.perf_counter() - t_write, 4)
        (tmp / FILES["summary"]).write_text(jsonio.dumps(summary))
        for f in sorted(tmp.iterdir()):
            dest = out / f.name
            os.replace(f, dest)
            written[f.stem if f.suffix != ".png" else "fig_" + f.stem] = dest
    finally:
        if figures_done is not None:  # failed meanwhile: let the helper finish before cleaning up
            try:
                figures_done()
            except Exception:  # the first error is the one reported
                log.debug("figures abandoned after an error", exc_info=True)
        shutil.rmtree(tmp, ignore_errors=True)
    return written
