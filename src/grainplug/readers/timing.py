"""When each frame was taken: the movie's rate, or the file's own time stamps where they are uneven."""

from __future__ import annotations

import numpy as np

from ..warning_codes import coded
from .base import Movie, MovieInfo

#: how far (in frame periods) time stamps may stray from a constant rate and still be its rounding
EVEN_TIMES_PERIODS = 0.25

#: ... or in seconds: Matroska stores times in whole milliseconds (16 and 17 ms apart at 60 fps)
EVEN_TIMES_S = 0.0006

def uneven(stamps: np.ndarray) -> bool:
    """Whether a file's frame times stray from a constant rate by more than their rounding (then they time the
    frames; else ``index / fps`` does)."""
    stamps = np.asarray(stamps, float)
    n = len(stamps)
    if n < 3:
        return False
    k = np.arange(n)
    slope, intercept = np.polyfit(k, stamps, 1)
    stray = float(np.max(np.abs(stamps - (intercept + slope * k))))
    period = float(np.median(np.diff(stamps)))
    return stray > max(EVEN_TIMES_PERIODS * period, EVEN_TIMES_S)

def timing_stamps(movie: Movie, info: MovieInfo) -> np.ndarray | None:
    """The file's own frame times (s) where they time the frames: recorded, the rate the file's own, and uneven
    (:func:`uneven`); else None, and ``index / fps`` times them."""
    if not (movie.has_file_timestamps and info.fps_source == "file"):
        return None
    stamps = np.asarray(movie.timestamps_s(), float)  # recorded while streaming, for video
    return stamps if uneven(stamps) else None

def frame_times(movie: Movie, info: MovieInfo, n: int) -> tuple[np.ndarray, list[str]]:
    """Time of each frame, and a warning when the file's own times are unevenly spaced.

    Where the file records a time for each frame and they keep to a constant rate within their rounding,
    the rate's times (``index / fps``: exact, where whole-millisecond stamps of a 2000 fps movie are not);
    where they stray from it (a variable frame rate, dropped frames), the file's times, with a warning.
    """
    stamps = timing_stamps(movie, info)
    if stamps is None or len(stamps) != n:
        return (np.arange(n) + movie.first_frame_index) / info.fps, []
    dt = np.diff(stamps)
    return stamps, [coded("time.uneven",
        f"the frames are not evenly spaced in time ({1000 * dt.min():.3g} to {1000 * dt.max():.3g} ms "
        "apart): the file's own time stamps are used, but a high-speed camera records at a constant "
        "rate — check how the file was made (re-encoded, frames dropped?), or give fps= to time the "
        "frames by their number")]
