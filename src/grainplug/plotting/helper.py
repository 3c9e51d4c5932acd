"""The figure helper process: ``python -m grainplug.plotting.helper``.

Started by :class:`grainplug.outputs.FigureWorker` before an analysis, it imports
matplotlib and renders some text once (the font cache) while the frames stream in
the parent, then reads one job from its standard input — a pickled
``(AnalysisResult, folder)`` — draws the figures into ``folder`` and writes a
pickled ``("ok", [paths])`` or ``("error", message)`` to its standard output.
"""

from __future__ import annotations

import io
import os
import pickle
import sys


def _yield_to_the_analysis() -> None:
    """Run only on cores the analysis leaves idle: its threads come first, and the
    figures are needed only at its end (SCHED_IDLE on Linux, else a lower priority)."""
    try:
        os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
        return
    except (AttributeError, OSError):
        pass
    try:
        os.nice(10)
    except (AttributeError, OSError):
        pass


def warm_up() -> None:
    """Import what drawing needs and draw once what the figures draw (an image, markers,
    lines, a legend, text at their sizes), so that the caches are filled before the job."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from .. import analysis, outputs  # noqa: F401 - unpickling the job needs them
    from . import figures  # noqa: F401 - what draws the job

    fig, ax = plt.subplots(figsize=(2, 2))
    ax.imshow(np.linspace(0, 1, 64, dtype=np.float32).reshape(8, 8), cmap="gray", interpolation="nearest",
              aspect="auto")
    ax.plot([0, 1], [0, 1], "s", ms=2.2, mfc="none", mec="orange", label="a")
    ax.plot([0, 1], [1, 0], "--", color="tab:red", label="b")
    ax.legend(loc="upper right", fontsize=7)
    ax.set_title("grainplug", fontsize=10)
    ax.set_xlabel("time (s)")
    fig.savefig(io.BytesIO(), format="png", dpi=20, pil_kwargs={"compress_level": 1})
    plt.close(fig)


def main() -> int:
    """Serve one job; the exit status is 0 when a reply was written."""
    reply_to = sys.stdout.buffer
    sys.stdout = sys.stderr  # nothing but the reply goes to the parent's pipe
    _yield_to_the_analysis()
    try:
        warm_up()
        res, folder = pickle.load(sys.stdin.buffer)
        from ..outputs import draw_figures

        # side by side: the analysis is over, its cores are free
        reply: tuple[str, object] = ("ok", [str(p) for p in draw_figures(res, folder, fork=True)])
    except EOFError:  # the parent went away or needs no figures
        return 0
    except Exception as exc:  # reported to the parent, which draws the figures itself
        reply = ("error", f"{type(exc).__name__}: {exc}")
    pickle.dump(reply, reply_to)
    reply_to.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
