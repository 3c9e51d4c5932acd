"""JSON for grainplug's outputs: numpy scalars and arrays, paths; atomic writes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def default(obj: object) -> object:
    """``json.dumps(default=...)`` for numpy scalars and arrays and for paths."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj)}")


def strict(obj: object) -> object:
    """``obj`` with every NaN or infinity (Python or numpy, in arrays too) as ``None``: JSON has no such
    numbers, and a strict parser refuses the ``NaN`` that Python's ``json`` writes by default."""
    if isinstance(obj, float | np.floating):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: strict(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [strict(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return strict(obj.tolist())
    return obj


def dumps(data: object) -> str:
    """Indented, strict JSON text (no ``NaN``: see :func:`strict`) with a final newline."""
    return json.dumps(strict(data), indent=2, default=default, allow_nan=False) + "\n"


def write_json(path: str | Path, data: object) -> None:
    """Write JSON atomically (:func:`grainplug._atomic.atomic_file`)."""
    from ._atomic import atomic_file

    with atomic_file(path) as tmp:
        tmp.write_text(dumps(data))
