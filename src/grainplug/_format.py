"""Numbers as people read them."""

from __future__ import annotations


def signed(value: float, decimals: int) -> str:
    """``value`` with its sign and ``decimals`` decimals; one that rounds to zero has no sign (not ``-0.0000``)."""
    text = f"{value:+.{decimals}f}"
    return text[1:] if float(text) == 0.0 else text
