"""The library's messages in the command line's words.

The library names a parameter the way a Python user types it, ``name=`` (``give
mm_per_px=``, ``allow_truncated=True``, ``boundary="open"``), never a flag. The command
line prints the same messages with its own flags: :func:`as_flags` turns every
``name=`` that is the keyword of one of its options into that option (``--mm-per-px``,
``--allow-truncated``, ``--boundary open``). Saved results keep the library's words, whichever
front end wrote them; the report adds each analysis keyword's option beside it
(:func:`grainplug.params.with_options`).
"""

from __future__ import annotations

import re
import sys

import click

from ..params import OPTION_ALIASES as ALIASES  # library keywords whose option has another name

# a keyword, ``=``, and its value if one follows at once: True, a quoted word, a tuple, a number or a word
_KEYWORD = re.compile(r"(?<![\w.\-])([a-z][a-z0-9_]*)=(True\b|\"[^\"]*\"|'[^']*'|\([^)]*\)|[\w.+-]+)?")


def option_flags(group: click.Group) -> dict[str, tuple[str, bool]]:
    """Keyword -> (its long flag, whether it is a switch) over every command of ``group`` (a lazily loaded one
    once loaded: only then can it be the command whose message is printed)."""
    flags: dict[str, tuple[str, bool]] = {}
    ctx = click.Context(group)
    lazy = getattr(group, "LAZY", {})
    for name in group.list_commands(ctx):
        if name in lazy and lazy[name] not in sys.modules:  # not loaded: not the command that speaks (and costly)
            continue
        command = group.get_command(ctx, name)
        for p in getattr(command, "params", ()):
            longs = [o for o in getattr(p, "opts", ()) if o.startswith("--")]
            if isinstance(p, click.Option) and longs and p.name:
                flags.setdefault(p.name, (longs[0], bool(p.is_flag)))
    return flags


def as_flags(text: str, flags: dict[str, tuple[str, bool]]) -> str:
    """``text`` with each library keyword (``name=``, and its value) written as the command line's option.

    Examples
    --------
    >>> as_flags("give mm_per_px= or allow_truncated=True", {"mm_per_px": ("--mm-per-px", False),
    ...                                                     "allow_truncated": ("--allow-truncated", True)})
    'give --mm-per-px or --allow-truncated'
    """
    def one(m: re.Match[str]) -> str:
        name, value = m.group(1), m.group(2)
        flag = flags.get(ALIASES.get(name, name))
        if flag is None:
            return m.group(0)
        opt, switch = flag
        if value is None or (switch and value == "True"):
            return opt
        return f"{opt} {value.strip(chr(34) + chr(39) + '()').replace(', ', ',')}"

    return _KEYWORD.sub(one, text)
