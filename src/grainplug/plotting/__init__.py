"""Figures (matplotlib, never pyplot in library code). matplotlib is imported when a
figure function is first used, so importing :mod:`grainplug.plotting.worker` stays cheap."""

from __future__ import annotations

import importlib

_FIGURES = ("plot_annotated_frame", "plot_diagram", "plot_spectrum")

__all__ = ["plot_annotated_frame", "plot_diagram", "plot_spectrum"]


def __getattr__(name: str) -> object:
    if name in _FIGURES:
        return getattr(importlib.import_module("grainplug.plotting.figures"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
