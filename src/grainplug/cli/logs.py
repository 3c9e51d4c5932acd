"""What reaches the user's terminal while a command runs: grainplug's own lines, and no other library's.

Libraries log on their own (tifffile's ``ERROR tifffile: <TiffPages @8> invalid page offset``, PyAV's
``libav.*``, dask's ``distributed.*``, numba). Without ``--debug`` none of their lines is printed: what
they said of the failure is kept (:attr:`CommandLog.heard`) and added to grainplug's one ``error:`` line
where it helps. grainplug's own log shows its errors only; ``--verbose`` shows it from INFO on,
``--debug`` shows everything.

The set-up lasts for one command (a context manager): the handler it adds and the levels it changes
are put back when the command ends, so calling :func:`grainplug.cli.main` twice in one process (a
notebook, the tests) leaves logging as it found it.
"""

from __future__ import annotations

import logging
import re
import sys
from collections import deque
from types import TracebackType

#: the most library lines kept to be quoted in an error line
HEARD_MAX = 5
#: the most characters of a library's line quoted
QUOTE_MAX = 160
#: loggers that print through handlers of their own (not the root's): silenced for the command unless --debug
OWN_HANDLER_LOGGERS = ("distributed", "bokeh", "tornado", "numba", "libav", "asyncio")


def is_ours(name: str) -> bool:
    """Whether a logger's name is grainplug's."""
    return name == "grainplug" or name.startswith("grainplug.")


class _Ours(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return is_ours(record.name)


class _Heard(logging.Handler):
    """Keeps the last few warnings and errors of other libraries, to quote in an error line."""

    def __init__(self, lines: deque[str]) -> None:
        super().__init__(level=logging.WARNING)
        self.lines = lines

    def emit(self, record: logging.LogRecord) -> None:
        if is_ours(record.name):
            return
        try:
            text = record.getMessage()
        except Exception:  # a library's malformed log call is not our failure
            return
        self.lines.append(f"{record.name.split('.')[0]}: {_plain(text)}")


def _plain(text: str) -> str:
    """A library's message as a user reads it: object reprs (``<tifffile.TiffPages @8>``) and spaces cut."""
    text = re.sub(r"<[\w.]+(?: [^<>]*)?>\s*", "", text)
    text = " ".join(text.split())
    return text if len(text) <= QUOTE_MAX else text[: QUOTE_MAX - 1] + "…"


class CommandLog:
    """Logging for one command: grainplug's lines on stderr at the level the flags ask, others' kept quiet.

    Parameters
    ----------
    debug : bool
        Every library's log at DEBUG (and the traceback, elsewhere).
    verbose : bool
        grainplug's own log at INFO.
    """

    def __init__(self, *, debug: bool = False, verbose: bool = False) -> None:
        self.debug = debug
        # grainplug's own log lines only with --verbose or --debug, and its errors: what the user must know reaches
        # them as the command's own `warning:` and `error:` lines
        self.level = logging.DEBUG if debug else logging.INFO if verbose else logging.ERROR
        self._lines: deque[str] = deque(maxlen=HEARD_MAX)
        self._handlers: list[logging.Handler] = []
        self._saved: list[tuple[logging.Logger, int, bool]] = []

    @property
    def heard(self) -> list[str]:
        """What other libraries warned of during the command (newest last), as ``library: message``."""
        return list(self._lines)

    def quote(self, message: str) -> str:
        """``message`` with what a library last said, where it adds something: ``... (tifffile: invalid page
        offset 256272)``."""
        for line in reversed(self._lines):
            said = line.split(": ", 1)[-1]
            if said and said not in message:
                return f"{message} ({line})"
        return message

    def __enter__(self) -> CommandLog:
        root = logging.getLogger()
        shown = logging.StreamHandler(sys.stderr)
        shown.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
        shown.setLevel(self.level)
        if not self.debug:
            shown.addFilter(_Ours())
        heard = _Heard(self._lines)
        self._handlers = [shown, heard]
        self._saved.append((root, root.level, root.disabled))
        root.setLevel(min(self.level, logging.WARNING))
        for h in self._handlers:
            root.addHandler(h)
        ours = logging.getLogger("grainplug")
        self._saved.append((ours, ours.level, ours.disabled))
        ours.setLevel(self.level)
        if not self.debug:
            for name in OWN_HANDLER_LOGGERS:  # they print through handlers of their own: quiet for the command
                lg = logging.getLogger(name)
                self._saved.append((lg, lg.level, lg.disabled))
                lg.setLevel(logging.CRITICAL + 1)
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        root = logging.getLogger()
        for h in self._handlers:
            root.removeHandler(h)
            h.close()
        for lg, level, disabled in reversed(self._saved):
            lg.setLevel(level)
            lg.disabled = disabled
        self._saved.clear()
