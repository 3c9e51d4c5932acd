"""The ``grainplug`` command line: a thin layer over the library.

Errors the user can fix print one line (``error: ...``) and exit with status 2;
``--debug`` shows the traceback instead.
"""

from __future__ import annotations

import logging
import os
import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .._system import ReadAhead

log = logging.getLogger("grainplug")


def _early_readahead(args: list[str]) -> list[ReadAhead]:
    """For ``analyze``: ask the disk for the movie before the heavy imports (numpy, scipy...).

    The reads then overlap the interpreter's start-up; the analysis asks again, in
    a window that follows its stream (:meth:`grainplug.readers.base.Movie.prefetch`).
    Only a hint: every argument that names a regular file is asked for, up to half
    of the free memory, by a background thread; nothing is read here.
    """
    if "analyze" not in args or not hasattr(os, "posix_fadvise"):
        return []
    from .._system import READAHEAD_MEMORY_SHARE, ReadAhead, free_memory_bytes

    budget = free_memory_bytes() * READAHEAD_MEMORY_SHARE
    return [ReadAhead(arg, budget) for arg in args[args.index("analyze") + 1:]
            if not arg.startswith("-") and os.path.isfile(arg)]


#: thread pools of the BLAS libraries numpy and scipy may load
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS")


def _single_threaded_blas() -> None:
    """Run BLAS on one thread, unless the user's environment says otherwise.

    grainplug's linear algebra is small (least squares on a few hundred plug edges,
    eigenvalues of 3x3 matrices): a BLAS thread pool only adds wake-up latency to
    it, and competes with the reading threads, the figure helper and, under
    ``batch --workers``, the other runs (measured: the drift fits of a run took
    0.02-0.18 s with OpenBLAS's pool on 2 cores, 0.02-0.03 s without). Set before
    numpy is imported; inherited by the helper and worker processes.
    """
    for name in BLAS_THREAD_VARIABLES:
        os.environ.setdefault(name, "1")


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script; returns the exit status."""
    args = list(sys.argv[1:] if argv is None else argv)
    if "numpy" not in sys.modules:  # too late otherwise: the pools exist
        _single_threaded_blas()
    readahead = _early_readahead(args)
    try:
        return _main(args)
    finally:
        for ra in readahead:
            ra.close()


def _main(args: list[str]) -> int:
    import click

    from ..errors import GrainplugError
    from .app import cli

    debug = "--debug" in args
    try:
        cli.main(args=args, prog_name="grainplug", standalone_mode=False)
    except click.exceptions.Exit as exc:
        return int(exc.exit_code or 0)
    except click.exceptions.Abort:
        click.echo("error: interrupted", err=True)
        return 130
    except click.UsageError as exc:
        if debug:
            raise
        where = f"grainplug {exc.ctx.info_name}" if exc.ctx and exc.ctx.parent else "grainplug"
        hint = f" (see '{where} --help')"
        click.echo(f"error: {exc.format_message()}{hint}", err=True)
        return 2
    except GrainplugError as exc:
        if debug:
            raise
        click.echo(f"error: {exc}", err=True)
        return 2
    except KeyboardInterrupt:
        click.echo("error: interrupted", err=True)
        return 130
    except Exception as exc:  # a bug: say so in one line, traceback with --debug
        if debug:
            raise
        click.echo(
            f"error: unexpected {type(exc).__name__}: {exc} — rerun with --debug and report it",
            err=True,
        )
        return 1
    return 0


def run() -> None:  # pragma: no cover - console script wrapper
    sys.exit(main())
