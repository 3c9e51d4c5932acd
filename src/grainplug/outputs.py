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
import os
import pickle
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
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


def _figures_of(res: AnalysisResult) -> list[str]:
    """The figures a result has: the diagram, the annotated frame, the spectrum when it oscillates."""
    keys = ["fig_diagram", "fig_frame"]
    if res.motion is not None and res.motion.oscillation_frequency_hz:
        keys.append("fig_spectrum")
    return keys


def _draw_one(res: AnalysisResult, folder: str | Path, key: str) -> Path:
    import matplotlib.pyplot as plt

    from .plotting import plot_annotated_frame, plot_diagram, plot_spectrum

    plot = {"fig_diagram": plot_diagram, "fig_frame": plot_annotated_frame, "fig_spectrum": plot_spectrum}[key]
    fig = plot(res)
    path = Path(folder) / FILES[key]
    # zlib level 1: a fraction of the default's time, files ~15% larger
    fig.savefig(path, dpi=110, pil_kwargs={"compress_level": 1})
    plt.close(fig)
    return path


def draw_figures(res: AnalysisResult, folder: str | Path, *, fork: bool = False) -> list[Path]:
    """Draw the figures of ``res`` as PNG files in ``folder``.

    With ``fork`` (the figure helper, a process without threads, on Linux) every
    figure but the first is drawn in a forked child, so that they are drawn side
    by side on the idle cores; the call returns when all are written and raises
    if a child failed. Otherwise they are drawn one after the other, in this process.
    """
    keys = _figures_of(res)
    # Linux only: on macOS system frameworks are not safe to use in a forked child
    if not (fork and sys.platform.startswith("linux") and len(keys) > 1):
        return [_draw_one(res, folder, key) for key in keys]
    children = []
    for key in keys[1:]:
        pid = os.fork()
        if pid == 0:  # the child draws one figure and leaves without any clean-up of the parent's
            code = 1
            try:
                _draw_one(res, folder, key)
                code = 0
            finally:
                os._exit(code)
        children.append((pid, key))
    paths = [_draw_one(res, folder, keys[0])]
    failed = []
    for pid, key in children:
        _, status = os.waitpid(pid, 0)
        if os.waitstatus_to_exitcode(status) != 0:
            failed.append(FILES[key])
        paths.append(Path(folder) / FILES[key])
    if failed:
        raise RuntimeError(f"drawing {', '.join(failed)} failed")
    return paths


def figure_payload(res: AnalysisResult) -> AnalysisResult:
    """A copy of ``res`` holding only what the figures draw: the diagram thinned to
    display size (:func:`grainplug.diagram.extract.display_stride`), no contrast image.
    Small to send to another process, whatever the record's length."""
    st, ss = display_stride(res.diagram.values.shape)
    thin = dataclasses.replace(res.diagram, values=np.ascontiguousarray(res.diagram.values[::st, ::ss]))
    return dataclasses.replace(res, diagram=thin, normalized=None)


class FigureWorker:
    """Draws a run's figures in a helper process started before the analysis.

    The helper (``python -m grainplug.plotting.helper``, a fresh interpreter)
    imports matplotlib and warms up its renderer (~0.5 s) on another core while
    the frames stream; the drawing then overlaps the writing of the tables. Any
    failure of the helper (no process allowed, a crash, a result that cannot be
    sent) falls back to drawing in this process. Use as a context manager.

    Examples
    --------
    >>> with FigureWorker() as fw:                      # doctest: +SKIP
    ...     res = analyze("run.tif")
    ...     write_outputs(res, "out", figure_worker=fw)
    """

    def __init__(self) -> None:
        import grainplug

        env = dict(os.environ, MPLBACKEND="Agg")
        # the helper imports this very grainplug, installed or not
        root = str(Path(grainplug.__file__).resolve().parent.parent)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [root, env.get("PYTHONPATH")]))
        self._proc: subprocess.Popen | None = None
        try:
            self._proc = subprocess.Popen([sys.executable, "-m", "grainplug.plotting.helper"],
                                          stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                          stderr=subprocess.DEVNULL, env=env)
        except OSError as exc:  # no helper: draw here
            log.debug("figure helper not started (%s); figures are drawn in this process", exc)

    @property
    def running(self) -> bool:
        """Whether a helper process is there to take the job."""
        return self._proc is not None and self._proc.poll() is None

    def submit(self, res: AnalysisResult, folder: str | Path) -> Callable[[], list[Path]]:
        """Start drawing the figures of ``res`` into ``folder``; call the result to wait for them."""
        if not self.running:
            self.close()
            return lambda: draw_figures(res, folder)
        proc = self._proc
        try:
            job = pickle.dumps((figure_payload(res), str(folder)), protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:  # a result that cannot be sent: draw here
            return self._fallback(exc, res, folder)
        sent: list[BaseException] = []

        def send() -> None:  # in a thread: the helper may still be importing matplotlib
            try:
                proc.stdin.write(job)
                proc.stdin.close()
            except OSError as exc:
                sent.append(exc)

        sender = threading.Thread(target=send, name="grainplug-figures", daemon=True)
        sender.start()

        def wait() -> list[Path]:
            sender.join()
            try:
                status, value = pickle.load(proc.stdout)
            except Exception as exc:  # the helper died or said nothing
                return self._fallback(sent[0] if sent else exc, res, folder)()
            self.close()
            if status != "ok":
                return self._fallback(RuntimeError(value), res, folder)()
            return [Path(p) for p in value]

        return wait

    def _fallback(self, exc: BaseException, res: AnalysisResult, folder: str | Path) -> Callable[[], list[Path]]:
        log.warning("figure helper failed (%s: %s); drawing in this process", type(exc).__name__, exc)
        self.close()
        return lambda: draw_figures(res, folder)

    def draw(self, res: AnalysisResult, folder: str | Path) -> list[Path]:
        """Draw the figures of ``res`` into ``folder``; returns when they are written."""
        return self.submit(res, folder)()

    def close(self) -> None:
        """Stop the helper: its reply, if any, has been read; it is not waited for otherwise."""
        proc, self._proc = self._proc, None
        if proc is None:
            return
        if proc.poll() is None:
            proc.kill()
        for pipe in (proc.stdin, proc.stdout):
            try:
                pipe.close()
            except OSError:
                pass
        proc.wait()

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
        figures_of = _figures_of(res)
        summary["outputs"] = {k: v for k, v in FILES.items() if not k.startswith("fig_") or k in figures_of}
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
        if figures_done is not None and figure_worker is not None:
            figure_worker.close()  # failed meanwhile: stop the helper before its folder goes
        shutil.rmtree(tmp, ignore_errors=True)
    return written
