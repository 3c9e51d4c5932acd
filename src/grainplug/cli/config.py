"""``grainplug.toml``: a lab's settings for ``analyze``, beside the movie or given with ``--config``.

.. code-block:: toml

    [analyze]
    fps = 2000
    tube_outer_diameter_mm = 5.5
    calibration = "calibrations/2026-11-20.json"   # relative to this file
    start = "0.5s"

Keys are the options' names (``mm_per_px`` or ``mm-per-px``). The command line wins over the
file, the file over the defaults. A file named ``grainplug.toml`` in the movie's folder (or in an
image folder given as the movie) is read without being asked; ``--config FILE`` names another.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import click
from click.core import ParameterSource

from ..errors import ParameterError

CONFIG_NAME = "grainplug.toml"
#: options that belong to one run, not to a lab's settings
NOT_SETTINGS = {"out", "config", "json", "as_json"}


def find_config(movie: Path, given: Path | None) -> Path | None:
    """The settings file: ``given``, else ``grainplug.toml`` beside the movie (or inside an image folder)."""
    if given is not None:
        if not given.is_file():
            raise ParameterError(f"no such settings file: {given} — check --config")
        return given
    places = [movie / CONFIG_NAME] if movie.is_dir() else []
    places.append(movie.parent / CONFIG_NAME)
    return next((p for p in places if p.is_file()), None)


class ConfigCommand(click.Command):
    """A command whose options not given on the command line are taken from ``grainplug.toml``."""

    section = "analyze"

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        rest = super().parse_args(ctx, args)
        movie = ctx.params.get("movie")
        path = find_config(Path(movie), ctx.params.get("config")) if movie is not None else None
        if path is not None:
            ctx.params.update(_settings(ctx, self, path))
            ctx.meta["grainplug.config"] = path
        return rest


def _settings(ctx: click.Context, command: click.Command, path: Path) -> dict[str, object]:
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ParameterError(f"{path}: not a readable TOML settings file ({exc}) — fix it or remove it") from None
    section = data.get(ConfigCommand.section, {})
    if not isinstance(section, dict):
        raise ParameterError(f"{path}: [{ConfigCommand.section}] must be a table of settings")
    options = {}
    for param in command.params:
        if isinstance(param, click.Option) and param.name not in NOT_SETTINGS:
            for opt in param.opts:
                options[opt.lstrip("-").replace("-", "_")] = param
    out: dict[str, object] = {}
    seen: dict[str, str] = {}
    for key, value in section.items():
        param = options.get(key.replace("-", "_"))
        if param is None:
            known = ", ".join(sorted(options))
            raise ParameterError(f"{path}: unknown setting {key!r} in [{ConfigCommand.section}] — known: {known}")
        if param.name in seen:  # mm-per-px and mm_per_px: which one was meant cannot be told
            raise ParameterError(f"{path}: {seen[param.name]!r} and {key!r} in [{ConfigCommand.section}] are the same "
                                 "setting — keep one of them")
        seen[str(param.name)] = key
        if ctx.get_parameter_source(param.name) is not ParameterSource.DEFAULT:
            continue  # given on the command line: it wins
        if isinstance(param.type, click.Path) and isinstance(value, str) and not Path(value).is_absolute():
            value = str(path.parent / value)  # relative to the settings file
        elif param.name == "style" and isinstance(value, str) and (path.parent / value).is_file():
            value = str(path.parent / value)  # a style sheet beside the settings file (else a sheet's name)
        try:
            out[param.name] = param.type_cast_value(ctx, value)
        except click.BadParameter as exc:
            raise ParameterError(f"{path}: {key}: {exc.format_message()}") from None
    return out
