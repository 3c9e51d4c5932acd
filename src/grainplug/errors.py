"""User-facing errors.

Every problem the user can fix (a missing file, a corrupt movie, a nonsense
parameter) is raised as a :class:`GrainplugError` whose message is one line that
names the problem and the fix. The CLI prints that line and exits non-zero; any
other exception is a bug and is reported as such.
"""

from __future__ import annotations


class GrainplugError(Exception):
    """An error caused by the input or the parameters, with a one-line message."""


class MovieError(GrainplugError):
    """A movie cannot be opened or decoded."""


class ParameterError(GrainplugError, ValueError):
    """A parameter is out of its meaningful range."""
