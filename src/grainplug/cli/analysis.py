"""The analysis' commands: info, calibrate, analyze, remeasure, review, overlay."""

from __future__ import annotations

import contextlib
import json
from pathlib import Path
from typing import TYPE_CHECKING

import click
from click.core import ParameterSource
from rich.markup import escape

from .._format import oscillation_phrase, with_interval
from ..errors import ParameterError
from ..measures.shake import shake_line
from ..params import FLOW_DIRECTIONS, AnalysisParams
from .common import (
    OVERWRITE_HELP,
    PUBLICATION_HELP,
    default_of,
    echo_json,
    err_console,
    figure_options_of,
    in_flags,
    mask_option,
    refuse_existing,
    roi_option,
    say_note,
    say_warning,
    window_params,
)
from .config import ConfigCommand
from .types import FRAME_OR_TIME, Number, param_number

if TYPE_CHECKING:
    pass


# ---------------------------------------------------------------------------
@click.command()
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
        from ..readers.timing import timing_stamps

        by_stamps = timing_stamps(m, m.info) is not None
        d["frame_times"] = "the file's time stamps (unevenly spaced)" if by_stamps else "frame index / fps"
    if as_json:
        echo_json(d)
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
@click.command()
@click.argument("image", type=click.Path(path_type=Path))
@click.option("--pitch-mm", type=Number(1e-3, 1e4, unit="mm"), required=True,
              help="Distance between neighbouring checkerboard corners (a square's side), dot centres, graph-paper "
                   "lines or ruler ticks, in mm.")
@click.option("--pattern", type=click.Choice(["auto", "checkerboard", "dots", "graph", "ruler"]), default="auto",
              show_default=True, help="The pattern in the image (graph: graph paper; ruler: a ruler's ticks).")
@click.option("--out", "out", type=click.Path(path_type=Path), default=Path("calibration.json"), show_default=True,
              help="Where to write the calibration; a PNG of what was found is written beside it "
                   "(OUT's name with _points.png: calibration_points.png).")
@click.option("--json", "as_json", is_flag=True, help="Print the calibration as JSON.")
def calibrate(image: Path, pitch_mm: float, pattern: str, out: Path, as_json: bool) -> None:
    """The scale (mm per pixel) from IMAGE of a checkerboard, a dot grid, graph paper or a ruler held at the
    tube's plane.

    IMAGE is a picture (PNG, TIFF, JPEG, BMP) or a short movie of the pattern taken with the
    camera and lens of the experiment (its first frames are averaged). Writes OUT (JSON, with the
    image's fingerprint) and OUT_points.png: the image with the points found. Neither may be IMAGE
    itself. Use it with `grainplug analyze MOVIE --calibration OUT`.
    """
    from .._atomic import refuse_overwriting_inputs
    from ..calibration_files import (
        calibrate_file,
        calibration_figure_path,
        draw_calibration,
        read_calibration_image,
        save_calibration,
    )

    if not (pitch_mm > 0 and pitch_mm < 1e4):
        raise ParameterError(f"--pitch-mm must be a length between 0 and 10 m, got {pitch_mm}")
    if out.suffix.lower() != ".json":
        raise ParameterError(f"--out must name a .json file, got {out}")
    figure_path = calibration_figure_path(out)
    refuse_overwriting_inputs([out, figure_path], [image])  # before anything is read or written
    cal = calibrate_file(image, pitch_mm=pitch_mm, pattern=pattern)
    save_calibration(cal, out, inputs=[image])
    figure = draw_calibration(read_calibration_image(image), cal, figure_path, inputs=[image])
    if as_json:
        echo_json(cal.as_dict())
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
@click.command(cls=ConfigCommand)
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
              help="Inner diameter of the tube: the scale measured from the tube, or with --mm-per-px the "
                   "plug length in diameters (λ/D) and the check of the given scale "
                   f"[default: {default_of(AnalysisParams, 'tube_diameter_mm'):g}].")
@click.option("--tube-outer-diameter-mm", type=param_number("tube_outer_diameter_mm"), default=None,
              help="Outer diameter of the tube: the scale then comes from its outer silhouette (any lighting).")
@click.option("--glass-index", type=param_number("glass_index"), default=default_of(AnalysisParams, "glass_index"),
              show_default=True,
              help="Refractive index of the tube's glass (1.47 borosilicate, 1.52 soda-lime), for the tube model.")
@click.option("--flow-direction", type=click.Choice(FLOW_DIRECTIONS), default=None,
              help="Direction of the grain flow in the image [default: the way the grains fall through the "
                   "bubbles; if none are seen, down a vertical tube, or right along a horizontal one, with a "
                   "warning].")
@click.option("--min-plug-mm", type=param_number("min_plug_mm"), default=default_of(AnalysisParams, "min_plug_mm"),
              show_default=True,
              help="Shortest grain region counted as a plug.")
@click.option("--min-gap-mm", type=param_number("min_gap_mm"), default=default_of(AnalysisParams, "min_gap_mm"),
              show_default=True,
              help="Shortest gap between grains counted as a bubble.")
@click.option("--glob", "glob_", default=None, help="For image folders: only files matching this pattern.")
@click.option("--threads", type=Number(1, 1024, integer=True), default=None,
              help="Threads reading uncompressed frames (TIFF stacks, raw video) [default: one per core].")
@click.option("--calibration", "calibration", type=click.Path(path_type=Path), default=None,
              help="calibration.json from `grainplug calibrate`: the scale, instead of the tube's width.")
@click.option("--background", "background", type=click.Path(path_type=Path), default=None,
              help="Light calibration: a picture or short movie of the tube empty (or full), nothing moving, "
                   "to flat-field the light along the tube.")
@click.option("--packed", "packed", type=click.Path(path_type=Path), default=None,
              help="A picture (or short movie) of the tube packed with still grains, with the movie's camera and "
                   "lamp: with --background (the tube empty), the grains' compactness is read from the light.")
@click.option("--packed-compactness", type=Number(0.05, 0.95), default=0.60, show_default=True,
              help="The compactness of the grains in the --packed picture (poured and settled glass beads: 0.60).")
@click.option("--grain-density-kg-m3", type=Number(100, 25000), default=2500.0, show_default=True,
              help="The grains' material density, for their mass flow rate from the movie (glass: 2500).")
@click.option("--allow-truncated", is_flag=True,
              help="For camera files that end early: analyse the complete frames instead of refusing.")
@click.option("--start", "start", type=FRAME_OR_TIME, default=None,
              help="Analyse from this frame (e.g. 120) or time (e.g. 2.5s) on: leave out the start-up transient.")
@click.option("--end", "end", type=FRAME_OR_TIME, default=None,
              help="Analyse up to this frame (excluded) or time.")
@click.option("--roi", "roi", default=None, metavar="X0,Y0,X1,Y1",
              help="Analyse only this rectangle of the frames (pixels; x1, y1 excluded): choose one tube when "
                   "the frame holds several.")
@click.option("--mask", "mask", multiple=True, metavar="FROM:TO",
              help="A stretch of the tube that hides its contents (a clamp, a label), in mm from the upstream end "
                   "of the view; repeatable. Plugs touching it are cut there, bubbles across it not measured. "
                   "Stretches where nothing changes over the record are found without it.")
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
            calibration: Path | None, background: Path | None, packed: Path | None, packed_compactness: float,
            grain_density_kg_m3: float,
            allow_truncated: bool,
            start: tuple[str, float] | None, end: tuple[str, float] | None, roi: str | None,
            mask: tuple[str, ...], no_figures: bool,
            dpi: int | None,
            figure_formats: str | None, publication: bool, style: str | None, overwrite: bool,
            as_json: bool) -> None:
    """Find the plugs in MOVIE and measure their celerity, length and oscillation."""
    from .._atomic import check_output_place
    from ..plotting.worker import FigureWorker

    # before the analysis, not after it: the folder is replaced whole, so it must hold none of the inputs
    check_output_place(out, inputs=[p for p in (movie, calibration, background, packed, config) if p is not None],
                       replace=True, kind="analysis")
    refuse_existing(out, overwrite)
    # a setting of grainplug.toml gives way to the command line: --figure-formats over publication = true, and
    # --publication over figure_formats = "..."
    source = click.get_current_context().get_parameter_source
    if publication and figure_formats and source("publication") != source("figure_formats"):
        if source("publication") is ParameterSource.COMMANDLINE:
            figure_formats = None
        else:
            publication = False
    figure_options = figure_options_of(dpi, figure_formats, publication, style)
    roi_px = roi_option(roi)
    if mm_per_px is not None and calibration is not None:
        raise ParameterError("give either --mm-per-px or --calibration (the scale), not both")
    diameter = {} if tube_diameter_mm is None else {"tube_diameter_mm": tube_diameter_mm}
    params = AnalysisParams(fps=fps, mm_per_px=mm_per_px, **diameter,
                            tube_outer_diameter_mm=tube_outer_diameter_mm, glass_index=glass_index,
                            flow_direction=flow_direction, min_plug_mm=min_plug_mm, min_gap_mm=min_gap_mm, glob=glob_,
                            allow_truncated=allow_truncated, roi=roi_px, mask_mm=mask_option(mask),
                            packed_compactness=packed_compactness, grain_density_kg_m3=grain_density_kg_m3,
                            **window_params(start, end))
    # the calibration and background files are read by the library, once (gp.analyze takes their paths)
    files = {k: v for k, v in (("calibration", calibration), ("background", background), ("packed", packed))
             if v is not None}
    # the figures' worker starts now, before the analysis' own imports (numpy among them): it imports
    # matplotlib while they load, the tube is found and the frames stream
    with (FigureWorker(figure_options.formats, preload=("grainplug.result",)) if not no_figures
          else contextlib.nullcontext()) as figure_worker:
        from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

        from ..pipeline import analyze as run_analysis

        with Progress(TextColumn("[progress.description]{task.description}"), BarColumn(),
                      TextColumn("{task.completed}/{task.total} frames"), TimeRemainingColumn(),
                      console=err_console, transient=True, disable=not err_console.is_terminal) as bar:
            task = bar.add_task(f"analysing {movie.name}", total=None)

            def progress(done: int, total: int) -> None:
                bar.update(task, completed=done, total=total)

            result = run_analysis(movie, params, progress=progress, threads=threads, **files)
        result.save(out, figures=not no_figures, report=not no_figures, figure_worker=figure_worker,
                    figure_options=figure_options)
    s = json.loads((out / "summary.json").read_text())  # what was written: outputs and figure settings too
    settings = click.get_current_context().meta.get("grainplug.config")
    if settings is not None:  # said once the run is done: a refusal stays one line
        say_note(f"settings from {settings}")
    for line in result.warnings:
        say_warning(line)
    if as_json:
        echo_json(s)
        return
    if not result.has_plugs or s.get("celerity_m_s") is None:
        say_note(result.statement)  # what is not measured, and why: a note, as every other line on stderr
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
        share = ((s.get("uncertainty") or {}).get("celerity") or {}).get("dominant")
        click.echo(f"celerity        {value} m/s  (95% CI {lo} to {hi}"
                   f"{', mostly the scale' if share == 'scale' else ''})")
        n_plugs = s["n_plugs"]
        click.echo(f"plug length     {fmt(s['plug_length_mm'], ' mm', 2)}  "
                   f"({fmt(s['plug_length_over_diameter'], ' D', 2)}, {n_plugs} plug{'' if n_plugs == 1 else 's'})")
        click.echo(f"bubble length   {fmt(s['bubble_length_mm'], ' mm', 2)}")
        if s["oscillation_frequency_hz"]:
            click.echo("oscillation     " + oscillation_phrase(
                s["oscillation_frequency_hz"], s.get("oscillation_frequency_ci95_hz"), s["oscillation_amplitude_mm"],
                s.get("oscillation_amplitude_ci95_mm"), s.get("oscillation_kind"), s.get("oscillation_stick_fraction")))
        comp = s.get("compactness") or {}
        if comp.get("plugs") is not None or comp.get("bubbles") is not None:
            def with_ci(key: str) -> str:
                lo_hi = comp.get(f"{key}_ci95")
                return fmt(comp.get(key), "", 3) + (f" (95% CI {lo_hi[0]:.3f} to {lo_hi[1]:.3f})" if lo_hi else "")
            click.echo(f"compactness     plugs {with_ci('plugs')}, bubbles {with_ci('bubbles')}")
        if s.get("mass_flow_rate_g_s") is not None:
            q_ci = s.get("mass_flow_rate_ci95_g_s")
            click.echo(f"mass flow rate  {fmt(s['mass_flow_rate_g_s'], ' g/s', 3)}"
                       + (f"  (95% CI {q_ci[0]:.3g} to {q_ci[1]:.3g})" if q_ci else ""))
        click.echo(f"scale           {fmt(s['mm_per_px'], ' mm/px', 5)} from {s['scale_source']}")
        if shake_line(s.get("shake")):
            click.echo(f"camera shake    {shake_line(s.get('shake'))}")
    click.echo(f"outputs in      {out}")


@click.command()
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
    from ..workflows import remeasure as run_remeasure

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
        echo_json(s)
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


@click.command()
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--port", type=Number(0, 65535, integer=True), default=0, show_default=True,
              help="Port on 127.0.0.1 (0: a free one).")
@click.option("--no-browser", is_flag=True, help="Do not open a browser (print the address only).")
def review(folder: Path, port: int, no_browser: bool) -> None:
    """Review an analysis (or a campaign's runs) in the browser: the diagram, any frame with its
    edges, the tracks; exclude, merge or split tracks, set a time window or spans without plugs.

    Edits are kept in FOLDER/corrections.json at once and the measures recomputed; "Write
    outputs" rewrites the run's files (as grainplug remeasure). Served on 127.0.0.1 only,
    offline; the printed address holds the page's access token (other users of the machine
    can reach the port, not the page): open that address. Ctrl-C stops it.
    """
    import threading
    import webbrowser

    from ..result import load_result
    from ..review import ReviewServer
    from ..review.server import review_targets

    for target in review_targets(folder).values():  # a damaged result: one line now, not a page that fails
        load_result(target)
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


@click.command()
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--out", "out", type=click.Path(path_type=Path), default=None,
              help="The video: .mp4 (H.264, needs PyAV: pip install \"grainplug[video]\") or .webm (VP8) "
                   "[default: FOLDER/overlay.mp4 with PyAV, else FOLDER/overlay.webm].")
@click.option("--slowdown", type=Number(0.01, 1e6), default=None,
              help="Play this many times slower than real time; the video's rate is the movie's / slowdown / "
                   "every [default: the frames kept at most 30 per second].")
@click.option("--every", type=Number(1, 1e6, integer=True), default=1, show_default=True,
              help="Keep one frame in this many: with the default slow-down, a video this many times shorter "
                   "at the same rate.")
def overlay(folder: Path, out: Path | None, slowdown: float | None, every: int) -> None:
    """Write a video of the analysed movie around the tube with the detected edges, track numbers,
    a scale bar and the time stamp (for checking by eye and for supplementary material): an H.264 MP4
    where PyAV is installed, else a VP8 WebM."""
    from ..overlay import write_overlay

    if not folder.is_dir():
        raise ParameterError(f"{folder} is not a folder: give the --out folder of an analysis")
    path = write_overlay(folder, out, slowdown=slowdown, every=every)
    click.echo(f"overlay            {path}")
