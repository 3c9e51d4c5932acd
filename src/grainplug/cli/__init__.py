"""The ``grainplug`` command line: a thin layer over the library.

Errors the user can fix print one line (``error: ...``) and exit with status 2;
``--debug`` shows the traceback instead. Exit statuses: 0 done, 1 an internal error
(a bug: please report it), 2 bad input or a place that cannot be written, 3 a
campaign with failed runs, 130 interrupted. Without ``--verbose`` or ``--debug``,
library log lines and numpy's warnings are not shown.
"""

from __future__ import annotations

import errno
import logging
import sys
import warnings
from pathlib import Path

log = logging.getLogger("grainplug")

#: the longest file name most file systems take, bytes
NAME_MAX = 255


def shorten(text: str, keep: int = 60) -> str:
    """``text`` cut in its middle to about ``keep`` characters (a path of thousands of characters in one line)."""
    return text if len(text) <= keep else f"{text[:keep // 2]}…{text[-keep // 2:]}"


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script; returns the exit status."""
    return _main(list(sys.argv[1:] if argv is None else argv))


def _main(args: list[str]) -> int:
    import click

    from ..errors import GrainplugError, Interrupted, MovieError, ParameterError
    from .app import cli
    from .logs import CommandLog
    from .words import ALIASES, as_flags, option_flags

    debug = "--debug" in args
    verbose = bool({"--verbose", "-v"} & set(args))
    quiet = not (debug or verbose)
    logs = CommandLog(debug=debug, verbose=verbose)  # only grainplug speaks on stderr unless --debug
    try:
        with warnings.catch_warnings(), logs:
            if quiet:  # numpy's and libraries' warnings are not the user's business; --verbose shows them
                warnings.simplefilter("ignore")
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
    except ParameterError as exc:
        if debug:
            raise
        # the library names its own parameters; say which flag that is
        flags = option_flags(cli)
        name = ALIASES.get(exc.param or "", exc.param)
        flag = flags[name][0] if name in flags else f"--{name.replace('_', '-')}" if name else None
        where = f"{flag}: " if flag and name != "source" else ""
        click.echo(f"error: {where}{as_flags(exc.message, flags)}", err=True)
        return 2
    except GrainplugError as exc:
        if debug and not isinstance(exc, Interrupted):  # Ctrl-C is no bug: one line even with --debug
            raise
        # what a library said of a file it could not read goes with grainplug's line about that file
        text = logs.quote(str(exc)) if isinstance(exc, MovieError) else str(exc)
        click.echo(f"error: {as_flags(text, option_flags(cli))}", err=True)
        return exc.exit_code
    except KeyboardInterrupt:
        click.echo("error: interrupted", err=True)
        return 130
    except SystemError as exc:
        # Ctrl-C inside a compiled (numba) function surfaces as "returned a result with an exception set"
        if isinstance(exc.__cause__, KeyboardInterrupt) or isinstance(exc.__context__, KeyboardInterrupt):
            click.echo("error: interrupted", err=True)
            return 130
        if debug:
            raise
        click.echo(f"error: unexpected SystemError: {exc} — rerun with --debug and report it", err=True)
        return 1
    except OSError as exc:
        if debug:
            raise
        if exc.errno == errno.ENAMETOOLONG:  # a path the system cannot take, whichever command met it
            name = Path(str(exc.filename or "")).name
            click.echo(f"error: {shorten(str(exc.filename or 'a name'))}: the name is too long for the file "
                       f"system ({len(name.encode())} bytes, at most {NAME_MAX}) — give a shorter name", err=True)
            return 2
        click.echo(f"error: unexpected OSError: {logs.quote(str(exc))} — rerun with --debug and report it", err=True)
        return 1
    except Exception as exc:  # a bug: say so in one line, traceback with --debug
        if debug:
            raise
        click.echo(
            f"error: unexpected {type(exc).__name__}: {logs.quote(str(exc))} — rerun with --debug and report it",
            err=True,
        )
        return 1
    return 0


def run() -> None:  # pragma: no cover - console script wrapper
    """The console script: :func:`main`, then exit without the final garbage collection."""
    status = main()
    # the process ends here: the interpreter's last collection would walk every object to free memory the
    # system takes back anyway (60 ms of a 40-frame run, docs/performance.md). Files are closed and outputs
    # renamed into place by then; frozen objects are still finalised by reference counting.
    import gc

    gc.freeze()
    sys.exit(status)
