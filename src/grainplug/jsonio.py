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


def dumps(data: object) -> str:
    """Indented JSON text with a final newline."""
    return json.dumps(data, indent=2, default=default) + "\n"


def write_json(path: str | Path, data: object) -> None:
    """Write JSON atomically (:func:`grainplug._atomic.atomic_file`)."""
    from ._atomic import atomic_file

    with atomic_file(path) as tmp:
        tmp.write_text(dumps(data))
