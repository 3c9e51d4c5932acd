"""The tests' view of warnings: by their stable code (``grainplug.warning_codes``), not by their sentence.

A warning's sentence is for people and may be reworded; its code is what a program (and a test) selects it by.
Each helper takes a result (or a movie's ``info``), a list of warnings, or a saved ``summary.json`` (read as a
dict: its ``warnings`` with the parallel ``warning_codes``), and insists that every warning has a known code, so
that "no warning of that code" cannot pass because a warning lost its code.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from grainplug.warning_codes import CODES, code_of


def coded_pairs(source: object) -> list[tuple[str, str]]:
    """(sentence, code) for each warning of ``source``, in order; fails on a warning without a known code."""
    if isinstance(source, Mapping):  # a summary.json: the codes are a parallel list
        texts, codes_ = list(source["warnings"]), list(source["warning_codes"])
        assert len(texts) == len(codes_), source
        pairs = list(zip(texts, codes_, strict=True))
    else:
        texts = getattr(source, "warnings", source)
        assert isinstance(texts, Iterable) and not isinstance(texts, str), source
        pairs = [(w, code_of(w)) for w in texts]
    bad = [(w, c) for w, c in pairs if c not in CODES or c == "legacy.uncoded"]
    assert not bad, f"warnings without a code: {bad}"
    return pairs


def codes(source: object) -> set[str]:
    """The codes of ``source``'s warnings."""
    return {c for _, c in coded_pairs(source)}


def of_code(source: object, *wanted: str) -> list[str]:
    """``source``'s warnings (their sentences) whose code is one of ``wanted``, in order."""
    assert all(c in CODES for c in wanted), wanted  # a misspelt code would select nothing, and pass "not said"
    return [w for w, c in coded_pairs(source) if c in wanted]
