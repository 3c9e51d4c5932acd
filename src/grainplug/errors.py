"""User-facing errors.

Every problem the user can fix (a missing file, a corrupt movie, a nonsense
parameter) is raised as a :class:`GrainplugError` whose message is one line that
names the problem and the fix, in terms of the data and of the library's own
parameter names. The CLI prints that line (naming its flags where a parameter is
at fault) and exits non-zero; any other exception is a bug and is reported as such.
"""

from __future__ import annotations


class GrainplugError(Exception):
    """An error caused by the input or the parameters, with a one-line message."""

    #: the command line's exit status for it
    exit_code = 2


class PartialCampaignError(GrainplugError):
    """Some runs of a campaign failed; the others were analysed and written."""

    exit_code = 3


class CampaignInterrupted(KeyboardInterrupt):
    """A campaign stopped by Ctrl-C: every run is done or not started; the message says how many."""


class Interrupted(GrainplugError):
    """Ctrl-C, reported by the command line as one line with exit status 130."""

    exit_code = 130


class MovieError(GrainplugError):
    """A movie cannot be opened or decoded."""


class ParameterError(GrainplugError, ValueError):
    """A parameter is out of its meaningful range.

    Parameters
    ----------
    message : str
        What is wrong and how to fix it.
    param : str, optional
        The parameter at fault (a field of :class:`grainplug.AnalysisParams` or a
        keyword argument), so that a front end can name its own spelling of it.
    """

    def __init__(self, message: str, *, param: str | None = None) -> None:
        self.message = message
        self.param = param
        super().__init__(f"{param}: {message}" if param else message)


def non_finite_frames(which: str) -> MovieError:
    """The error for frames with NaN or infinite pixels (``which``: the frames, in words), with the fix."""
    return MovieError(f"{which} hold NaN or infinite pixels (masked or dead pixels?): give finite grey levels — "
                      "replace them first, e.g. with the frame's median (np.nan_to_num(frames, nan=...))")
