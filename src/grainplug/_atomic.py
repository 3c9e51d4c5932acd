"""One way to write outputs: everything lands whole, or not at all.

Every file grainplug writes goes through :func:`atomic_directory` (a set of files
that belong together: an analysis, a campaign, the paper's reproduction) or
:func:`atomic_file` (one file).

An analysis's folder is **replaced whole** (``replace=True``): the new set is built in
a temporary sibling folder, flushed to the disk, then swapped in by renames, so
a reader sees the previous complete result or the new complete result, never a
mix, and files of a previous run that this one does not write (a stale
``spectrum.png``) go with the old folder. A campaign's folder, which also holds
its runs, gets its own files replaced one by one (``replace=False``). A run
killed half-way leaves a temporary folder whose name carries its process id: the
next run into the same place removes it, and puts the previous result back if the
kill fell between the two renames.

Places that cannot be right are refused with one line before anything is
written: a file, a path under a file, a symbolic-link loop, the input movie or
a folder that holds it, an empty path, or a folder of someone else's files.
"""

from __future__ import annotations

import contextlib
import errno
import json
import logging
import os
import secrets
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from .errors import GrainplugError

log = logging.getLogger(__name__)

__all__ = ["OutputPlaceError", "atomic_directory", "atomic_file", "check_output_place", "is_complete",
           "mark_campaign",
           "refuse_overwriting_inputs"]

#: a folder holding this file was written by grainplug (an analysis or a campaign)
MARKER = ".grainplug"
#: files a user edits in place (a reviewer's corrections): not part of the completion check
USER_FILES = ("corrections.json",)
#: files grainplug writes into an output folder after it was made (``grainplug overlay``): its own, but drawn
#: from that analysis, so a new analysis in the folder replaces them with the rest
DERIVED_FILES = ("overlay.mp4", "overlay.webm")
#: what writes an output folder: a folder replaced whole is replaced only by a run of the same kind, and a
#: campaign's folder (its runs, the user's manifest beside them) never
KINDS = ("analysis", "paper", "simulation", "synthetic", "campaign")
#: the file that names a folder's kind when its marker does not say (versions before the kind was written)
_IDENTITY = (("campaign", "campaign.csv"), ("paper", "paper.json"), ("simulation", "fields.nc"),
             ("synthetic", "truth.json"), ("analysis", "result.npz"), ("analysis", "summary.json"))
#: what each kind writes, for folders whose marker lists nothing (older versions): anything else there is a user's
_KNOWN = {
    "analysis": {"summary.json", "plug_edges.csv", "tracks.csv", "diagram.npz", "result.npz", "report.html",
                 "diagram.tif", "edges_long.csv", "fields.nc", "grain_velocity.csv",
                 *(f"{stem}.{ext}" for stem in ("diagram", "spectrum", "frame") for ext in ("png", "svg", "pdf"))},
    "simulation": {"fields.nc", "summary.json", *(f"diagram.{ext}" for ext in ("png", "svg", "pdf"))},
    "paper": {"paper.json", "reproduction.md", "report.html"},
    "synthetic": {"truth.json", "truth_edges.csv"},
}
_PAPER_FIGURES = ("model_vs_experiment", "celerity_", "length_", "growth_rates_")
#: folders no command writes into: the file system's root and the system's own folders
_SYSTEM = frozenset({"/", "/bin", "/boot", "/dev", "/etc", "/lib", "/lib32", "/lib64", "/opt", "/proc", "/root",
                     "/run", "/sbin", "/srv", "/sys", "/usr", "/var", "/home", "/tmp", "/mnt", "/media"})


class OutputPlaceError(GrainplugError):
    """The output place cannot be written, or writing there would destroy something."""


def _describe(exc: OSError, place: Path) -> str:
    reasons = {errno.ENOSPC: "the disk is full", errno.EDQUOT: "the disk quota is exceeded",
               errno.EROFS: "the file system is read-only", errno.EACCES: "permission denied",
               errno.EPERM: "permission denied", errno.ENAMETOOLONG: "the name is too long"}
    why = reasons.get(exc.errno or 0, exc.strerror or str(exc))
    return f"cannot write {place}: {why} — choose another output folder (the previous result, if any, is intact)"


def check_output_place(out: str | Path, *, inputs: Iterable[str | Path] = (), replace: bool = True,
                       keeps: Iterable[str] = (), carry: bool = False, kind: str | None = None) -> Path:
    """The output folder, checked; raises :class:`OutputPlaceError` with the fix when it cannot be used.

    Parameters
    ----------
    out : path
        The folder to write.
    inputs : paths
        Files the run reads: the folder must neither be one of them nor hold one.
    replace : bool
        Whether the folder will be replaced whole. It must then be new, empty or grainplug's,
        and hold nothing grainplug did not write there: anything its completion marker does not
        list (a user's notes, a reviewer's ``corrections.json``) would be lost, so it is refused.
    keeps : names
        :data:`USER_FILES` the new output writes again (a result that carries its corrections).
    carry : bool
        What grainplug did not write there is carried into the new folder (see :func:`atomic_directory`),
        so it is no loss and not refused.
    kind : str, optional
        What will write there (one of :data:`KINDS`). A folder that holds anything is then used only
        when it holds an earlier output of the same kind: never a campaign's folder for an analysis,
        nor a folder of the user's files for a campaign.
    """
    if kind is not None and kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
    if str(out).strip() == "" or (replace and str(out).strip() == "."):
        what = "empty" if str(out).strip() == "" else "the current folder (it would be replaced whole)"
        raise OutputPlaceError(f"the output folder is {what} — give a folder of its own, e.g. results/run1")
    p = Path(out).expanduser()
    try:
        resolved = p.resolve(strict=False)
    except (RuntimeError, OSError) as exc:  # a symbolic-link loop
        raise OutputPlaceError(f"{p} is a loop of symbolic links ({exc}) — give another output folder") from None
    if p.is_symlink() and not p.exists():
        raise OutputPlaceError(f"{p} is a symbolic link to nothing (or a loop of links) — give another output folder")
    if str(resolved) in _SYSTEM or any(str(resolved).startswith(f"{d}/") for d in ("/proc", "/sys", "/dev")):
        raise OutputPlaceError(f"{p} is a system folder — give a folder of its own for the output, e.g. "
                               "results/run1")
    for src in inputs:
        s = _resolved(src)
        if s is None:
            continue
        if _same_place(s, resolved):
            raise OutputPlaceError(f"{p} is the input itself — give another output folder, the input would be lost")
        if replace and resolved in s.parents:
            raise OutputPlaceError(f"{p} holds the input {s.name}: replacing it would delete it — "
                                   "give another output folder")
    for parent in [resolved, *resolved.parents]:
        if parent.exists() and not parent.is_dir():
            what = "is a file" if parent == resolved else f"is under {parent}, which is a file"
            raise OutputPlaceError(f"{p} {what} — the output must be a folder")
        if parent.exists():
            break
    entries = _entries(resolved)
    if not entries or (not replace and kind is None):
        return p
    found = _kind_of(resolved, entries)
    if found is None:
        how = "grainplug replaces its output folder whole" if replace else "the output goes into a folder of its own"
        raise OutputPlaceError(f"{p} holds files grainplug did not write ({entries[0].name}, ...) — give a new "
                               f"or empty folder ({how})")
    if found == "campaign" and (replace or kind != "campaign"):
        raise OutputPlaceError(f"{p} is a campaign's folder (grainplug batch): its runs and what you keep there "
                               f"would be lost — give another output folder for the {kind or 'output'}")
    if kind is not None and found != kind and (found != "output" or kind == "campaign"):
        raise OutputPlaceError(f"{p} holds a grainplug {found}, not a {kind} — give another output folder "
                               "(or move that one out first)")
    if replace:
        foreign = [] if carry else _foreign(resolved, entries, set(keeps), found)
        if foreign:
            names = ", ".join(foreign[:3]) + (", ..." if len(foreign) > 3 else "")
            why = (" (a reviewer's corrections: `grainplug remeasure` applies them to the analysis there)"
                   if any(f in USER_FILES for f in foreign) else "")
            raise OutputPlaceError(f"{p} holds what grainplug did not write there: {names}{why} — move it out "
                                   "first (the folder is replaced whole), or give another output folder")
    return p


def _resolved(path: str | Path | None) -> Path | None:
    """``path`` made absolute with its links followed (None for no path; a link loop as it is)."""
    if path is None or str(path).strip() == "":
        return None
    p = Path(path).expanduser()
    try:
        return p.resolve(strict=False)
    except (RuntimeError, OSError):  # a loop of links: compared by its own name
        return Path(os.path.abspath(p))


def _same_place(a: Path, b: Path) -> bool:
    """Whether two paths name one file: the same path once links are followed, or hard links of one file."""
    if a == b:
        return True
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):
        return False


def refuse_overwriting_inputs(outputs: Iterable[str | Path], inputs: Iterable[str | Path | None]) -> None:
    """Raise :class:`OutputPlaceError` when one of ``outputs`` (files about to be written) is one of ``inputs``.

    Called before anything is written, so that no command ever writes over what it reads: a movie, a
    calibration image, a manifest, a background, a settings file (the same file by another path, a
    symbolic or a hard link, included).
    """
    ins = [(src, r) for src in inputs if (r := _resolved(src)) is not None]
    for out in outputs:
        o = _resolved(out)
        if o is None:
            continue
        for src, r in ins:
            if _same_place(o, r):
                raise OutputPlaceError(f"{out} would be written over the input {src} — give another output name "
                                       "(nothing was written)")


def _entries(folder: Path) -> list[Path]:
    """What a folder holds, without what a killed run left there (an empty list for no folder)."""
    if not folder.is_dir():
        return []
    try:
        return sorted((e for e in folder.iterdir() if not e.name.startswith(f".{folder.name}.grainplug-")
                       and not e.name.startswith(".grainplug-")), key=lambda e: e.name)
    except OSError:
        return []


def _marker(folder: Path) -> dict | None:
    """The completion marker of ``folder`` when it is a valid one (a JSON object), else None."""
    try:
        data = json.loads((folder / MARKER).read_text())
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    return data if isinstance(data, dict) else None


def _listed(folder: Path) -> set[str] | None:
    """The top-level names the marker of ``folder`` lists (None when it lists nothing: no marker, an empty one,
    one written by a version without the list)."""
    files = (_marker(folder) or {}).get("files")
    return {str(name).split("/", 1)[0] for name in files} if isinstance(files, dict) else None


def _grainplugs(path: Path) -> bool:
    """Whether a JSON file is one grainplug wrote (it names the version that wrote it)."""
    try:
        with open(path, "rb") as fh:
            return b'"grainplug_version"' in fh.read(1 << 16)
    except OSError:
        return False


def _kind_of(folder: Path, entries: list[Path]) -> str | None:
    """What wrote ``folder`` (one of :data:`KINDS`), or None when nothing says grainplug did.

    The marker's ``kind`` says it; a marker that lists files without a kind (older versions) by what it
    lists ("output" when that does not tell); an empty marker is a campaign's (what ``batch`` wrote before
    it listed its files); otherwise (no marker, or the one line of the first versions) by a file of
    grainplug's own that names its version (a user's ``summary.json`` does not).
    """
    marker = _marker(folder)
    if marker is not None and marker.get("kind") in KINDS:
        return str(marker["kind"])
    listed = _listed(folder)
    if listed is not None:  # an output replaced whole, written before its kind was
        return next((k for k, name in _IDENTITY if name in listed and k != "campaign"), "output")
    try:
        if (folder / MARKER).is_file() and (folder / MARKER).stat().st_size == 0:
            return "campaign"  # what batch wrote before it listed its files
    except OSError:
        pass
    names = {e.name for e in entries}
    for k, name in _IDENTITY:
        if name in names and k != "campaign" and _grainplugs(folder / name):
            return k
    return None


def _known(kind: str | None, name: str) -> bool:
    """Whether ``name`` is one an output of ``kind`` writes (for folders whose marker lists nothing)."""
    if name in _KNOWN.get(kind or "", ()):
        return True
    stem, _, ext = name.rpartition(".")
    if kind == "paper":
        return ext in ("png", "svg", "pdf") and stem.startswith(_PAPER_FIGURES)
    if kind == "synthetic":
        return stem == "movie" or stem == "movie_frames" or name == "movie_frames"
    return False


def _foreign(folder: Path, entries: list[Path], keeps: set[str], kind: str | None = None) -> list[str]:
    """Entries of an output folder grainplug did not write: what its completion marker does not list, or,
    when it lists nothing (older versions), what the output of its ``kind`` never writes."""
    listed = _listed(folder)
    own = {MARKER, *DERIVED_FILES, *keeps}
    if listed is not None:
        own |= listed
    kind = kind or _kind_of(folder, entries)
    return sorted(e.name for e in entries if e.name not in own and not e.name.startswith(".grainplug-")
                  and (listed is not None or not _known(kind, e.name)))


def _fsync_tree(folder: Path) -> None:
    for f in folder.rglob("*"):
        if f.is_file():
            with open(f, "rb") as fh:
                os.fsync(fh.fileno())
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _seal(folder: Path, carried: Iterable[str] = (), kind: str | None = None) -> None:
    """Write the completion marker: every file of the set with its size (see :func:`is_complete`),
    except the files a user edits (:data:`USER_FILES`) and the entries carried from the previous folder
    (``carried``: they stay the user's, so that a later run does not take them for grainplug's)."""
    skip = set(carried)
    files = {f.relative_to(folder).as_posix(): f.stat().st_size
             for f in sorted(folder.rglob("*")) if f.is_file() and f.name != MARKER and f.name not in USER_FILES
             and f.relative_to(folder).parts[0] not in skip}
    seal: dict[str, object] = {"grainplug_output": "replaced whole by each run", "complete": True}
    if kind is not None:
        seal["kind"] = kind
    (folder / MARKER).write_text(json.dumps({**seal, "files": files}, indent=1) + "\n")


def mark_campaign(folder: Path) -> None:
    """Mark ``folder`` as a campaign's as soon as it is made (before its first run), unless it is marked."""
    if _marker(folder) is None or _marker(folder).get("kind") != "campaign":  # type: ignore[union-attr]
        _seal_campaign(folder, [])


def _seal_campaign(folder: Path, names: Iterable[str]) -> None:
    """The marker of a campaign's folder (its files replaced one by one): what the campaign wrote there, this
    time and before, so that the folder is known for a campaign's and its user's files for the user's."""
    files: dict[str, int] = {}
    old = _marker(folder)
    if old is not None and isinstance(old.get("files"), dict):
        files.update({str(k): v for k, v in old["files"].items() if os.path.lexists(folder / str(k))})
    for name in names:
        f = folder / name
        files[name] = f.stat().st_size if f.is_file() else 0
    (folder / MARKER).write_text(json.dumps({"grainplug_output": "a campaign: its files replaced one by one",
                                             "kind": "campaign", "files": dict(sorted(files.items()))},
                                            indent=1) + "\n")


def _carry(src: Path, dst: Path) -> None:
    """Put ``src`` (a file, a folder or a symbolic link) at ``dst`` as well: hard links where the file system
    has them, copies otherwise. ``src`` stays where it is until the swap, so a run killed meanwhile loses
    nothing."""
    if src.is_symlink():
        os.symlink(os.readlink(src), dst)
    elif src.is_dir():
        try:
            shutil.copytree(src, dst, symlinks=True, copy_function=os.link)
        except (OSError, shutil.Error):
            shutil.rmtree(dst, ignore_errors=True)
            shutil.copytree(src, dst, symlinks=True)
    else:
        try:
            os.link(src, dst)
        except OSError:
            shutil.copy2(src, dst)


def cwd_inside(folder: Path) -> bool:
    """Whether this process's current folder is ``folder`` or inside it (False when it is gone)."""
    try:
        cwd = Path.cwd()
    except OSError:
        return False
    folder = folder.resolve()
    return cwd == folder or folder in cwd.parents


def is_complete(folder: str | Path) -> bool:
    """Whether ``folder`` holds a complete output set: its completion marker lists every file with
    its size, and every file is there with that size (a folder damaged since, or written by a
    version without markers, is not complete)."""
    folder = Path(folder)
    try:
        seal = json.loads((folder / MARKER).read_text())
        files = seal["files"] if seal.get("complete") is True else None
        return isinstance(files, dict) and bool(files) and all(
            (folder / name).is_file() and (folder / name).stat().st_size == size for name, size in files.items())
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return False


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs on this machine (a killed one not yet reaped, a zombie, does not)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:  # Linux: the state follows the command's closing parenthesis
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return True


def recover(out: Path) -> None:
    """Clean what a killed run left beside ``out``; put back a previous result caught mid-swap."""
    parent, name = out.parent, out.name
    if not parent.is_dir():
        return
    for leftover in sorted(parent.glob(f".{name}.grainplug-*")):
        parts = leftover.name.rsplit("-", 2)
        try:
            pid = int(parts[-2])
        except (ValueError, IndexError):
            continue
        if _alive(pid) and pid != os.getpid():
            continue  # another run is writing here now
        if leftover.name.startswith(f".{name}.grainplug-old-") and not out.exists():
            os.replace(leftover, out)  # killed between the two renames: the previous result goes back
        else:
            shutil.rmtree(leftover, ignore_errors=True)


@contextlib.contextmanager
def atomic_directory(out_dir: str | Path, written: dict[str, Path] | None = None, *, replace: bool = False,
                     inputs: Iterable[str | Path] = (), keeps: Iterable[str] = (),
                     carry: bool = False, kind: str | None = None) -> Iterator[Path]:
    """Write files into a temporary folder, then move them all into ``out_dir``.

    Parameters
    ----------
    out_dir : str or Path
        Destination folder, created if needed.
    written : dict, optional
        Filled with ``{file name: final path}`` once the files are in place.
    replace : bool
        Replace the whole folder (an analysis's): files of a previous run that this
        block does not write are removed with the old folder. Otherwise (a campaign's
        folder, which holds its runs) only the files written are replaced.
    inputs : paths
        Files the run reads (refused as output places, see :func:`check_output_place`).
    keeps : names
        User files (:data:`USER_FILES`) this block writes again, so their being there is no loss.
    carry : bool
        With ``replace``: what grainplug did not write in the folder (a user's ``notes.txt``, a
        subfolder) is carried into the new folder (hard-linked, or copied), instead of refusing the
        folder; an entry this block writes under the same name wins. For a result rewritten in place
        (``remeasure``), where the user's files belong to the same analysis.
    kind : str, optional
        What writes the folder (one of :data:`KINDS`): recorded in its marker, and a folder that holds an
        output of another kind is refused (see :func:`check_output_place`).

    Notes
    -----
    The folder replaced may be this process's current folder (``grainplug remeasure .``): it is
    replaced by its absolute path, and the process (like a shell that was there) stays in the
    old, removed folder; the working directory is the caller's to change (``os.chdir`` to the
    folder again, ``cd .`` in a shell), never this function's.

    Yields
    ------
    Path
        The temporary folder to write into.

    Raises
    ------
    OutputPlaceError
        When the place cannot be used or written (full disk, read-only): nothing
        of the previous result is changed.
    """
    out = check_output_place(out_dir, inputs=inputs, replace=replace, keeps=keeps, carry=carry, kind=kind)
    if replace:  # "./" or "run1/..": the folder by its name in its parent (links are not followed)
        out = Path(os.path.abspath(out))
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        recover(out)
        if replace:
            tmp = _new_dir(out.parent, f".{out.name}.grainplug-new-{os.getpid()}-")
        else:
            out.mkdir(parents=True, exist_ok=True)
            tmp = _new_dir(out, ".grainplug-")
    except OSError as exc:
        raise OutputPlaceError(_describe(exc, out)) from None
    try:
        try:
            yield tmp
        except OSError as exc:
            if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM):
                raise OutputPlaceError(_describe(exc, out)) from None
            raise
        try:
            if replace:
                carried = []
                if carry and out.is_dir():
                    for name in _foreign(out.resolve(), _entries(out.resolve()), set(keeps)):
                        if not os.path.lexists(tmp / name):
                            _carry(out / name, tmp / name)
                            carried.append(name)
                    if carried:
                        log.info("kept in %s what grainplug did not write there: %s", out, ", ".join(carried))
                _seal(tmp, carried, kind)
                _fsync_tree(tmp)
                old = None
                if out.exists():
                    old = Path(tempfile.mkdtemp(prefix=f".{out.name}.grainplug-old-{os.getpid()}-", dir=out.parent))
                    old.rmdir()
                    os.replace(out, old)
                os.replace(tmp, out)
                if old is not None:
                    shutil.rmtree(old, ignore_errors=True)
                if written is not None:
                    for f in sorted(out.iterdir()):
                        if f.name != MARKER:
                            written[f.name] = f
            else:
                names = []
                for f in sorted(tmp.iterdir()):
                    dest = out / f.name
                    os.replace(f, dest)
                    names.append(f.name)
                    if written is not None:
                        written[f.name] = dest
                _seal_campaign(out, names)
        except OSError as exc:
            raise OutputPlaceError(_describe(exc, out)) from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _new_dir(parent: Path, prefix: str) -> Path:
    """A new, uniquely named folder in ``parent``, with the permissions the user's umask gives.

    (``tempfile.mkdtemp`` makes it private, mode 0700: a result folder shared on a lab's server
    must be readable as any other folder.)
    """
    for _ in range(100):
        path = parent / f"{prefix}{secrets.token_hex(5)}"
        try:
            path.mkdir(0o777)
        except FileExistsError:
            continue
        return path
    raise FileExistsError(errno.EEXIST, "no free temporary name", str(parent / prefix))


def _new_file(parent: Path, prefix: str, suffix: str) -> Path:
    """A new, empty, uniquely named file in ``parent``, with the permissions the user's umask gives
    (``tempfile.mkstemp`` makes it 0600)."""
    for _ in range(100):
        path = parent / f"{prefix}{secrets.token_hex(5)}{suffix}"
        try:
            os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        except FileExistsError:
            continue
        return path
    raise FileExistsError(errno.EEXIST, "no free temporary name", str(parent / prefix))


@contextlib.contextmanager
def atomic_file(path: str | Path, *, inputs: Iterable[str | Path | None] = ()) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; it replaces ``path`` when the block ends well.

    The temporary name keeps the suffix, so writers that pick a format from the
    name (matplotlib, tifffile) still do. ``inputs``: files the output was made from; ``path`` must not
    be one of them (:func:`refuse_overwriting_inputs`).
    """
    dest = Path(path)
    if str(path).strip() == "":
        raise OutputPlaceError("the output file name is empty — give a file name")
    refuse_overwriting_inputs([dest], inputs)
    if dest.is_dir():
        raise OutputPlaceError(f"{dest} is a folder — give a file name")
    try:
        dest.parent.mkdir(parents=True, exist_ok=True)
        tmp = _new_file(dest.parent, f".{dest.stem}-", dest.suffix)
    except OSError as exc:
        raise OutputPlaceError(_describe(exc, dest)) from None
    try:
        try:
            yield tmp
            os.replace(tmp, dest)
        except OSError as exc:
            if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.ENOTDIR):
                raise OutputPlaceError(_describe(exc, dest)) from None
            raise
    finally:
        tmp.unlink(missing_ok=True)
