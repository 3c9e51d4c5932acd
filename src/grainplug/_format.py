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


def oscillation_phrase(frequency_hz: float, frequency_ci95_hz: tuple[float, float] | list[float] | None,
                       amplitude_mm: float | None, amplitude_ci95_mm: tuple[float, float] | list[float] | None,
                       kind: str | None = None, stick_fraction: float | None = None) -> str:
    """One line for an oscillation: ``4.000 Hz (95% CI 3.998 to 4.002), amplitude 2.37 mm (95% CI 2.36 to 2.38,
    half peak-to-peak), stick-slip (still 60 % of the period)``; the intervals and the kind left out when
    missing, the digits enough to tell an interval's ends apart."""

    def plain(value: float, ci: tuple[float, float] | list[float] | None, decimals: int) -> str:
        if not ci or None in ci:
            return f"{value:.{decimals}f}"
        while decimals < 6 and f"{ci[0]:.{decimals}f}" == f"{ci[1]:.{decimals}f}":
            decimals += 1
        return f"{value:.{decimals}f} (95% CI {ci[0]:.{decimals}f} to {ci[1]:.{decimals}f}"

    f_text = plain(frequency_hz, frequency_ci95_hz, 2)
    f_text = f_text.replace(" (95% CI", " Hz (95% CI") + ")" if "CI" in f_text else f_text + " Hz"
    out = f_text
    if amplitude_mm is not None:
        a_text = plain(amplitude_mm, amplitude_ci95_mm, 2)
        a_text = (a_text.replace(" (95% CI", " mm (95% CI") + ", half peak-to-peak)" if "CI" in a_text
                  else a_text + " mm (half peak-to-peak)")
        out += f", amplitude {a_text}"
    if kind:
        out += f", {kind}" + (f" (still {100 * stick_fraction:.0f} % of the period)"
                              if stick_fraction is not None else "")
    return out
