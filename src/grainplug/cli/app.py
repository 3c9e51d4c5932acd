"""Click commands. Each command parses options, calls the library and prints."""

from __future__ import annotations

import contextlib
import json
import logging
from pathlib import Path
from typing import TYPE_CHECKING

import click
from click.core import ParameterSource
from rich.console import Console
from rich.markup import escape

from .._format import with_interval
from .._version import __version__
from ..errors import ParameterError
from ..params import FLOW_DIRECTIONS
from .config import ConfigCommand
from .types import FINITE, FRAME_OR_TIME, Number, param_number

if TYPE_CHECKING:
    from ..campaigns.batch import Campaign

err_console = Console(stderr=True)


def in_flags(text: str) -> str:
    """A library message in this command line's words: each keyword it names (``mm_per_px=``) as the option."""
    from .words import as_flags, option_flags

    return as_flags(text, option_flags(cli))


def say_warning(line: str, prefix: str = "") -> None:
    """``warning: <prefix><line>`` on stderr, the library's keywords named as this command line's options."""
    err_console.print(f"[yellow]warning:[/] {escape(prefix + in_flags(line))}", highlight=False, soft_wrap=True)


class LazyGroup(click.Group):
    """Commands whose options need heavy imports are loaded when named (click's lazy-loading
    pattern), so that every other command starts without them."""

    LAZY = {"synth": "grainplug.cli.synth"}  # noqa: RUF012 - a constant

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted([*super().list_commands(ctx), *self.LAZY])

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
    # without --verbose or --debug, libraries' log lines stay quiet: what matters reaches the user
    # as grainplug's own one-line warnings and errors
    level = logging.DEBUG if debug else logging.INFO if verbose else logging.ERROR
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")


OVERWRITE_HELP = ("Replace --out if it holds an earlier result (the whole folder; refused if it holds anything "
                  "grainplug did not write there, such as your notes or a reviewer's corrections.json).")
PUBLICATION_HELP = ("Every figure also as SVG and PDF, for a journal (about 0.6 s more a run; "
                    "publication = true in grainplug.toml keeps it on).")


def _refuse_existing(out: Path, overwrite: bool) -> None:
    """An existing, non-empty output folder is replaced only when asked (``--overwrite``)."""
    if overwrite or not out.exists() or (out.is_dir() and not any(out.iterdir())):
        return
    what = "folder" if out.is_dir() else "file"
    raise ParameterError(f"--out {out}: that {what} already exists — pass --overwrite to replace it, or give "
                         "another --out")


def _roi_option(text: str | None) -> tuple[int, int, int, int] | None:
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


def _figure_options(dpi: int | None, formats: str | None, publication: bool, style: str | None):
    """``FigureOptions`` of the figure flags (checked before the analysis)."""
    from ..plotting.options import PUBLICATION, FigureOptions

    if publication and formats:
        raise ParameterError("give either --publication (PNG, SVG and PDF) or --figure-formats, not both")
    base = PUBLICATION if publication else FigureOptions()
    fmts = tuple(f.strip().lower() for f in formats.split(",") if f.strip()) if formats else base.formats
    if style and not (Path(style).is_file() or _known_style(style)):
        raise ParameterError(f"--style {style}: neither a file nor a matplotlib style sheet name")
    try:
        return FigureOptions(dpi=dpi or base.dpi, formats=fmts, style=style)
    except ParameterError as exc:
        raise ParameterError(f"--{'dpi' if exc.param == 'dpi' else 'figure-formats'}: {exc.message}") from None


def _known_style(name: str) -> bool:
    import matplotlib.style

    return name in matplotlib.style.available or name == "default"


def _echo_json(data: object) -> None:
    from ..jsonio import dumps

    click.echo(dumps(data), nl=False)


# ---------------------------------------------------------------------------
@cli.command()
@click.argument("movie", type=click.Path(path_type=Path))
@click.option("--glob", "glob_", default=None, help="For image folders: only files matching this pattern.")
@click.option("--fps", type=param_number("fps"), default=None,
              help="Frame rate to use instead of the file's.")
@click.option("--allow-truncated", is_flag=True,
              help="For camera files that end early: describe the complete frames instead of refusing.")
@click.option("--json", "as_json", is_flag=True, help="Print the description as JSON.")
def info(movie: Path, glob_: str | None, fps: float | None, allow_truncated: bool, as_json: bool) -> None:
    """Describe MOVIE: size, frames, frame rate and how it was derived, bit depth, colour, camera."""
    from ..readers import open_movie

    with open_movie(movie, glob=glob_, fps=fps, verify=True, allow_truncated=allow_truncated) as m:
        d = m.info.as_dict()
        # decode the last frame: a file that cannot deliver it is reported now
        last = m.read(m.info.n_frames - 1)
        d["last_frame_shape"] = list(last.shape)
        # how an analysis times the frames, as the pipeline decides (a camera file's stamps, when they keep to a
        # constant rate, give that rate: fps_note)
        from ..pipeline import timing_stamps

        by_stamps = timing_stamps(m, m.info) is not None
        d["frame_times"] = "the file's time stamps (unevenly spaced)" if by_stamps else "frame index / fps"
    if as_json:
        _echo_json(d)
        return
    how = f": {d['fps_note']}" if d.get("fps_note") else ""
    fps_txt = f"{d['fps']:.6g} fps ({d['fps_source']}{how})" if d["fps"] else "unknown (pass --fps)"
    from .._format import duration

    dur = duration(d["duration_s"]) if d["duration_s"] is not None else "unknown"
    kind = "grey" if d["channels"] == 1 else "RGB"
    click.echo(f"movie      {d['path']}")
    click.echo(f"format     {d['format']}")
    click.echo(f"size       {d['width']} x {d['height']} px")
    click.echo(f"frames     {d['n_frames']}")
    click.echo(f"frame rate {fps_txt}")
    if d.get("record_fps"):
        click.echo(f"recorded   {d['record_fps']:.6g} fps")
    click.echo(f"bit depth  {d['bit_depth']} ({d['dtype']})")
    click.echo(f"channels   {d['channels']} ({d.get('colour') or kind})")
    click.echo(f"duration   {dur}")
    if d.get("camera"):
        click.echo(f"camera     {d['camera']}")
    details = d.get("details") or {}
    flips = [name for name, key in (("vertical", "flip_vertical"), ("horizontal", "flip_horizontal"))
             if details.get(key)]
    if flips:
        click.echo(f"flipped    {' and '.join(flips)} (applied, as the camera was set)")
    if details.get("timestamp_jitter"):
        click.echo(f"time stamp jitter {100 * float(details['timestamp_jitter']):.2g} %")
    for line in d.get("warnings") or []:
        say_warning(line)


# ---------------------------------------------------------------------------
@cli.command()
@click.argument("image", type=click.Path(path_type=Path))
@click.option("--pitch-mm", type=Number(1e-3, 1e4, unit="mm"), required=True,
              help="Distance between neighbouring checkerboard corners (a square's side), dot centres, graph-paper "
                   "lines or ruler ticks, in mm.")
@click.option("--pattern", type=click.Choice(["auto", "checkerboard", "dots", "graph", "ruler"]), default="auto",
              show_default=True, help="The pattern in the image (graph: graph paper; ruler: a ruler's ticks).")
@click.option("--out", "out", type=click.Path(path_type=Path), default=Path("calibration.json"), show_default=True,
              help="Where to write the calibration; a PNG of what was found is written beside it.")
@click.option("--json", "as_json", is_flag=True, help="Print the calibration as JSON.")
def calibrate(image: Path, pitch_mm: float, pattern: str, out: Path, as_json: bool) -> None:
    """The scale (mm per pixel) from IMAGE of a checkerboard, a dot grid, graph paper or a ruler held at the
    tube's plane.

    IMAGE is a picture (PNG, TIFF, JPEG, BMP) or a short movie of the pattern taken with the
    camera and lens of the experiment (its first frames are averaged). Writes OUT (JSON, with the
    image's fingerprint) and OUT with a .png suffix: the image with the points found. Use it with
    `grainplug analyze MOVIE --calibration OUT`.
    """
    from ..calibration.files import calibrate_file, draw_calibration, read_calibration_image, save_calibration

    if not (pitch_mm > 0 and pitch_mm < 1e4):
        raise ParameterError(f"--pitch-mm must be a length between 0 and 10 m, got {pitch_mm}")
    if out.suffix.lower() != ".json":
        raise ParameterError(f"--out must name a .json file, got {out}")
    cal = calibrate_file(image, pitch_mm=pitch_mm, pattern=pattern)
    save_calibration(cal, out)
    figure = draw_calibration(read_calibration_image(image), cal, out.with_suffix(".png"))
    if as_json:
        _echo_json(cal.as_dict())
    else:
        click.echo(f"scale       {cal.mm_per_px:.6g} mm/px ± {100 * cal.rel_sd:.2g} % "
                   f"(x {cal.mm_per_px_x:.6g}, y {cal.mm_per_px_y:.6g})")
        if cal.pattern in ("graph", "ruler"):
            what = "line crossings" if cal.pattern == "graph" else "ticks"
            click.echo(f"pattern     {cal.pattern}, {cal.n_points} {what}, pitch {cal.pitch_mm:g} mm "
                       "(from the lines' spatial frequency)")
        else:
            click.echo(f"pattern     {cal.pattern}, {cal.n_points} points, pitch {cal.pitch_mm:g} mm, "
                       f"fit residual {cal.rms_residual_px:.2f} px")
        click.echo(f"tilt        {cal.tilt_deg:+.2f}°")
        click.echo(f"variation   {100 * cal.scale_variation:.2g} % over the pattern")
        click.echo(f"written     {out} and {figure}")
    for line in cal.warnings:
        say_warning(line)


# ---------------------------------------------------------------------------
@cli.command(cls=ConfigCommand)
@click.argument("movie", type=click.Path(path_type=Path))
@click.option("--out", "out", type=click.Path(path_type=Path), required=True,
              help="Folder for summary.json, CSV tables, diagram, figures and report.")
@click.option("--config", "config", type=click.Path(path_type=Path), default=None,
              help="Settings file (TOML, [analyze] table of these options); default: grainplug.toml beside the "
                   "movie, if there is one. Options given here win over it.")
@click.option("--fps", type=param_number("fps"), default=None,
              help="Frame rate (overrides the file; needed for image folders).")
@click.option("--mm-per-px", type=param_number("mm_per_px"), default=None,
              help="Scale; by default measured from the tube.")
@click.option("--tube-diameter-mm", type=param_number("tube_diameter_mm"), default=None,
              help="Inner diameter of the tube, for the scale measured from the tube [default: 3].")
@click.option("--tube-outer-diameter-mm", type=param_number("tube_outer_diameter_mm"), default=None,
              help="Outer diameter of the tube: the scale then comes from its outer silhouette (any lighting).")
@click.option("--glass-index", type=param_number("glass_index"), default=1.47, show_default=True,
              help="Refractive index of the tube's glass (1.47 borosilicate, 1.52 soda-lime), for the tube model.")
@click.option("--flow-direction", type=click.Choice(FLOW_DIRECTIONS), default=None,
              help="Direction of the grain flow in the image [default: the way the grains fall through the "
                   "bubbles; if none are seen, down a vertical tube, or right along a horizontal one, with a "
                   "warning].")
@click.option("--min-plug-mm", type=param_number("min_plug_mm"), default=3.0, show_default=True,
              help="Shortest grain region counted as a plug.")
@click.option("--min-gap-mm", type=param_number("min_gap_mm"), default=0.6, show_default=True,
              help="Shortest gap between grains counted as a bubble.")
@click.option("--glob", "glob_", default=None, help="For image folders: only files matching this pattern.")
@click.option("--threads", type=Number(1, 1024, integer=True), default=None,
              help="Threads reading uncompressed frames (TIFF stacks, raw video) [default: one per core].")
@click.option("--calibration", "calibration", type=click.Path(path_type=Path), default=None,
              help="calibration.json from `grainplug calibrate`: the scale, instead of the tube's width.")
@click.option("--background", "background", type=click.Path(path_type=Path), default=None,
              help="Light calibration: a picture or short movie of the tube empty (or full), nothing moving, "
                   "to flat-field the light along the tube.")
@click.option("--allow-truncated", is_flag=True,
              help="For camera files that end early: analyse the complete frames instead of refusing.")
@click.option("--start", "start", type=FRAME_OR_TIME, default=None,
              help="Analyse from this frame (e.g. 120) or time (e.g. 2.5s) on: leave out the start-up transient.")
@click.option("--end", "end", type=FRAME_OR_TIME, default=None,
              help="Analyse up to this frame (excluded) or time.")
@click.option("--roi", "roi", default=None, metavar="X0,Y0,X1,Y1",
              help="Analyse only this rectangle of the frames (pixels; x1, y1 excluded): choose one tube when "
                   "the frame holds several.")
@click.option("--no-figures", is_flag=True, help="Skip the figures and the HTML report.")
@click.option("--dpi", type=Number(20, 1200, integer=True), default=None,
              help="Resolution of the PNG figures [default: 200].")
@click.option("--figure-formats", default=None, metavar="png,svg,pdf",
              help="Formats of every figure, comma-separated [default: png, or all three with --publication].")
@click.option("--publication", is_flag=True, help=PUBLICATION_HELP)
@click.option("--style", "style", default=None,
              help="A matplotlib style sheet (a name or a .mplstyle file) for every figure.")
@click.option("--overwrite", is_flag=True, help=OVERWRITE_HELP)
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON on stdout.")
def analyze(movie: Path, out: Path, config: Path | None, fps: float | None, mm_per_px: float | None,
            tube_diameter_mm: float | None, tube_outer_diameter_mm: float | None, glass_index: float,
            flow_direction: str | None, min_plug_mm: float, min_gap_mm: float, glob_: str | None,
            threads: int | None,
            calibration: Path | None, background: Path | None, allow_truncated: bool,
            start: tuple[str, float] | None, end: tuple[str, float] | None, roi: str | None, no_figures: bool,
            dpi: int | None,
            figure_formats: str | None, publication: bool, style: str | None, overwrite: bool,
            as_json: bool) -> None:
    """Find the plugs in MOVIE and measure their celerity, length and oscillation."""
    from .._atomic import check_output_place
    from ..params import AnalysisParams
    from ..plotting.worker import FigureWorker

    check_output_place(out, inputs=[movie], replace=True)  # before the analysis, not after it
    _refuse_existing(out, overwrite)
    # a setting of grainplug.toml gives way to the command line: --figure-formats over publication = true, and
    # --publication over figure_formats = "..."
    source = click.get_current_context().get_parameter_source
    if publication and figure_formats and source("publication") != source("figure_formats"):
        if source("publication") is ParameterSource.COMMANDLINE:
            figure_formats = None
        else:
            publication = False
    figure_options = _figure_options(dpi, figure_formats, publication, style)
    roi_px = _roi_option(roi)
    if mm_per_px is not None and tube_diameter_mm is not None:
        raise ParameterError("give either --mm-per-px (the scale) or --tube-diameter-mm (scale from the tube), "
                             "not both")
    if mm_per_px is not None and calibration is not None:
        raise ParameterError("give either --mm-per-px or --calibration (the scale), not both")
    cal = None
    if calibration is not None:
        from ..calibration.files import load_calibration

        cal = load_calibration(calibration)
    light = None
    if background is not None:
        from ..calibration.files import read_background

        light = read_background(background)
    diameter = 3.0 if tube_diameter_mm is None else tube_diameter_mm
    params = AnalysisParams(fps=fps, mm_per_px=mm_per_px, tube_diameter_mm=diameter,
                            tube_outer_diameter_mm=tube_outer_diameter_mm, glass_index=glass_index,
                            flow_direction=flow_direction, min_plug_mm=min_plug_mm, min_gap_mm=min_gap_mm, glob=glob_,
                            allow_truncated=allow_truncated, calibration=cal, background=light, roi=roi_px,
                            **_window_params(start, end))
    # the figures' worker starts now, before the analysis' own imports (numpy among them): it imports
    # matplotlib while they load, the tube is found and the frames stream
    with FigureWorker(figure_options.formats) if not no_figures else contextlib.nullcontext() as figure_worker:
        from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

        from ..pipeline import analyze as run_analysis

        with Progress(TextColumn("[progress.description]{task.description}"), BarColumn(),
                      TextColumn("{task.completed}/{task.total} frames"), TimeRemainingColumn(),
                      console=err_console, transient=True, disable=not err_console.is_terminal) as bar:
            task = bar.add_task(f"analysing {movie.name}", total=None)

            def progress(done: int, total: int) -> None:
                bar.update(task, completed=done, total=total)

            result = run_analysis(movie, params, progress=progress, threads=threads)
        result.save(out, figures=not no_figures, report=not no_figures, figure_worker=figure_worker,
                    figure_options=figure_options)
    s = json.loads((out / "summary.json").read_text())  # what was written: outputs and figure settings too
    settings = click.get_current_context().meta.get("grainplug.config")
    if settings is not None:  # said once the run is done: a refusal stays one line
        err_console.print(f"settings from {escape(str(settings))}", highlight=False, soft_wrap=True)
    for line in result.warnings:
        say_warning(line)
    if as_json:
        _echo_json(s)
        return
    if not result.has_plugs or s.get("celerity_m_s") is None:
        err_console.print(escape(in_flags(result.statement)), highlight=False, soft_wrap=True)
    if result.has_plugs:
        def fmt(v: object, unit: str = "", nd: int = 4) -> str:
            return "—" if v is None else f"{v:.{nd}f}{unit}" if isinstance(v, float) else f"{v}{unit}"

        ci = s.get("celerity_ci95_m_s") or [None, None]
        # three significant digits (a slow plug is not -0.0000), more where the interval is narrower than that
        value, lo, hi = with_interval(s["celerity_m_s"], *ci)
        still = ci[0] is not None and ci[1] is not None and ci[0] <= 0 <= ci[1]
        note = ("  (the plugs did not move by a pixel over the record)" if s["regime"] == "static" else
                "  (no direction of travel: the celerity's 95% CI holds 0)" if still else "")
        click.echo(f"regime          {s['regime']}{note}")
        click.echo(f"celerity        {value} m/s  (95% CI {lo} to {hi})")
        n_plugs = s["n_plugs"]
        click.echo(f"plug length     {fmt(s['plug_length_mm'], ' mm', 2)}  "
                   f"({fmt(s['plug_length_over_diameter'], ' D', 2)}, {n_plugs} plug{'' if n_plugs == 1 else 's'})")
        click.echo(f"bubble length   {fmt(s['bubble_length_mm'], ' mm', 2)}")
        if s["oscillation_frequency_hz"]:
            click.echo(f"oscillation     {fmt(s['oscillation_frequency_hz'], ' Hz', 3)}, "
                       f"amplitude {fmt(s['oscillation_amplitude_mm'], ' mm', 2)}")
        click.echo(f"scale           {fmt(s['mm_per_px'], ' mm/px', 5)} from {s['scale_source']}")
    click.echo(f"outputs in      {out}")


#: the most run warnings ``batch`` prints; the rest are counted, and all are in campaign.csv and the report
MAX_RUN_WARNINGS = 20


def _print_run_warnings(camp: Campaign, out: Path) -> None:
    """Each run's warnings, as ``analyze`` prints them (``warning: run X: ...``), at most
    :data:`MAX_RUN_WARNINGS` lines."""
    lines = camp.run_warnings
    for run, w in lines[:MAX_RUN_WARNINGS]:
        say_warning(w, f"run {run}: ")
    if len(lines) > MAX_RUN_WARNINGS:
        err_console.print(f"[yellow]warning:[/] {len(lines) - MAX_RUN_WARNINGS} more run warnings: see the warnings "
                          f"column of {escape(str(out / 'campaign.csv'))} and the report", highlight=False,
                          soft_wrap=True)


def _window_params(start: tuple[str, float] | None, end: tuple[str, float] | None) -> dict[str, float | int]:
    """``--start/--end`` as :class:`AnalysisParams` fields (``start_frame`` or ``start_s``...)."""
    out: dict[str, float | int] = {}
    for name, point in (("start", start), ("end", end)):
        if point is not None:
            kind, value = point
            out[f"{name}_frame" if kind == "frame" else f"{name}_s"] = int(value) if kind == "frame" else value
    return out


# ---------------------------------------------------------------------------
#: the set-up of the paper's model (each default the paper as printed), shared by stability and simulate
_MODEL_OPTIONS = [
    click.option("--diameter-mm", type=FINITE, default=3.0, show_default=True, help="Pipe inner diameter D."),
    click.option("--grain-diameter-um", type=FINITE, default=225.0, show_default=True, help="Grain diameter d."),
    click.option("--c0", type=FINITE, default=0.55, show_default=True, help="Base-state compactness."),
    click.option("--kappa", type=FINITE, default=0.5, show_default=True, help="Janssen coefficient."),
    click.option("--mu-s", type=FINITE, default=0.6249, show_default=True, help="Friction coefficient (tan 32°)."),
    click.option("--theta-deg", type=FINITE, default=0.0, show_default=True, help="Pipe inclination from vertical."),
    click.option("--gamma", type=FINITE, default=1.4, show_default=True, help="Ratio of specific heats of air."),
    click.option("--air-viscosity-pa-s", type=FINITE, default=1.8e-5, show_default=True),
    click.option("--grain-density-kg-m3", type=FINITE, default=2500.0, show_default=True),
    click.option("--b", "b", type=FINITE, default=1.0, show_default=True, help="Capillary factor on friction."),
    click.option("--B1-star", "b1_star", type=FINITE, default=None,
              help="Use this B1* instead of computing it from D, d, c0, gamma, mu_a, rho_s."),
    click.option("--variant", type=click.Choice(["printed", "frozen-friction"]), default="printed", show_default=True,
              help="printed: the paper's equations as printed; frozen-friction: wall friction not perturbed "
                   "(= --friction-law coulomb-frozen)."),
    click.option("--friction-law", type=click.Choice(["v2", "v|v|", "coulomb-frozen", "coulomb-weight"]), default=None,
              metavar="LAW",
              help="Wall friction F(c, v), one of: v2 as printed (2 b mu_s v^2), v|v| (signed), coulomb-frozen "
                   "(held at its base value), coulomb-weight (following the local weight) [default: v2, or the "
                   "variant's]."),
    click.option("--base-pressure", "base_pressure", default="printed", show_default=True,
              metavar="printed|atmospheric|PA",
              help="Absolute air pressure of the base state: as printed (P* = 1, i.e. rho_s g D = 74 Pa), the "
                   "atmosphere (101325 Pa), or a value in Pa; B1* and the compressibility term follow it."),
    click.option("--base-velocity", type=click.Choice(["printed", "balanced"]), default="printed", show_default=True,
              help="printed: v* = 1; balanced: the velocity at which wall friction carries the weight."),
    click.option("--jamming", is_flag=True,
              help="Add a jamming pressure Fr (c - c_min)^2 / (c_max - c)^5 (Johnson & Jackson) to the grains' "
                   "momentum: it diverges at random close packing (not in the paper)."),
    click.option("--jamming-fr-pa", type=Number(0, 1e6, unit="Pa"), default=0.05, show_default=True,
              help="Its constant Fr."),
    click.option("--jamming-c-max", type=Number(0.01, 0.99), default=0.64, show_default=True,
              help="Its random close packing c_max (it starts at c_min = 0.50)."),
]


def _model_options(f):
    for option in reversed(_MODEL_OPTIONS):
        f = option(f)
    return f


def _model_params(diameter_mm: float, grain_diameter_um: float, c0: float, kappa: float, mu_s: float,
                  theta_deg: float, gamma: float, air_viscosity_pa_s: float, grain_density_kg_m3: float,
                  b: float, b1_star: float | None, variant: str, friction_law: str | None, base_pressure: str,
                  base_velocity: str, jamming: bool, jamming_fr_pa: float, jamming_c_max: float):
    """The :class:`ModelParams` of the model options."""
    from ..stability import P_ATM_PA, ModelParams

    if base_pressure == "printed":
        base_pressure_pa = None
    elif base_pressure == "atmospheric":
        base_pressure_pa = P_ATM_PA
    else:
        try:
            base_pressure_pa = float(base_pressure)
        except ValueError:
            raise ParameterError(f"--base-pressure must be printed, atmospheric or a pressure in Pa, "
                                 f"got {base_pressure!r}") from None
    return ModelParams(diameter_mm=diameter_mm, grain_diameter_um=grain_diameter_um, c0=c0, kappa=kappa,
                       mu_s=mu_s, theta_deg=theta_deg, gamma=gamma, air_viscosity_pa_s=air_viscosity_pa_s,
                       grain_density_kg_m3=grain_density_kg_m3, b=b, B1_star_override=b1_star, variant=variant,
                       friction_law=friction_law, base_pressure_pa=base_pressure_pa, base_velocity=base_velocity,
                       jamming=jamming, jamming_fr_pa=jamming_fr_pa, jamming_c_max=jamming_c_max)


@cli.command()
@_model_options
@click.option("--k-min", type=Number(1e-6, 1e4), default=0.001, show_default=True,
              help="Smallest wavenumber, dimensionless (k* = k D; wavelength lambda/D = 2 pi / k*).")
@click.option("--k-max", type=Number(1e-6, 1e4), default=3.0, show_default=True, help="Largest wavenumber k*.")
@click.option("--n-k", type=Number(10, 1e12, unit="wavenumbers", integer=True), default=1000, show_default=True,
              help="How many wavenumbers, evenly spread from --k-min to --k-max (at least 10; solved in chunks with "
                   "flat memory, 10^8 in minutes; refused when estimated over an hour). Beyond 10^5, --json and "
                   "--plot hold a curve of 10^4 of them that keeps the peak and the cut-offs.")
@click.option("--json", "as_json", is_flag=True, help="Print roots, most unstable mode, cut-offs and inputs as JSON.")
@click.option("--plot", "plot", type=click.Path(path_type=Path), default=None,
              help="Write the paper's Fig. 9 (growth rates against k*) to this PNG (with --sweep: lambda/D).")
@click.option("--sweep", "sweep_spec", default=None, metavar="NAME=START:STOP:N",
              help="Vary one input (e.g. grain_diameter_um=50:400:15 or c0=0.45:0.62:10) and report "
                   "the most unstable and cut-off wavelengths for each value.")
def stability(k_min: float, k_max: float, n_k: int, as_json: bool, plot: Path | None, sweep_spec: str | None,
              **model: object) -> None:
    """Linear stability of the paper's 1D model: the three roots omega*(k*).

    Every set-up choice is a switch whose default is the paper as printed: the friction law,
    the base pressure and the base velocity; the output states the base state's residual,
    its absolute pressure and the caveats of the set-up.
    """
    from ..stability import analyze_stability

    p = _model_params(**model)
    variant, base_pressure, base_velocity, jamming = (model["variant"], model["base_pressure"],
                                                      model["base_velocity"], model["jamming"])
    if not (0 < k_min < k_max) or n_k < 10:
        raise ParameterError("need 0 < --k-min < --k-max and --n-k >= 10")
    if plot is not None and plot.suffix.lower() not in (".png", ".svg", ".pdf"):
        raise ParameterError(f"--plot must name a .png, .svg or .pdf file, got {plot.name}")
    if sweep_spec:
        _stability_sweep(p, sweep_spec, k_min=k_min, k_max=k_max, n_k=n_k, as_json=as_json, plot=plot)
        return
    res = analyze_stability(p, k_min=k_min, k_max=k_max, n_k=n_k)
    if plot is not None:
        import matplotlib.pyplot as plt

        from ..plotting.stability import plot_growth_rates

        fig = plot_growth_rates(res)
        _save_figure(fig, plot)
        plt.close(fig)
    if as_json:
        _print_stability_warnings(res.warnings)
        _echo_json({"grainplug_version": __version__, **res.as_dict()})
        return
    m = res.most_unstable
    click.echo(f"variant            {variant}" + ("" if p.is_printed else
                                                      f"   (set-up: friction {p.law}, base pressure "
                                                      f"{base_pressure}, base velocity {base_velocity}"
                                                      + (", jamming pressure" if jamming else "") + ")"))
    click.echo(f"B1*                {p.B1_star:.6g}   (P_c = {p.P_c_pa:.4g} Pa, t_c = {p.t_c_s:.4g} s, "
               f"v_c = {p.v_c_m_s:.4g} m/s)")
    click.echo(f"base state         c0 = {p.c0:g}, v0* = {p.v0_star:.4g} ({p.v0_star * p.v_c_m_s:.3g} m/s), "
               f"P0 = {p.base_pressure_abs_pa:.4g} Pa (P0* = {p.P0_star:.4g}; B* = B1* P0* = {p.B_star:.4g})")
    click.echo(f"base-state balance -c0 cos(theta) + F(c0, v0) = {p.base_state_residual:+.4f} "
               "(0 if the base state were steady)")
    for line in p.caveats():
        click.echo(f"caveat             {in_flags(line)}")
    if m is None:
        click.echo(f"most unstable      none: every k* in [{k_min:g}, {k_max:g}] is stable")
        if p.is_printed:
            click.echo("note               the printed model does not give the paper's long-wave instability "
                       "(k* ~ 0.2, cut-off ~ 0.6); --variant frozen-friction does — see docs/stability.md")
    else:
        label = "most unstable     " if m.at_range_edge is None else "largest in range  "
        click.echo(f"{label} k* = {m.k:.5f}  growth rate {m.growth_rate:.5f}/t_c "
                   f"({m.growth_rate / p.t_c_s:.3g}/s)  phase speed {m.phase_speed:+.4f} v_c "
                   f"({m.phase_speed * p.v_c_m_s:+.3f} m/s)  lambda/D = {m.wavelength_over_diameter:.3f}"
                   + ("" if m.at_range_edge is None else f"  (at {m.at_range_edge}: no maximum inside the range)"))
    for kc in res.cutoff_k:
        click.echo(f"cut-off            k* = {kc:.5f}  lambda/D = {2 * 3.141592653589793 / kc:.3f}")
    if plot is not None:
        click.echo(f"figure             {plot}")
    _print_stability_warnings(res.warnings)


def _print_stability_warnings(lines: list[str]) -> None:
    """The analysis' warnings, its keywords named as this command's flags (k_min=: --k-min)."""
    for line in lines:
        say_warning(line)


@cli.command()
@_model_options
@click.option("--boundary", type=click.Choice(["periodic", "open"]), default="periodic", show_default=True,
              help="periodic: a box that repeats (the linear analysis' set-up); open: a pipe fed at the top, "
                   "the base pressure held at both ends, free outflow at the bottom.")
@click.option("--length-D", "length_D", type=Number(1, 1e6, unit="D"), default=251.0, show_default=True,
              help="Box or pipe length in pipe diameters.")
@click.option("--cells", "n_cells", type=Number(16, 1e6, unit="cells", integer=True), default=1024,
              show_default=True, help="Finite-volume cells.")
@click.option("--duration-tc", type=Number(1e-3, 1e7, unit="t_c"), default=600.0, show_default=True,
              help="Simulated time in units of t_c = sqrt(D/g).")
@click.option("--output-interval-tc", type=Number(1e-4, 1e7, unit="t_c"), default=0.5, show_default=True,
              help="Time between saved fields.")
@click.option("--cfl", type=Number(0.01, 0.5), default=0.4, show_default=True,
              help="Courant number of each Runge-Kutta stage (a step is 3 stages long).")
@click.option("--noise", type=Number(0, 0.099), default=1e-9, show_default=True,
              help="Standard deviation of the initial compactness noise.")
@click.option("--seed", type=Number(0, 2**32 - 1, integer=True), default=0, show_default=True,
              help="Seed of the initial noise.")
@click.option("--feed-c", type=Number(0.001, 0.999), default=None, help="Open pipe: compactness fed at the top "
              "[default: c0].")
@click.option("--feed-v", type=Number(1e-6, 1e3, unit="v_c"), default=None,
              help="Open pipe: velocity of the fed grains in units of v_c [default: the base velocity].")
@click.option("--feed-rate-g-s", type=Number(1e-6, 1e6, unit="g/s"), default=None,
              help="Open pipe: mass flow rate of the grains fed at the top (sets their velocity).")
@click.option("--balance/--no-balance", "balance", default=None,
              help="Add the uniform force S that makes the base state steady, as the linear analysis assumes "
                   "[default: in a periodic box, not in an open pipe].")
@click.option("--out", "out_dir", type=click.Path(path_type=Path), required=True,
              help="Folder for fields.nc, summary.json and diagram.png (replaced as a whole).")
@click.option("--publication", is_flag=True, help=PUBLICATION_HELP)
@click.option("--overwrite", is_flag=True, help=OVERWRITE_HELP)
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
def simulate(boundary: str, length_D: float, n_cells: int, duration_tc: float, output_interval_tc: float, cfl: float,
             noise: float, seed: int, feed_c: float | None, feed_v: float | None, feed_rate_g_s: float | None,
             balance: bool | None, out_dir: Path, publication: bool, overwrite: bool, as_json: bool,
             **model: object) -> None:
    """Integrate the paper's 1D model in time (finite volumes) and measure what it forms.

    Conservative in grain and air mass (the air's mass balance replaces the printed
    pressure equation, to which it linearises). The compactness diagram goes through
    the same plug detection and measures as a movie, beside the linear prediction and
    the waves measured on the fields. See docs/model.md.
    """
    import numpy as np

    from ..simulation import SimulationParams, simulate_and_measure
    from ..simulation.store import save_simulation

    p = _model_params(**model)
    sim = SimulationParams(boundary=boundary, length_D=length_D, n_cells=n_cells, duration_tc=duration_tc,
                           output_interval_tc=output_interval_tc, cfl=cfl, noise=noise, feed_c=feed_c, feed_v=feed_v,
                           feed_rate_g_s=feed_rate_g_s, balance=balance)
    from .._atomic import check_output_place

    check_output_place(out_dir)  # refuse a bad place before the run, not after
    _refuse_existing(out_dir, overwrite)
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed:.0f}/{task.total:g} t_c"),
                  TimeRemainingColumn(), console=err_console, transient=True,
                  disable=not err_console.is_terminal) as bar:
        # the compiled kernel is built on the first run after an install (~15 s), before the first output
        first = "simulating (compiles once after install, ~15 s)"
        task = bar.add_task(first, total=duration_tc)
        res, summary = simulate_and_measure(p, sim, rng=np.random.default_rng(seed),
                                            progress=lambda t, total: bar.update(task, completed=t,
                                                                                 description="simulating"))
    summary["seed"] = seed
    import matplotlib.pyplot as plt

    from ..plotting.simulation import plot_simulation

    fig = plot_simulation(res)
    try:
        options = _figure_options(None, None, publication, None)
        save_simulation(res, out_dir, summary, figure=fig, figure_options=options)
    finally:
        plt.close(fig)
    if as_json:
        _echo_json(summary)
        return
    for line in simulation_lines(summary):
        click.echo(line)
    click.echo(f"outputs            {out_dir}/ (fields.nc, summary.json, diagram.png)")


def simulation_lines(summary: dict) -> list[str]:
    """The terminal report of ``grainplug simulate``."""
    r, w, m, lin = summary["run"], summary["waves"], summary["measured_as_movie"], summary["linear"]
    out = [f"run                {r['boundary']} {r['length_D']:g} D, {r['n_cells']} cells, {r['duration_tc']:g} t_c "
           f"({r['duration_s']:.3g} s) in {r['n_steps']} steps, {r['wall_s']:.1f} s",
           f"conservation       grain {r['grain_drift']:.1e}, air {r['air_drift']:.1e} (relative change)"
           if r["boundary"] == "periodic" else
           # the ends let grains and air in and out: the content's change is no check of the scheme, the grain's
           # budget (change = inflow - outflow) is
           f"content change     grain {r['grain_drift']:.1e}, air {r['air_drift']:.1e} (relative; the pipe's ends "
           "let grains and air in and out)"]
    if r["boundary"] != "periodic" and "grain_budget_residual" in r:
        g0 = abs(r["grain_total"][0]) or 1.0
        out.append(f"grain budget       in {r['grain_inflow'] / g0:.3f}, out {r['grain_outflow'] / g0:.3f} (of the "
                   f"starting content); change - (in - out) = {r['grain_budget_residual']:.1e}")
    if r.get("balance_force_rho_s_g"):
        out.append(f"balance force      S = {r['balance_force_rho_s_g']:+.3f} rho_s g, uniform, so that the base state "
                   "is steady (--no-balance leaves it out)")
    if lin["most_unstable_lambda_D"] is None:
        out.append("linear theory      stable: no wavelength grows")
    else:
        edge = lin.get("most_unstable_at_range_edge")
        what = "most unstable" if not edge else f"largest growth (at {edge} of k* in [0.001, 3]: no maximum inside),"
        out.append(f"linear theory      {what} lambda/D = {lin['most_unstable_lambda_D']:.1f}, growth "
                   f"{lin['growth_rate_per_tc']:.4f}/t_c, phase speed {lin['phase_speed_m_s']:+.3f} m/s")
    if w["n_waves"]:
        fronts = w["front_speed_m_s"]
        fronts = "not followed" if fronts is None or fronts != fronts else f"{fronts:+.3f} m/s"  # NaN: not followed
        out.append(f"waves at the end   {w['n_waves']} in the box, dense segment {w['dense_length_D']:.1f} D "
                   f"({w['dense_fraction']:.2f} of the box), fronts {fronts}, "
                   f"c {w['c_min']:.3f}..{w['c_max']:.3f}")
    else:
        out.append(f"waves at the end   none: {w.get('why_none') or 'the flow stayed uniform'}")
    if m["regime"] == "none":
        out.append(f"as a movie         {in_flags(m['statement'])}")
        if w["n_waves"]:
            out.append(f"                   (c stays within {w['c_min']:.2f}..{w['c_max']:.2f}: no air bubble forms, "
                       "so a camera would see a compact flow)")
    else:
        cel = "-" if m["celerity_m_s"] is None else f"{m['celerity_m_s']:+.3f} m/s"
        plug = "-" if m["plug_length_mm"] is None else f"{m['plug_length_mm']:.1f} mm"
        bub = "-" if m["bubble_length_mm"] is None else f"{m['bubble_length_mm']:.1f} mm"
        out.append(f"as a movie         {m['regime']}: celerity {cel}, plugs {plug}, bubbles {bub}")
    for warning in summary["warnings"]:
        out.append(f"warning            {in_flags(warning)}")
    return out


@cli.command()
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--no-figures", is_flag=True, help="Skip figures and report.")
@click.option("--json", "as_json", is_flag=True, help="Print the new summary as JSON.")
def remeasure(folder: Path, no_figures: bool, as_json: bool) -> None:
    """Reapply FOLDER/corrections.json (a reviewer's edits) to a saved analysis and rewrite its outputs.

    The measures are recomputed from the detected plugs without reading the movie; without a
    corrections file the detection is restored as it was.
    """
    from .._atomic import cwd_inside
    from ..corrections import replayed
    from ..outputs import remeasure as run_remeasure

    if not folder.is_dir():
        raise ParameterError(f"{folder} is not a folder: give the --out folder of an analysis")
    here = cwd_inside(folder)  # `remeasure .`: the shell stays in the folder replaced
    res = run_remeasure(folder, figures=not no_figures, report=not no_figures)
    s = res.summary
    for line in res.warnings:  # as analyze prints them: an edit not applied is said here, not only in the files
        say_warning(line)
    if here:
        err_console.print(f"note: {escape(str(folder))} was replaced whole by its new version: a shell in it still "
                          "sees the old, removed folder — `cd .` to see the new one", highlight=False, soft_wrap=True)
    if as_json:
        _echo_json(s)
        return
    st = replayed(res)
    n_edits = 0 if res.corrections is None else len(res.corrections.edits)
    applied = [] if st is None else [e.describe() for e in st.applied]
    empty = 0 if st is None else len(st.empty_windows)
    said = f"{len(applied)} applied" if len(applied) == n_edits else f"{len(applied)} of {n_edits} applied"
    said += ": " + "; ".join(applied) if applied else ""
    if len(applied) < n_edits:
        said += f" — {n_edits - len(applied)} not applied (see the warnings)"
    if empty:
        which = "it holds" if len(applied) == 1 else f"{empty} of them hold{'s' if empty == 1 else ''}"
        said += f" — {which} none of the record: no plugs are left (see the warnings)"
    click.echo(f"corrections        {said}")
    cel = "-" if s["celerity_m_s"] is None else f"{s['celerity_m_s']:+.4f} m/s"
    plug = "-" if s["plug_length_mm"] is None else f"{s['plug_length_mm']:.2f} mm"
    click.echo(f"regime             {s['regime']}; celerity {cel}; plug length {plug}")
    if res.statement:
        click.echo(f"note               {in_flags(res.statement)}")
    click.echo(f"outputs            {folder}/")


@cli.command()
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--port", type=Number(0, 65535, integer=True), default=0, show_default=True,
              help="Port on 127.0.0.1 (0: a free one).")
@click.option("--no-browser", is_flag=True, help="Do not open a browser (print the address only).")
def review(folder: Path, port: int, no_browser: bool) -> None:
    """Review an analysis (or a campaign's runs) in the browser: the diagram, any frame with its
    edges, the tracks; exclude, merge or split tracks, set a time window or spans without plugs.

    Edits are kept in FOLDER/corrections.json at once and the measures recomputed; "Write
    outputs" rewrites the run's files (as grainplug remeasure). Served on 127.0.0.1 only,
    offline; Ctrl-C stops it.
    """
    import threading
    import webbrowser

    from ..review import ReviewServer

    try:
        server = ReviewServer(folder, port=port)
    except OSError as exc:
        raise ParameterError(f"cannot listen on 127.0.0.1:{port} ({exc.strerror or exc}) — choose another --port "
                             "or 0") from None
    with server:
        click.echo(f"review             {server.url}  (Ctrl-C to stop)")
        if not no_browser:
            webbrowser.open(server.url)
        try:
            threading.Event().wait()
        except KeyboardInterrupt:
            click.echo("review stopped")


@cli.command()
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--out", "out", type=click.Path(path_type=Path), default=None,
              help="The video: .mp4 (H.264, needs PyAV: pip install \"grainplug[video]\") or .webm (VP8) "
                   "[default: FOLDER/overlay.mp4 with PyAV, else FOLDER/overlay.webm].")
@click.option("--slowdown", type=Number(0.01, 1e6), default=None,
              help="Play this many times slower than real time [default: at most 30 frames per second].")
@click.option("--every", type=Number(1, 1e6, integer=True), default=1, show_default=True,
              help="Keep one frame in this many.")
def overlay(folder: Path, out: Path | None, slowdown: float | None, every: int) -> None:
    """Write a video of the analysed movie around the tube with the detected edges, track numbers,
    a scale bar and the time stamp (for checking by eye and for supplementary material): an H.264 MP4
    where PyAV is installed, else a VP8 WebM."""
    from ..overlay import write_overlay

    if not folder.is_dir():
        raise ParameterError(f"{folder} is not a folder: give the --out folder of an analysis")
    path = write_overlay(folder, out, slowdown=slowdown, every=every)
    click.echo(f"overlay            {path}")


_SWEEP_NAMES = {"B1_star": "B1_star_override", "B1-star": "B1_star_override"}


#: axis labels of the inputs a sweep varies
SWEEP_LABELS = {"diameter_mm": "pipe diameter D (mm)", "grain_diameter_um": "grain diameter d (µm)",
                "grain_density_kg_m3": "grain density ρs (kg/m³)", "air_viscosity_pa_s": "air viscosity (Pa s)",
                "gamma": "ratio of specific heats γ", "g_m_s2": "gravity g (m/s²)", "c0": "compactness c0",
                "kappa": "Janssen coefficient κ", "mu_s": "friction coefficient μs", "theta_deg": "inclination θ (°)",
                "b": "capillary factor b", "B1_star_override": "B1*", "base_pressure_pa": "base pressure P0 (Pa)",
                "jamming_fr_pa": "jamming constant Fr (Pa)", "jamming_c_min": "jamming c_min",
                "jamming_c_max": "jamming c_max"}


def _stability_sweep(p, spec: str, *, k_min: float, k_max: float, n_k: int, as_json: bool,
                     plot: Path | None) -> None:
    """``--sweep NAME=START:STOP:N``: lambda/D of the most unstable mode and of the cut-offs."""
    import dataclasses

    import numpy as np

    from ..stability import ModelParams, sweep
    from ..stability.analysis import check_sweep_size

    try:
        name, rng = spec.split("=", 1)
        start, stop, count = rng.split(":")
        first, last, n = float(start), float(stop), float(count)
        if not (np.isfinite(first) and np.isfinite(last) and n >= 1 and n == int(n)):
            raise ValueError
    except (ValueError, OverflowError):
        raise ParameterError(f"--sweep {spec!r}: write NAME=START:STOP:N (N a whole number >= 1), "
                             "e.g. c0=0.45:0.62:10") from None
    name = _SWEEP_NAMES.get(name.strip(), name.strip().replace("-", "_"))
    fields = {f.name for f in dataclasses.fields(ModelParams)} - {"variant"}
    if name not in fields:
        raise ParameterError(f"--sweep: unknown input {name!r}; choose one of {', '.join(sorted(fields))}")
    check_sweep_size(int(n), param="sweep")  # before the values are made
    values = np.linspace(first, last, int(n))
    try:
        rows = sweep(p, name, values, k_min=k_min, k_max=k_max, n_k=n_k)
    except ParameterError as exc:  # the sweep's values are this option's
        if exc.param != "values":
            raise
        raise ParameterError(exc.message, param="sweep") from None
    if plot is not None:
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6.4, 4.4), constrained_layout=True)
        x = [r[name] for r in rows]
        ax.plot(x, [r["most_unstable_wavelength_over_diameter"] or np.nan for r in rows], "o-",
                label="most unstable λ/D")
        ax.plot(x, [(r["cutoff_wavelength_over_diameter"] or [np.nan])[0] for r in rows], "s--",
                label="cut-off λ/D")
        ax.set_xlabel(SWEEP_LABELS.get(name, name))
        ax.set_ylabel("λ/D")
        ax.set_title(f"variant '{p.variant}'", fontsize=9)
        ax.legend(fontsize=8)
        _save_figure(fig, plot)
        plt.close(fig)
    edge = [f"{r[name]:g}" for r in rows if r.get("most_unstable_at_range_edge")]
    if edge:
        err_console.print(f"[yellow]warning:[/] for {name} = {', '.join(edge)} the growth rate is largest at an end of "
                          f"the k* range: its k* max is that end, not a maximum — widen --k-min/--k-max",
                          highlight=False, soft_wrap=True)
    if as_json:
        _echo_json({"grainplug_version": __version__, "variant": p.variant, "input": name, "rows": rows,
                    "inputs": p.as_dict()})
        return
    click.echo(f"{name:>18s} {'B1*':>8s} {'k* max':>8s} {'λ/D max':>8s} {'cut-off k*':>10s} {'λ/D cut':>8s}")
    for r in rows:
        km, lm = r["most_unstable_k"], r["most_unstable_wavelength_over_diameter"]
        kc = r["cutoff_k"][0] if r["cutoff_k"] else None
        lc = r["cutoff_wavelength_over_diameter"][0] if r["cutoff_k"] else None

        def f(v, nd=4):
            return f"{v:.{nd}f}" if v is not None else "stable"

        click.echo(f"{r[name]:18.5g} {r['B1_star']:8.4f} {f(km):>8s} {f(lm, 2):>8s} {f(kc):>10s} {f(lc, 2):>8s}")


def _save_figure(fig, path: Path) -> None:
    """Save a figure atomically."""
    from .._atomic import atomic_file

    with atomic_file(path) as tmp:
        fig.savefig(tmp, dpi=120, format=path.suffix.lstrip(".") or "png")


@cli.command()
@click.option("--compactness", type=FINITE, default=0.55, show_default=True, help="Grain volume fraction c.")
@click.option("--grain-density-kg-m3", type=FINITE, default=2500.0, show_default=True)
@click.option("--grain-sound-speed-m-s", type=FINITE, default=5000.0, show_default=True)
@click.option("--pressure-pa", type=FINITE, default=101325.0, show_default=True)
@click.option("--temperature-k", type=FINITE, default=293.15, show_default=True)
@click.option("--gamma", type=FINITE, default=1.4, show_default=True)
@click.option("--isothermal", is_flag=True, help="Isothermal air (default: adiabatic).")
@click.option("--column-length-m", type=FINITE, default=1.0, show_default=True, help="Length of the grain-air column.")
@click.option("--plug-length-m", type=FINITE, default=0.03, show_default=True)
@click.option("--air-column-m", type=FINITE, default=1.0, show_default=True,
              help="Length of the air column under the plug (the spring).")
@click.option("--json", "as_json", is_flag=True, help="Print the inputs, sound speeds and modes as JSON.")
def resonance(as_json: bool, **kwargs: object) -> None:
    """Acoustic resonance of the grain-air column (Wood's sound speed, pipe modes, plug on air spring)."""
    from ..stability.resonance import ResonanceInputs
    from ..stability.resonance import resonance as compute

    r = compute(ResonanceInputs(**kwargs))
    if as_json:
        _echo_json({"grainplug_version": __version__, **r})
        return
    click.echo(f"air             {r['process']}, sound speed {r['air_sound_speed_m_s']:.1f} m/s, "
               f"density {r['air_density_kg_m3']:.3f} kg/m3")
    click.echo(f"mixture (Wood)  sound speed {r['mixture_sound_speed_m_s']:.2f} m/s, "
               f"density {r['mixture_density_kg_m3']:.1f} kg/m3")
    click.echo("half-wave       " + ", ".join(f"{f:.2f}" for f in r["half_wave_hz"]) + " Hz")
    click.echo("quarter-wave    " + ", ".join(f"{f:.2f}" for f in r["quarter_wave_hz"]) + " Hz")
    spring = r["plug_on_air_spring_hz"]
    click.echo(f"plug on spring  {'none (no grains)' if spring is None else f'{spring:.2f} Hz'}")


# ---------------------------------------------------------------------------
@cli.command()
@click.option("--out", "out", type=click.Path(path_type=Path), required=True,
              help="Folder for paper.json, reproduction.md, figures and report.html.")
@click.option("--no-figures", is_flag=True, help="Skip figures and report.")
@click.option("--json", "as_json", is_flag=True, help="Print fits, lengths, stability and checks as JSON.")
@click.option("--no-simulations", is_flag=True,
              help="Compare the measurements with the linear theory only (skip the ~4 s of nonlinear runs).")
@click.option("--publication", is_flag=True, help=PUBLICATION_HELP)
@click.option("--overwrite", is_flag=True, help=OVERWRITE_HELP)
def paper(out: Path, no_figures: bool, as_json: bool, no_simulations: bool, publication: bool,
          overwrite: bool) -> None:
    """Reproduce the paper's numbers and figures from its own Tables 1 and 2, and put the model's
    predictions (linear and simulated) beside the measurements."""
    from .._atomic import check_output_place
    from ..campaigns.paper import reproduce
    from ..campaigns.paper_outputs import write_paper

    check_output_place(out)
    _refuse_existing(out, overwrite)
    doing = "reproducing the paper" + ("" if no_simulations else " (its simulations compile once after install, ~15 s)")
    with err_console.status(doing) if err_console.is_terminal else contextlib.nullcontext():
        rep = reproduce(simulate=not no_simulations)
    write_paper(rep, out, figures=not no_figures,
                figure_options=_figure_options(None, None, publication, None))
    if as_json:
        _echo_json({"grainplug_version": __version__, **rep.as_dict()})
        return
    click.echo("plug celerity against the mass flow rate ṁ (g/s), fitted as v_p = a + b ṁ:")
    for g, f in rep.fits.items():
        click.echo(f"  {g:18s} a = {f.intercept:+.4f} m/s, b = {f.slope:+.5f} (m/s)/(g/s)   (R² {f.r2:.3f}, n {f.n})")
    n_ok = sum(c.agrees for c in rep.checks)
    click.echo(f"checks: {n_ok} of {len(rep.checks)} statements agree with the tables and models; "
               f"see {out / 'reproduction.md'}")
    for c in rep.checks:
        if not c.agrees:
            click.echo(f"  disagrees: {c.claim} — {c.note}")
    if rep.model_panel is not None:
        click.echo("model against experiment:")
        for sentence in rep.model_panel.verdict:
            click.echo(f"  {sentence}")


# ---------------------------------------------------------------------------
@cli.command()
@click.argument("manifest", type=click.Path(path_type=Path))
@click.option("--out", "out", type=click.Path(path_type=Path), required=True,
              help="Folder for campaign.csv/.parquet, fits.json, figures, report.html and runs/.")
@click.option("--workers", type=Number(1, 1024, integer=True), default=1, show_default=True,
              help="Runs analysed in parallel on this machine.")
@click.option("--scheduler", default=None, help="Address of a Dask distributed scheduler (tcp://host:8786).")
@click.option("--no-figures", is_flag=True, help="Skip figures and HTML reports.")
@click.option("--verify", is_flag=True,
              help="Reuse a finished run only if every byte of its movie is unchanged (reads every movie whole).")
@click.option("--json", "as_json", is_flag=True, help="Print the fits as JSON.")
@click.option("--no-simulations", is_flag=True,
              help="In the report, compare with the model's linear theory only (skip ~4 s of simulations).")
@click.option("--publication", is_flag=True, help=PUBLICATION_HELP)
def batch(manifest: Path, out: Path, workers: int, scheduler: str | None, no_figures: bool, verify: bool,
          as_json: bool, no_simulations: bool, publication: bool) -> None:
    """Analyse every run of MANIFEST (CSV or TOML), then tabulate, fit and report.

    One row per run: movie (relative to the manifest), fps, mm_per_px or tube_diameter_mm,
    flow_direction, mass_flow_rate_g_s, humidity_pct, surface, group, and any metadata.
    Runs already analysed with the same movie (size and sampled content; every byte with
    --verify) and parameters are reused. Ctrl-C stops at once; every run is then done or not
    started, and the same command finishes the campaign.
    """
    from rich.progress import BarColumn, Progress, TextColumn

    from ..campaigns import run_campaign
    from ..errors import CampaignInterrupted, Interrupted

    with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total} runs"),
                  console=err_console, transient=True, disable=not err_console.is_terminal) as bar:
        task = bar.add_task("campaign", total=None)

        def progress(done: int, total: int, run: str) -> None:
            last = done == total and not no_simulations  # then the tables, fits and the model's simulations
            bar.update(task, completed=done, total=total,
                       description="fits and model (the simulations compile once after install, ~15 s)" if last
                       else f"run {escape(run)}")

        try:
            camp = run_campaign(manifest, out, workers=workers, scheduler=scheduler, figures=not no_figures,
                                verify=verify, simulate=not no_simulations, progress=progress,
                                figure_options=_figure_options(None, None, publication, None))
        except CampaignInterrupted as exc:  # before click's own handler, which prints a blank line
            raise Interrupted(str(exc)) from None
    t = camp.table
    if camp.stale_runs:
        names = ", ".join(camp.stale_runs[:5]) + (", ..." if len(camp.stale_runs) > 5 else "")
        err_console.print(f"[yellow]warning:[/] {len(camp.stale_runs)} run folder(s) under {escape(str(out / 'runs'))} "
                          f"are no longer in the manifest ({escape(names)}): kept, but left out of the campaign — "
                          "delete them if they are not needed", highlight=False, soft_wrap=True)
    if camp.worker_deaths:
        err_console.print(f"[yellow]warning:[/] {camp.worker_deaths} worker process(es) died during the batch "
                          "(killed, or out of memory); their runs were started again — if it repeats, use fewer "
                          "--workers", highlight=False, soft_wrap=True)
    if as_json:
        from ..campaigns.batch import fit_selection

        _print_run_warnings(camp, out)  # on stderr, as analyze --json prints its warnings
        _echo_json({"grainplug_version": __version__, "fits": camp.fits,
                    "runs": t[["run", "status"]].to_dict(orient="records"), "n_reused": camp.n_reused,
                    "n_remeasured": camp.n_remeasured, "left_out_of_fits": fit_selection(t)[1]})
    else:
        counts = t.status.value_counts().to_dict()
        again = f", {camp.n_remeasured} of them measured again with their new corrections" if camp.n_remeasured else ""
        reused = f" ({camp.n_reused} reused from an earlier batch{again})" if camp.n_reused else ""
        click.echo(f"{len(t)} runs: " + ", ".join(f"{v} {k}" for k, v in sorted(counts.items())) + reused)
        from ..campaigns.batch import ALL_RUNS, fit_selection

        _print_run_warnings(camp, out)
        for run, why in fit_selection(t)[1].items():
            if run == ALL_RUNS or not why.endswith("no plugs measured"):
                say_warning(why, f"run {run}: " if run else "fits: ")
        fits = {g: f["celerity"] for g, f in camp.fits.items() if f.get("celerity")}
        if fits:
            click.echo("plug celerity against the mass flow rate ṁ (g/s), fitted as v_p = a + b ṁ:")
        for g, c in fits.items():
            click.echo(f"  {g:22s} a = {c['intercept_m_s']:+.4g} m/s, b = {c['slope_m_s_per_g_s']:+.4g} (m/s)/(g/s)"
                       f"   (R² {c['r2']:.3f}, n {c['n']})")
        click.echo(f"outputs in {out}")
    if camp.n_failed:
        from ..errors import PartialCampaignError

        for row in t[t.status == "failed"].itertuples():
            err_console.print(f"[red]failed:[/] run {escape(str(row.run))}: {escape(str(row.error))}",
                              highlight=False, soft_wrap=True)
        others = "the others are done" if camp.n_failed < len(t) else "none is done"
        raise PartialCampaignError(
            f"{camp.n_failed} of {len(t)} runs failed, each named above ({others}; see {out / 'campaign.csv'})"
        )
