"""A spawned process that draws an analysis's figures: ``python -m grainplug.plotting.worker``.

Importing matplotlib and drawing the first figure costs ~0.5 s, as much as the whole
analysis of a short movie. :class:`FigureWorker` starts a fresh interpreter (spawned,
never forked) before the analysis; it imports matplotlib and warms up its renderer, in
each figure format the parent will ask for, on the other core while the frames stream,
then draws the figures while the parent writes the tables (measured in
docs/performance.md: a 40-frame movie end to end 1.35 -> 1.08 s). A second helper, to
draw the figures two at a time, was measured slower on two cores: its imports take the
CPU that the analysis leaves idle. The parent owns the helper: a context manager that
always stops and reaps the process, and falls back to drawing in-process on any failure
of the helper.

Protocol: the parent writes a line naming the formats to warm up (``png,svg,pdf``), then
one pickled ``(AnalysisResult, folder, FigureOptions)``, to the worker's standard input;
the worker answers with a pickled ``("ok", [paths])`` or ``("error", message)`` on its
standard output.
"""

from __future__ import annotations

import dataclasses
import io
import logging
import os
import pickle
import subprocess
import sys
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..result import AnalysisResult
    from .options import FigureOptions

log = logging.getLogger(__name__)


def figure_payload(res: AnalysisResult) -> AnalysisResult:
    """A copy of ``res`` holding only what the figures draw: the diagram thinned to
    display size, no contrast image. Small to send, whatever the record's length."""
    import numpy as np

    from ..diagram import display_stride

    st, ss = display_stride(res.diagram.values.shape)
    thin = dataclasses.replace(res.diagram, values=np.ascontiguousarray(res.diagram.values[::st, ::ss]))
    return dataclasses.replace(res, diagram=thin, normalized=None)


class FigureWorker:
    """Draws a run's figures in a spawned helper process started before the analysis.

    Use as a context manager; :meth:`submit` returns a function that waits for the
    figures. Any failure of the helper (no process allowed, a crash, a result that
    cannot be sent) falls back to :func:`grainplug.plotting.files.draw_figures` in this process.

    Parameters
    ----------
    formats : sequence of str
        The figure formats the job will ask for: the helper warms up their writers while
        it waits (the first PDF of a process costs ~0.1 s more than the next).
    preload : sequence of str
        Modules the job's objects are defined in (``"grainplug.result"``): the helper imports
        them while it waits, so that unpickling the job costs nothing then.

    Examples
    --------
    >>> with FigureWorker() as fw:                      # doctest: +SKIP
    ...     res = gp.analyze("run.tif")
    ...     write_outputs(res, "out", figure_worker=fw)
    """

    def __init__(self, formats: Sequence[str] = ("png",), *, preload: Sequence[str] = ()) -> None:
        import grainplug

        # the child's environment only: a headless backend, and this very grainplug on its path
        env = dict(os.environ, MPLBACKEND="Agg")
        root = str(Path(grainplug.__file__).resolve().parent.parent)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [root, env.get("PYTHONPATH")]))
        self._proc: subprocess.Popen | None = None
        self._sender: threading.Thread | None = None
        try:
            self._proc = subprocess.Popen([sys.executable, "-m", "grainplug.plotting.worker"],
                                          stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                          stderr=subprocess.DEVNULL, env=env)
            # a few bytes: never blocks
            self._proc.stdin.write((",".join(formats) + "|" + ",".join(preload) + "\n").encode())
            self._proc.stdin.flush()
        except OSError as exc:
            log.debug("figure worker not started (%s); figures are drawn in this process", exc)

    @property
    def running(self) -> bool:
        """Whether a helper process is there to take the job."""
        return self._proc is not None and self._proc.poll() is None

    def submit(self, res: AnalysisResult, folder: str | Path,
               options: FigureOptions | None = None) -> Callable[[], list[Path]]:
        """Start drawing the figures of ``res`` into ``folder``; call the result to wait for them."""
        from .files import draw_figures

        if not self.running:
            self.close()
            return lambda: draw_figures(res, folder, options)
        proc = self._proc
        try:
            job = pickle.dumps((figure_payload(res), str(folder), options), protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:  # a result that cannot be sent: draw here
            return self._fallback(exc, res, folder, options)
        failed: list[BaseException] = []

        def send() -> None:  # in a thread: the helper may still be importing matplotlib
            try:
                proc.stdin.write(job)
                proc.stdin.close()
            except OSError as exc:
                failed.append(exc)

        self._sender = threading.Thread(target=send, name="grainplug-figures")
        self._sender.start()

        def wait() -> list[Path]:
            self._sender.join()
            try:
                status, value = pickle.load(proc.stdout)
            except Exception as exc:  # the helper died or said nothing
                return self._fallback(failed[0] if failed else exc, res, folder, options)()
            self.close()
            if status != "ok":
                return self._fallback(RuntimeError(value), res, folder, options)()
            return [Path(p) for p in value]

        return wait

    def _fallback(self, exc: BaseException, res: AnalysisResult, folder: str | Path,
                  options: FigureOptions | None = None) -> Callable[[], list[Path]]:
        from .files import draw_figures

        log.warning("figure worker failed (%s: %s); drawing in this process", type(exc).__name__, exc)
        self.close()
        return lambda: draw_figures(res, folder, options)

    def close(self) -> None:
        """Stop the helper and reap it (its reply, if any, has been read)."""
        proc, self._proc = self._proc, None
        if proc is not None:
            if proc.poll() is None:
                proc.kill()
            for pipe in (proc.stdin, proc.stdout):
                try:
                    pipe.close()
                except OSError:
                    pass
            proc.wait()
        sender, self._sender = self._sender, None
        if sender is not None:
            sender.join()  # the pipe is closed: the write has returned or failed

    def __enter__(self) -> FigureWorker:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


def _warm_up(formats: Sequence[str] = ("png",), preload: Sequence[str] = ()) -> None:
    """Import what drawing needs (and the modules of ``preload``, which unpickling the job needs) and draw
    once what the figures draw (an image, markers, lines, a legend, text at their sizes) in each of
    ``formats``, so that the caches are filled before the job."""
    import importlib

    import numpy as np

    from . import figures  # noqa: F401 - what draw_figures draws with
    from ._figure import new_figure

    for name in preload:
        if name.startswith("grainplug."):  # only this package's modules, named by the parent
            importlib.import_module(name)

    fig, ax = new_figure(figsize=(2, 2))
    ax.imshow(np.linspace(0, 1, 64, dtype=np.float32).reshape(8, 8), cmap="gray", interpolation="nearest",
              aspect="auto")
    ax.plot([0, 1], [0, 1], "s", ms=2.2, mfc="none", mec="orange", label="a")
    ax.plot([0, 1], [1, 0], "--", color="tab:red", label="b")
    ax.legend(loc="upper right", fontsize=7)
    ax.set_title("grainplug", fontsize=10)
    ax.set_xlabel("time (s)")
    for fmt in formats:
        fig.savefig(io.BytesIO(), format=fmt, dpi=20, **({"pil_kwargs": {"compress_level": 1}} if fmt == "png" else {}))


def _yield_to_the_analysis() -> None:
    """Run only on cores the analysis leaves idle (SCHED_IDLE on Linux, else a lower priority):
    the figures are needed only at its end."""
    try:
        os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
        return
    except (AttributeError, OSError):
        pass
    try:
        os.nice(10)
    except (AttributeError, OSError):
        pass


def main() -> int:
    """Serve one job; the exit status is 0 when a reply was written or none was asked for."""
    reply_to = sys.stdout.buffer
    sys.stdout = sys.stderr  # nothing but the reply goes to the parent's pipe
    _yield_to_the_analysis()
    try:
        first, _, modules = sys.stdin.buffer.readline().decode("ascii", "replace").strip().partition("|")
        formats = first.split(",")
        _warm_up([f for f in formats if f in ("png", "svg", "pdf")] or ["png"], [m for m in modules.split(",") if m])
        res, folder, options = pickle.load(sys.stdin.buffer)
        from .files import draw_figures

        reply: tuple[str, object] = ("ok", [str(p) for p in draw_figures(res, folder, options)])
    except EOFError:  # the parent went away or needs no figures
        return 0
    except Exception as exc:  # reported to the parent, which draws the figures itself
        reply = ("error", f"{type(exc).__name__}: {exc}")
    pickle.dump(reply, reply_to)
    reply_to.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
