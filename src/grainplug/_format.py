"""Numbers as people read them."""

from __future__ import annotations

import math


def rounded(x: float | None, nd: int = 6) -> float | None:
    """``x`` rounded to ``nd`` decimals for JSON, None for a missing or non-finite one."""
    return None if x is None or not math.isfinite(x) else round(float(x), nd)


def signed(value: float, decimals: int) -> str:
    """``value`` with its sign and ``decimals`` decimals; one that rounds to zero has no sign (not ``-0.0000``)."""
    text = f"{value:+.{decimals}f}"
    return text[1:] if float(text) == 0.0 else text


def with_interval(value: float | None, lo: float | None, hi: float | None) -> tuple[str, str, str]:
    """A signed value and its interval, each to three significant digits, more where the interval's ends would
    read the same (a celerity known to 1e-5 m/s is not "-0.0500 to -0.0500"); "—" for a missing one."""
    digits = 3
    if isinstance(lo, float) and isinstance(hi, float):
        while digits < 8 and f"{lo:+#.{digits}g}" == f"{hi:+#.{digits}g}":
            digits += 1

    def one(v: float | None) -> str:
        return "—" if v is None else f"{v:+#.{digits}g}"

    return one(value), one(lo), one(hi)


def duration(seconds: float) -> str:
    """A record's duration to four significant digits: ``0.0005 s`` (a high-speed clip), ``2.35 s``, ``1235 s``
    (fixed decimals read 0.5 ms as 0.001 s)."""
    return f"{seconds:.4g} s" if abs(seconds) < 1e4 else f"{seconds:.0f} s"
