"""Click types that check numbers at the door: finite, and within a range that says why."""

from __future__ import annotations

import math

import click


class Number(click.ParamType):
    """A finite number, optionally within ``[lo, hi]``, with the unit in the message.

    ``Number(1, 1e7, unit="frames per second")`` refuses ``inf``, ``nan``, ``0`` and
    ``1e12`` with "must be between 1 and 1e+07 frames per second, got 1e12".
    """

    name = "number"

    def __init__(self, lo: float | None = None, hi: float | None = None, *, unit: str = "",
                 integer: bool = False) -> None:
        self.lo, self.hi, self.unit, self.integer = lo, hi, unit, integer
        self.name = "integer" if integer else "number"

    def convert(self, value: object, param: click.Parameter | None, ctx: click.Context | None) -> float | int:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            x = float(value)
        else:
            try:
                x = float(str(value).strip())
            except ValueError:
                self.fail(f"{value!r} is not a number", param, ctx)
        if not math.isfinite(x):
            self.fail(f"must be a finite number, got {value}", param, ctx)
        if self.integer and x != int(x):
            self.fail(f"must be a whole number, got {value}", param, ctx)
        unit = f" {self.unit}" if self.unit else ""
        if (self.lo is not None and x < self.lo) or (self.hi is not None and x > self.hi):
            if self.lo is not None and self.hi is not None:
                self.fail(f"must be between {self.lo:g} and {self.hi:g}{unit}, got {value}", param, ctx)
            bound = f"at least {self.lo:g}" if self.lo is not None else f"at most {self.hi:g}"
            self.fail(f"must be {bound}{unit}, got {value}", param, ctx)
        return int(x) if self.integer else x


#: any finite number
FINITE = Number()


def param_number(name: str) -> Number:
    """The option type of an analysis parameter, with its range from :data:`grainplug.params.RANGES`."""
    from ..params import RANGES

    r = RANGES[name]
    return Number(r.lo, r.hi, unit=r.unit, integer=r.integer)


class FrameOrTime(click.ParamType):
    """A point of a movie: a frame number (``120``) or a time in seconds (``2.5s``).

    Converts to ``("frame", int)`` or ``("s", float)``.
    """

    name = "frame|seconds"

    def convert(self, value: object, param: click.Parameter | None, ctx: click.Context | None) -> tuple[str, float]:
        if isinstance(value, tuple):
            return value
        text = str(value).strip().lower()
        try:
            if text.endswith("s"):
                x = float(text[:-1])
                if not (math.isfinite(x) and x >= 0):
                    raise ValueError
                return ("s", x)
            k = int(text)
            if k < 0:
                raise ValueError
            return ("frame", k)
        except ValueError:
            self.fail(f"{value!r} is neither a frame number (e.g. 120) nor a time in seconds (e.g. 2.5s)", param, ctx)


FRAME_OR_TIME = FrameOrTime()
