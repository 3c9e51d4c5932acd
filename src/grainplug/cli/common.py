"""What every command of the command line shares: the error console, the library's words as flags, output
folders, figure options, the window's and region's flags."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import click
from rich.console import Console
from rich.markup import escape

from ..errors import ParameterError

if TYPE_CHECKING:
    pass

err_console = Console(stderr=True)


def in_flags(text: str) -> str:
    """A library message in this command line's words: each keyword it names (``mm_per_px=``) as the option."""
    from .words import as_flags, option_flags

    ctx = click.get_current_context(silent=True)
    root = ctx.find_root().command if ctx is not None else None
    return as_flags(text, option_flags(root)) if isinstance(root, click.Group) else text


def say_warning(line: str, prefix: str = "") -> None:
    """``warning: <prefix><line>`` on stderr, the library's keywords named as this command line's options."""
    err_console.print(f"[yellow]warning:[/] {escape(prefix + in_flags(line))}", highlight=False, soft_wrap=True)


def say_note(line: str) -> None:
    """``note: <line>`` on stderr (what the user should know, not a doubt about the result), the library's
    keywords named as this command line's options."""
    err_console.print(f"note: {escape(in_flags(line))}", highlight=False, soft_wrap=True)


OVERWRITE_HELP = ("Replace --out if it holds an earlier result (the whole folder; refused if it holds anything "
                  "grainplug did not write there, such as your notes or a reviewer's corrections.json).")


PUBLICATION_HELP = ("Every figure also as SVG and PDF, for a journal (about 0.6 s more a run; "
                    "publication = true in grainplug.toml keeps it on).")


def refuse_existing(out: Path, overwrite: bool) -> None:
    """An existing, non-empty output folder is replaced only when asked (``--overwrite``)."""
    if overwrite or not out.exists() or (out.is_dir() and not any(out.iterdir())):
        return
    what = "folder" if out.is_dir() else "file"
    raise ParameterError(f"--out {out}: that {what} already exists — pass --overwrite to replace it, or give "
                         "another --out")


def roi_option(text: str | None) -> tuple[int, int, int, int] | None:
    """``--roi X0,Y0,X1,Y1`` as four integers (checked against the frame by the analysis)."""
    if text is None:
        return None
    parts = [p.strip() for p in text.split(",")]
    try:
        values = tuple(int(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 4:
        raise ParameterError(f"--roi must be four pixel numbers X0,Y0,X1,Y1 (e.g. 40,0,120,1024), got {text!r}")
    return values  # type: ignore[return-value]


def figure_options_of(dpi: int | None, formats: str | None, publication: bool, style: str | None):
    """``FigureOptions`` of the figure flags (checked before the analysis)."""
    from ..plotting.options import PUBLICATION, FigureOptions

    if publication and formats:
        raise ParameterError("give either --publication (PNG, SVG and PDF) or --figure-formats, not both")
    base = PUBLICATION if publication else FigureOptions()
    fmts = tuple(f.strip().lower() for f in formats.split(",") if f.strip()) if formats else base.formats
    if style and not (Path(style).is_file() or known_style(style)):
        raise ParameterError(f"--style {style}: neither a file nor a matplotlib style sheet name")
    if style and Path(style).is_file():
        check_style_file(Path(style))
    try:
        return FigureOptions(dpi=dpi or base.dpi, formats=fmts, style=style)
    except ParameterError as exc:
        raise ParameterError(f"--{'dpi' if exc.param == 'dpi' else 'figure-formats'}: {exc.message}") from None


def _strip_comment(line: str) -> str:
    """``line`` without its comment: from the first ``#`` outside double quotes (a quoted colour keeps its)."""
    quoted = False
    for i, ch in enumerate(line):
        if ch == '"':
            quoted = not quoted
        elif ch == "#" and not quoted:
            return line[:i].strip()
    return line.strip()


def check_style_file(path: Path) -> None:
    """Refuse a style sheet with a line matplotlib would ignore (it only complains, and draws without it).

    Each line ``key: value`` (comments and blank lines aside) must name a setting of matplotlib's and give
    it a value its validator takes; the first that does not is named, with its number.
    """
    import warnings

    import matplotlib

    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise ParameterError(f"--style {path}: not a readable style sheet ({exc})") from None
    probe = matplotlib.RcParams()
    for n, raw in enumerate(lines, 1):
        line = _strip_comment(raw)
        if not line:
            continue
        key, colon, value = (part.strip() for part in line.partition(":"))
        why = None
        if not colon:
            why = "no 'key: value'"
        elif key not in matplotlib.rcParams:
            why = f"{key!r} is no matplotlib setting"
        else:
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # a deprecated setting is still a setting
                    probe[key] = value[1:-1] if len(value) > 1 and value[0] == value[-1] == '"' else value
            except (ValueError, KeyError, TypeError) as exc:
                why = f"bad value for {key} ({exc})"
        if why:
            raise ParameterError(f"--style {path}: line {n} ({raw.strip()!r}): {why} — fix or remove it "
                                 "(matplotlib would skip it)")


def known_style(name: str) -> bool:
    import matplotlib.style

    return name in matplotlib.style.available or name == "default"


def echo_json(data: object) -> None:
    from ..jsonio import dumps

    click.echo(dumps(data), nl=False)


def window_params(start: tuple[str, float] | None, end: tuple[str, float] | None) -> dict[str, float | int]:
    """``--start/--end`` as :class:`AnalysisParams` fields (``start_frame`` or ``start_s``...)."""
    out: dict[str, float | int] = {}
    for name, point in (("start", start), ("end", end)):
        if point is not None:
            kind, value = point
            out[f"{name}_frame" if kind == "frame" else f"{name}_s"] = int(value) if kind == "frame" else value
    return out


def default_of(cls: type, name: str) -> object:
    """The default of field ``name`` of the parameter dataclass ``cls``: the command line's defaults are the
    library's, written once."""
    import dataclasses

    for f in dataclasses.fields(cls):
        if f.name == name:
            if f.default is dataclasses.MISSING:
                raise LookupError(f"{cls.__name__}.{name} has no default")
            return f.default
    raise LookupError(f"{cls.__name__} has no field {name}")


def mask_option(values: tuple[str, ...] | list[str] | str | None) -> tuple[tuple[float, float], ...]:
    """``--mask FROM:TO`` (repeatable; a list in grainplug.toml) as ``mask_mm`` pairs (checked by the library)."""
    if not values:
        return ()
    out = []
    for text in [values] if isinstance(values, str) else values:
        parts = str(text).replace(",", ":").split(":")
        try:
            a, b = (float(p) for p in parts)
        except ValueError:
            raise ParameterError(f"--mask takes FROM:TO in mm (e.g. 55.5:61), got {text!r}") from None
        out.append((a, b))
    return tuple(out)
