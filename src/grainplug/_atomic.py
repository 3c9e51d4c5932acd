"""One way to write outputs: everything lands whole, or not at all.

Every file grainplug writes goes through :func:`atomic_directory` (a set of files
that belong together: an analysis, a campaign, the paper's reproduction) or
:func:`atomic_file` (one file). Files are written under temporary names in the
destination folder, on the same file system, and renamed into place only when all
of them are complete, so an interrupted run (Ctrl-C, a full disk, a crash) leaves
the previous results intact and no half-written file behind.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

__all__ = ["atomic_directory", "atomic_file"]


@contextlib.contextmanager
def atomic_directory(out_dir: str | Path, written: dict[str, Path] | None = None) -> Iterator[Path]:
    """Write files into a temporary folder, then move them all into ``out_dir``.

    Parameters
    ----------
    out_dir : str or Path
        Destination folder, created if needed. Files already there that the block
        does not write are left as they are.
    written : dict, optional
        Filled with ``{file name: final path}`` once the files are in place.

    Yields
    ------
    Path
        The temporary folder to write into (inside ``out_dir``).

    Notes
    -----
    Each file is moved with :func:`os.replace`, atomic on POSIX and Windows. If
    the block raises, nothing is moved and the temporary folder is removed.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".grainplug-", dir=out))
    try:
        yield tmp
        for f in sorted(tmp.iterdir()):
            dest = out / f.name
            os.replace(f, dest)
            if written is not None:
                written[f.name] = dest
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


@contextlib.contextmanager
def atomic_file(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; it replaces ``path`` when the block ends well.

    The temporary name keeps the suffix, so writers that pick a format from the
    name (matplotlib, tifffile) still do.
    """
    dest = Path(path)
    dest.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{dest.stem}-", suffix=dest.suffix, dir=dest.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        os.replace(tmp, dest)
    finally:
        tmp.unlink(missing_ok=True)
