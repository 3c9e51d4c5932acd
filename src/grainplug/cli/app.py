"""The ``grainplug`` group: its options, and its commands by family, each loaded when named.

The analysis' commands (:mod:`grainplug.cli.analysis`) load with the group; the model's
(:mod:`grainplug.cli.model`), the campaigns' (:mod:`grainplug.cli.campaigns`) and ``synth``
(:mod:`grainplug.cli.synth`) only when named, so that every other command starts without
their imports. Shared helpers are in :mod:`grainplug.cli.common`.
"""

from __future__ import annotations

import click

from .._version import __version__
from . import analysis


class LazyGroup(click.Group):
    """Commands whose options need heavy imports are loaded when named (click's lazy-loading
    pattern), so that every other command starts without them."""

    LAZY = {"synth": "grainplug.cli.synth",  # noqa: RUF012 - a constant
            "stability": "grainplug.cli.model", "simulate": "grainplug.cli.model", "resonance": "grainplug.cli.model",
            "batch": "grainplug.cli.campaigns", "paper": "grainplug.cli.campaigns",
            "manifest": "grainplug.cli.campaigns"}

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted([*super().list_commands(ctx), *self.LAZY])

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        """No command (``grainplug``, ``grainplug --debug``): the usage on stdout, exit status 0 (as ``--help``),
        not click's usage error on stderr."""
        if not [a for a in args if a not in ("--debug", "-v", "--verbose")]:
            click.echo(ctx.get_help())
            ctx.exit(0)
        return super().parse_args(ctx, args)

    def invoke(self, ctx: click.Context) -> object:
        """The command, with Ctrl-C reported as :class:`~grainplug.errors.Interrupted` (one line, status 130):
        click's own handling writes an empty line to stderr first."""
        from ..errors import Interrupted

        try:
            return super().invoke(ctx)
        except KeyboardInterrupt as exc:
            raise Interrupted(str(exc) or "interrupted") from None

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name in self.LAZY:
            import importlib

            return getattr(importlib.import_module(self.LAZY[name]), name)
        return super().get_command(ctx, name)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, prog_name="grainplug")
@click.option("--debug", is_flag=True, help="Show full tracebacks and debug logging.")
@click.option("-v", "--verbose", is_flag=True, help="Log what the library does.")
def cli(debug: bool, verbose: bool) -> None:
    """grainplug: density waves of grains falling through narrow pipes.

    Positions are in mm along the tube from the top of the field of view,
    increasing with the flow; celerities in m/s, positive downstream.
    """


for _command in (analysis.info, analysis.calibrate, analysis.analyze, analysis.remeasure, analysis.review,
                 analysis.overlay):
    cli.add_command(_command)
