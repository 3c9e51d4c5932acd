"""Click commands. Each command parses options, calls the library and prints."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import click
from rich.console import Console

from .._version import __version__
from ..errors import ParameterError

err_console = Console(stderr=True)


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, prog_name="grainplug")
@click.option("--debug", is_flag=True, help="Show full tracebacks and debug logging.")
@click.option("-v", "--verbose", is_flag=True, help="Log what the library does.")
def cli(debug: bool, verbose: bool) -> None:
    """grainplug: density waves of grains falling through narrow pipes.

    Positions are in mm along the tube from the top of the field of view,
    increasing with the flow; celerities in m/s, positive downstream.
    """
    level = logging.DEBUG if debug else logging.INFO if verbose else logging.WARNING
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")


def _echo_json(data: object) -> None:
    from ..synthetic.writers import _json_default

    click.echo(json.dumps(data, indent=2, default=_json_default))


# ---------------------------------------------------------------------------
@cli.command()
@click.argument("movie", type=click.Path(path_type=Path))
@click.option("--glob", "glob_", default=None, help="For image folders: only files matching this pattern.")
@click.option("--fps", type=float, default=None, help="Frame rate to use instead of the file's.")
@click.option("--json", "as_json", is_flag=True, help="Print the description as JSON.")
def info(movie: Path, glob_: str | None, fps: float | None, as_json: bool) -> None:
    """Describe MOVIE: size, frames, frame rate, bit depth, channels, duration."""
    from ..readers import open_movie

    with open_movie(movie, glob=glob_, fps=fps, verify=True) as m:
        d = m.info.as_dict()
        # decode the last frame: a file that cannot deliver it is reported now
        last = m.read(m.info.n_frames - 1)
        d["last_frame_shape"] = list(last.shape)
        d["timestamps_in_file"] = m.has_file_timestamps
    if as_json:
        _echo_json(d)
        return
    fps_txt = f"{d['fps']:.6g} fps ({d['fps_source']})" if d["fps"] else "unknown (pass --fps)"
    dur = f"{d['duration_s']:.3f} s" if d["duration_s"] is not None else "unknown"
    kind = "grey" if d["channels"] == 1 else "RGB"
    click.echo(f"movie      {d['path']}")
    click.echo(f"format     {d['format']}")
    click.echo(f"size       {d['width']} x {d['height']} px")
    click.echo(f"frames     {d['n_frames']}")
    click.echo(f"frame rate {fps_txt}")
    click.echo(f"bit depth  {d['bit_depth']} ({d['dtype']})")
    click.echo(f"channels   {d['channels']} ({kind})")
    click.echo(f"duration   {dur}")


# ---------------------------------------------------------------------------
def _synth_options(f):
    from ..synthetic import FLOW_DIRECTIONS, FORMATS, REGIMES

    opts = [
        click.option("--out", "out", type=click.Path(path_type=Path), required=True,
                     help="Folder to write the movie and its truth into."),
        click.option("--format", "fmt", type=click.Choice(list(FORMATS)), default="tiff", show_default=True),
        click.option("--seed", type=int, default=0, show_default=True),
        click.option("--frames", "n_frames", type=int, default=300, show_default=True),
        click.option("--fps", type=float, default=250.0, show_default=True),
        click.option("--width", "width_px", type=int, default=128, show_default=True,
                     help="Frame width across the tube (canonical vertical view)."),
        click.option("--height", "height_px", type=int, default=640, show_default=True,
                     help="Frame height along the tube (canonical vertical view)."),
        click.option("--mm-per-px", type=float, default=0.185, show_default=True),
        click.option("--tube-diameter-mm", type=float, default=3.0, show_default=True),
        click.option("--wall-mm", type=float, default=1.0, show_default=True),
        click.option("--tube-offset-px", type=float, default=0.0, show_default=True),
        click.option("--tilt-deg", type=float, default=0.0, show_default=True),
        click.option("--flow-direction", type=click.Choice(FLOW_DIRECTIONS), default="down", show_default=True),
        click.option("--polarity", type=click.Choice(["dark", "bright"]), default="dark", show_default=True,
                     help="dark plugs on a bright field, or bright plugs on a dark field"),
        click.option("--grey", "grey", is_flag=True, help="Write grey frames instead of RGB."),
        click.option("--bit-depth", type=click.Choice(["8", "16"]), default="8", show_default=True),
        click.option("--regime", type=click.Choice(REGIMES), default="propagative", show_default=True),
        click.option("--no-plug-fill", type=click.Choice(["empty", "compact"]), default="empty", show_default=True),
        click.option("--celerity-m-s", type=float, default=-0.05, show_default=True),
        click.option("--frequency-hz", type=float, default=7.0, show_default=True),
        click.option("--amplitude-mm", type=float, default=1.5, show_default=True),
        click.option("--stick-fraction", type=float, default=0.5, show_default=True),
        click.option("--plug-length-mm", type=float, default=30.0, show_default=True),
        click.option("--plug-length-sd-mm", type=float, default=2.0, show_default=True),
        click.option("--bubble-length-mm", type=float, default=25.0, show_default=True),
        click.option("--bubble-length-sd-mm", type=float, default=4.0, show_default=True),
        click.option("--merge-split", is_flag=True, help="Let some plugs merge and split again."),
        click.option("--falling-grains-per-mm", type=float, default=0.4, show_default=True),
        click.option("--noise-sigma", type=float, default=3.0, show_default=True),
        click.option("--flicker", type=float, default=0.0, show_default=True),
        click.option("--gradient", type=float, default=0.0, show_default=True),
    ]
    for opt in reversed(opts):
        f = opt(f)
    return f


@cli.command()
@_synth_options
@click.option("--json", "as_json", is_flag=True, help="Print the truth as JSON.")
def synth(out: Path, fmt: str, grey: bool, bit_depth: str, as_json: bool, **kwargs: object) -> None:
    """Render a synthetic plug-flow movie with its ground truth (truth.json)."""
    from ..synthetic import SynthConfig, synthesize

    try:
        cfg = SynthConfig(rgb=not grey, bit_depth=int(bit_depth), **kwargs)
    except TypeError as exc:  # pragma: no cover - option/field mismatch is a bug
        raise ParameterError(str(exc)) from None
    if fmt in ("mraw", "cine") and cfg.rgb:
        cfg = SynthConfig(**{**cfg.as_dict(), "rgb": False, "tint": cfg.tint})
        err_console.print(f"note: {fmt} is written grey")
    with err_console.status(f"rendering {cfg.n_frames} frames"):
        result = synthesize(cfg, out, fmt=fmt)
    if as_json:
        _echo_json(result.truth)
    else:
        click.echo(f"wrote {result.movie} and {result.truth_json.name}")


# ---------------------------------------------------------------------------
@cli.command()
@click.argument("movie", type=click.Path(path_type=Path))
@click.option("--out", "out", type=click.Path(path_type=Path), required=True,
              help="Folder for summary.json, CSV tables, diagram, figures and report.")
@click.option("--fps", type=float, default=None, help="Frame rate (overrides the file; needed for image folders).")
@click.option("--mm-per-px", type=float, default=None, help="Scale; by default measured from the tube's inner width.")
@click.option("--tube-diameter-mm", type=float, default=3.0, show_default=True,
              help="Inner diameter of the tube, for the scale.")
@click.option("--flow-direction", type=click.Choice(["down", "up", "left", "right"]), default=None,
              help="Direction of the grain flow in the image [default: down for a vertical tube].")
@click.option("--min-plug-mm", type=float, default=3.0, show_default=True,
              help="Shortest grain region counted as a plug.")
@click.option("--glob", "glob_", default=None, help="For image folders: only files matching this pattern.")
@click.option("--no-figures", is_flag=True, help="Skip the PNG figures and the HTML report.")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON on stdout.")
def analyze(movie: Path, out: Path, fps: float | None, mm_per_px: float | None,
            tube_diameter_mm: float, flow_direction: str | None, min_plug_mm: float,
            glob_: str | None, no_figures: bool, as_json: bool) -> None:
    """Find the plugs in MOVIE and measure their celerity, length and oscillation."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    from ..analysis import AnalysisParams
    from ..analysis import analyze as run_analysis
    from ..outputs import write_outputs

    params = AnalysisParams(fps=fps, mm_per_px=mm_per_px, tube_diameter_mm=tube_diameter_mm,
                            flow_direction=flow_direction, min_plug_mm=min_plug_mm, glob=glob_)
    with Progress(TextColumn("[progress.description]{task.description}"), BarColumn(),
                  TextColumn("{task.completed}/{task.total} frames"), TimeRemainingColumn(),
                  console=err_console, transient=True, disable=not err_console.is_terminal) as bar:
        task = bar.add_task(f"analysing {movie.name}", total=None)

        def progress(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        result = run_analysis(movie, params, progress=progress)
    write_outputs(result, out, figures=not no_figures, report=not no_figures)
    s = result.summary
    if as_json:
        _echo_json(s)
        return
    if not result.has_plugs:
        err_console.print(result.statement)
    else:
        def fmt(v: object, unit: str = "", nd: int = 4) -> str:
            return "—" if v is None else f"{v:.{nd}f}{unit}" if isinstance(v, float) else f"{v}{unit}"

        ci = s["celerity_ci95_m_s"]
        click.echo(f"regime          {s['regime']}")
        click.echo(f"celerity        {fmt(s['celerity_m_s'], ' m/s')}  (95% CI {fmt(ci[0])} to {fmt(ci[1])})")
        click.echo(f"plug length     {fmt(s['plug_length_mm'], ' mm', 2)}  "
                   f"({fmt(s['plug_length_over_diameter'], ' D', 2)}, {s['n_plugs']} plugs)")
        click.echo(f"bubble length   {fmt(s['bubble_length_mm'], ' mm', 2)}")
        if s["oscillation_frequency_hz"]:
            click.echo(f"oscillation     {fmt(s['oscillation_frequency_hz'], ' Hz', 3)}, "
                       f"amplitude {fmt(s['oscillation_amplitude_mm'], ' mm', 2)}")
        click.echo(f"scale           {fmt(s['mm_per_px'], ' mm/px', 5)} from {s['scale_source']}")
    click.echo(f"outputs in      {out}")
