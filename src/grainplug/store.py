"""A whole :class:`~grainplug.result.AnalysisResult` in one file, and back.

``result.npz`` holds every array of the result under its path in the result
(``"diagram.values"``, ``"runs.top_mm"``...) and, under ``"__tree__"``, a JSON
description of everything else: scalars, strings, lists, and which dataclass
each part is. Nothing is pickled (the file is read with ``allow_pickle=False``),
so a result file cannot run code and stays readable with numpy alone.
"""

from __future__ import annotations

import dataclasses
import json
import zipfile
import zlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .errors import GrainplugError
from .warning_codes import CODES, CodedWarning

#: version of the layout of ``result.npz`` (4: arrays written in another file of the folder, the diagram and its
#: contrast in ``diagram.npz``, are read from there, not held twice; 3: warnings keep their codes; 2: corrections
#: keep where their tracks were; 1 to 3 are read too, the first two's warnings as uncoded text)
FORMAT_VERSION = 4
RESULT_FILE = "result.npz"


def _encode(obj: Any, path: str, arrays: dict[str, np.ndarray]) -> Any:
    if isinstance(obj, np.ndarray):
        arrays[path] = obj
        return {"__array__": path}
    if isinstance(obj, CodedWarning):
        return {"__warning__": [obj.code, str(obj)]}
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        out = {"__type__": type(obj).__name__}
        for f in dataclasses.fields(obj):
            out[f.name] = _encode(getattr(obj, f.name), f"{path}.{f.name}" if path else f.name, arrays)
        return out
    if isinstance(obj, tuple):
        return {"__tuple__": [_encode(v, f"{path}.{k}", arrays) for k, v in enumerate(obj)]}
    if isinstance(obj, dict):
        if all(isinstance(k, str) for k in obj):
            return {k: _encode(v, f"{path}.{k}", arrays) for k, v in obj.items()}
        return {"__items__": [[_encode(k, f"{path}.k{i}", arrays), _encode(v, f"{path}.v{i}", arrays)]
                              for i, (k, v) in enumerate(obj.items())]}
    if isinstance(obj, list):
        return [_encode(v, f"{path}.{k}", arrays) for k, v in enumerate(obj)]
    if isinstance(obj, np.generic):
        return obj.item()
    if obj is None or isinstance(obj, (bool, int, float, str)):
        return obj
    raise TypeError(f"cannot store {type(obj).__name__} at {path!r}")


def _decode(obj: Any, arrays: Any, types: dict[str, type]) -> Any:
    if isinstance(obj, list):
        return [_decode(v, arrays, types) for v in obj]
    if not isinstance(obj, dict):
        return obj
    if "__array__" in obj:
        return arrays[obj["__array__"]]
    if "__warning__" in obj:
        code, text = obj["__warning__"]
        return CodedWarning(code, text) if code in CODES else str(text)  # a code of a newer version: the text
    if "__tuple__" in obj:
        return tuple(_decode(v, arrays, types) for v in obj["__tuple__"])
    if "__items__" in obj:
        return {_decode(k, arrays, types): _decode(v, arrays, types) for k, v in obj["__items__"]}
    if "__type__" in obj:
        cls = types[obj["__type__"]]
        kwargs = {k: _decode(v, arrays, types) for k, v in obj.items() if k != "__type__"}
        return cls(**kwargs)
    return {k: _decode(v, arrays, types) for k, v in obj.items()}


def write_result(res: Any, path: str | Path, *, beside: Mapping[str, tuple[str, str]] | None = None) -> None:
    """Write ``res`` (an AnalysisResult) to ``path`` (an ``.npz`` file; not atomic by itself:
    :meth:`AnalysisResult.save` writes it inside an atomic folder).

    ``beside``: arrays of the result (by their path in it, ``"diagram.values"``) already written in another
    ``.npz`` file of the same folder, as ``(file name, key)``: the result refers to them there (with their shape
    and type) instead of holding a second copy.
    """
    arrays: dict[str, np.ndarray] = {}
    tree = _encode(res, "", arrays)
    refs = {}
    for name, (file, key) in (beside or {}).items():
        if name in arrays:
            a = arrays.pop(name)
            refs[name] = {"file": file, "key": key, "shape": list(a.shape), "dtype": a.dtype.str}
    meta = {"format": "grainplug-result", "format_version": FORMAT_VERSION, "tree": tree, "beside": refs}
    with open(path, "wb") as fh:
        np.savez(fh, __tree__=np.array(json.dumps(meta)), **arrays)


def _read_beside(p: Path, refs: Mapping[str, Any], arrays: dict[str, np.ndarray]) -> None:
    """The arrays ``result.npz`` refers to in another file of its folder (:func:`write_result`'s ``beside``),
    checked for their shape and type."""
    for name, ref in refs.items():
        other = p.parent / str(ref["file"])
        try:
            with open(other, "rb") as fh, np.load(fh, allow_pickle=False) as data:
                a = data[str(ref["key"])]
        except FileNotFoundError:
            raise GrainplugError(f"{p.name} needs {other.name} beside it (it holds the result's {name}), and "
                                 f"{other.parent} has none — copy an analysis folder whole, or analyse the movie "
                                 "again") from None
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
            raise GrainplugError(f"{other} is damaged ({type(exc).__name__}: {exc}): the result's {name} is in it "
                                 "— analyse the movie again (grainplug analyze ... --overwrite)") from None
        if list(a.shape) != list(ref["shape"]) or a.dtype.str != ref["dtype"]:
            raise GrainplugError(f"{other} does not hold the result's {name} ({a.dtype.str} {list(a.shape)}, "
                                 f"not {ref['dtype']} {ref['shape']}): it was replaced since — analyse the movie "
                                 "again (grainplug analyze ... --overwrite)")
        arrays[name] = a


def read_result(path: str | Path, types: Mapping[str, type]) -> Any:
    """Read a result written by :func:`write_result`; ``types`` names the classes of its parts (the caller's:
    :func:`grainplug.result.load_result` gives :class:`~grainplug.result.AnalysisResult`'s)."""
    p = Path(path)
    try:
        with open(p, "rb") as fh, np.load(fh, allow_pickle=False) as data:  # closed when it is no zip either
            meta = json.loads(str(data["__tree__"]))
            arrays = {k: data[k] for k in data.files if k != "__tree__"}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        # a truncated or damaged file (a copy cut short, a full disk) is no zip archive, or a part of it is cut
        raise GrainplugError(f"{p} is damaged or not a grainplug result ({type(exc).__name__}: {exc}) — analyse "
                             "the movie again (grainplug analyze ... --overwrite), or pass a folder written by "
                             "result.save() or `grainplug analyze`") from None
    if not isinstance(meta, dict):
        raise GrainplugError(f"{p} is not a grainplug result (no description of its parts) — pass a folder "
                             "written by result.save() or `grainplug analyze`")
    if meta.get("format") != "grainplug-result" or meta.get("format_version", 0) > FORMAT_VERSION:
        raise GrainplugError(f"{p} was written by a newer grainplug (format {meta.get('format_version')}) "
                             "— upgrade grainplug to read it")
    _read_beside(p, meta.get("beside") or {}, arrays)
    try:
        return _decode(meta["tree"], arrays, dict(types))
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise GrainplugError(f"{p} is damaged ({type(exc).__name__}: {exc}) — analyse the movie again "
                             "(grainplug analyze ... --overwrite)") from None


def result_file(folder: str | Path) -> Path:
    """The ``result.npz`` of an analysis folder (or the file itself, or the folder of another of its files).

    Raises
    ------
    GrainplugError
        When there is none, saying what to pass.
    """
    p = Path(folder).expanduser()
    f = p / RESULT_FILE if p.is_dir() else p
    if p.is_file() and p.name != RESULT_FILE and (p.parent / RESULT_FILE).exists():
        f = p.parent / RESULT_FILE  # another file of the folder (its summary.json): the folder was meant
    if not f.exists():
        hint = (" (it was written by an older grainplug: analyse the movie again)"
                if (p / "summary.json").exists() else "")
        raise GrainplugError(f"no {RESULT_FILE} in {p}{hint} — pass a folder written by result.save() "
                             "or `grainplug analyze`")
    return f


def read_corrections(folder: str | Path) -> Any:
    """The reviewer's corrections in ``folder/corrections.json`` (None when there is none).

    Raises
    ------
    ParameterError
        When the file is not valid corrections, naming the file and what is wrong.
    """
    from .corrections import CORRECTIONS_FILE, Corrections
    from .errors import ParameterError

    f = Path(folder) / CORRECTIONS_FILE
    if not f.exists():
        return None
    try:
        data = json.loads(f.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ParameterError(f"{f}: not readable JSON ({exc}) — fix or delete the file") from None
    try:
        return Corrections.from_dict(data)
    except ParameterError as exc:
        raise ParameterError(f"{f}: {exc.message} — fix or delete the file") from None
