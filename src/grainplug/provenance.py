"""Where an analysis' input came from: a file's identity (size, time, sampled hash), or an array's."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np

from .readers import Movie


# -- provenance ------------------------------------------------------------------------
def fingerprint(path: str | Path, *, full: bool = False) -> dict[str, object]:
    """Identity of an input: path, size, modification time and a SHA-256 of sampled content.

    Parameters
    ----------
    path : path
        A movie file, or a folder of image files (every file is covered, with its name).
    full : bool
        Also hash every byte (``sha256``): slow on large movies, exact.

    Notes
    -----
    ``sha256_sampled`` covers the first and last MiB of each file (the header and the
    last frames) and 32 blocks of 64 KiB evenly spaced between them, so that a movie
    changed in place (re-exported, re-recorded under the same name) is told apart
    without reading gigabytes; a change confined to bytes between the blocks is only
    seen with ``full=True`` (``grainplug batch --verify``).
    """
    p = Path(path)
    h = hashlib.sha256()
    whole = hashlib.sha256() if full else None
    files = sorted(q for q in p.iterdir() if q.is_file()) if p.is_dir() else [p]
    size = 0
    mtime = 0.0
    block, ends, n_blocks = 1 << 16, 1 << 20, 32
    for f in files:
        st = f.stat()
        size += st.st_size
        mtime = max(mtime, st.st_mtime)
        h.update(f.name.encode())
        h.update(str(st.st_size).encode())
        with open(f, "rb") as fh:
            h.update(fh.read(ends))
            if st.st_size > 2 * ends:
                span = st.st_size - 2 * ends - block
                for k in range(n_blocks):
                    fh.seek(ends + span * k // (n_blocks - 1))
                    h.update(fh.read(block))
                fh.seek(-ends, os.SEEK_END)
                h.update(fh.read(ends))
            if whole is not None:
                whole.update(f.name.encode())
                fh.seek(0)
                while chunk := fh.read(1 << 22):
                    whole.update(chunk)
    out: dict[str, object] = {"path": str(p.resolve()), "bytes": size, "files": len(files), "mtime": mtime,
                              "sha256_sampled": h.hexdigest()}
    if whole is not None:
        out["sha256"] = whole.hexdigest()
    return out

def movie_identity(movie: Movie) -> dict[str, object]:
    """Provenance of the input: a file's :func:`fingerprint`, or an array's shape and the hash
    of its first and last frames."""
    if not movie.info.format.startswith("array"):
        return fingerprint(movie.path)
    n = movie.info.n_frames
    h = hashlib.sha256()
    for k in sorted({0, n - 1}):
        h.update(np.ascontiguousarray(movie.read(k)).tobytes())
    return {"path": None, "kind": "array", "shape": [n, *movie.info.frame_shape], "dtype": movie.info.dtype,
            "sha256_first_last_frames": h.hexdigest()}
