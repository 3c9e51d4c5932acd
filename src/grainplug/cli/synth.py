"""``grainplug synth``: its options list the synthetic formats and regimes, so it is
loaded only when named (see :class:`grainplug.cli.app.LazyGroup`)."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import ParameterError
from ..params import FLOW_DIRECTIONS
from ..synthetic import FORMATS, REGIMES, SynthConfig, synthesize
from .common import echo_json, err_console, refuse_existing
from .types import FINITE, Number


def _synth_options(f):
    opts = [
        click.option("--out", "out", type=click.Path(path_type=Path), required=True,
                     help="Folder to write the movie and its truth into."),
        click.option("--format", "fmt", type=click.Choice(list(FORMATS)), default="tiff", show_default=True,
                     help="File format of the movie (avi, mjpeg, ffv1, mov and h264 need PyAV: "
                          "pip install \"grainplug[video]\")."),
        click.option("--seed", type=int, default=0, show_default=True,
                     help="Seed of the random generator: the same seed gives the same bytes."),
        click.option("--frames", "n_frames", type=Number(1, 1e6, integer=True), default=300, show_default=True,
                     help="Number of frames."),
        click.option("--fps", type=Number(1, 1e7, unit="frames per second"), default=250.0, show_default=True,
                     help="Frame rate, frames per second."),
        click.option("--width", "width_px", type=int, default=128, show_default=True,
                     help="Frame width across the tube (canonical vertical view)."),
        click.option("--height", "height_px", type=int, default=640, show_default=True,
                     help="Frame height along the tube (canonical vertical view)."),
        click.option("--mm-per-px", type=FINITE, default=0.185, show_default=True,
                     help="Scale of the image, mm per pixel."),
        click.option("--tube-diameter-mm", type=FINITE, default=3.0, show_default=True,
                     help="Inner diameter of the tube, mm."),
        click.option("--wall-mm", type=FINITE, default=1.0, show_default=True,
                     help="Wall thickness of the glass tube, mm."),
        click.option("--tube-offset-px", type=FINITE, default=0.0, show_default=True,
                     help="Shift of the tube axis from the frame centre, across the tube, px."),
        click.option("--tilt-deg", type=FINITE, default=0.0, show_default=True,
                     help="Tilt of the tube axis in the image, degrees (at most 5)."),
        click.option("--flow-direction", type=click.Choice(FLOW_DIRECTIONS), default="down", show_default=True,
                     help="Direction of the grain flow in the image."),
        click.option("--polarity", type=click.Choice(["dark", "bright"]), default="dark", show_default=True,
                     help="dark plugs on a bright field, or bright plugs on a dark field"),
        click.option("--grey", "grey", is_flag=True, help="Write grey frames instead of RGB."),
        click.option("--bit-depth", type=click.Choice(["8", "16"]), default="8", show_default=True,
                     help="Bits per sample of the frames."),
        click.option("--regime", type=click.Choice(REGIMES), default="propagative", show_default=True,
                     help="Motion of the plugs (none: no plugs)."),
        click.option("--no-plug-fill", type=click.Choice(["empty", "compact"]), default="empty", show_default=True,
                     help="With --regime none: an empty tube (sparse falling grains) or a compact column."),
        click.option("--celerity-m-s", type=FINITE, default=-0.05, show_default=True,
                     help="Mean celerity of the plugs, m/s, positive downstream."),
        click.option("--frequency-hz", type=FINITE, default=7.0, show_default=True,
                     help="Oscillation frequency (oscillating, stick-slip), Hz."),
        click.option("--amplitude-mm", type=FINITE, default=1.5, show_default=True,
                     help="Oscillation amplitude, mm."),
        click.option("--stick-fraction", type=FINITE, default=0.5, show_default=True,
                     help="Stuck part of each period (stick-slip), 0 to 1."),
        click.option("--plug-length-mm", type=FINITE, default=30.0, show_default=True,
                     help="Mean plug length, mm."),
        click.option("--plug-length-sd-mm", type=FINITE, default=2.0, show_default=True,
                     help="Standard deviation of the plug lengths, mm."),
        click.option("--bubble-length-mm", type=FINITE, default=25.0, show_default=True,
                     help="Mean bubble length, mm."),
        click.option("--bubble-length-sd-mm", type=FINITE, default=4.0, show_default=True,
                     help="Standard deviation of the bubble lengths, mm."),
        click.option("--merge-split", is_flag=True, help="Let some plugs merge and split again."),
        click.option("--falling-grains-per-mm", type=FINITE, default=0.4, show_default=True,
                     help="Grains falling through the bubbles, per mm of bubble."),
        click.option("--noise-sigma", type=FINITE, default=3.0, show_default=True,
                     help="Gaussian sensor noise, 8-bit grey levels."),
        click.option("--flicker", type=FINITE, default=0.0, show_default=True,
                     help="Frame-to-frame light fluctuation, relative, uniform in [-flicker, +flicker]."),
        click.option("--gradient", type=FINITE, default=0.0, show_default=True,
                     help="Relative fall of the illumination from the top to the bottom of the view."),
    ]
    for opt in reversed(opts):
        f = opt(f)
    return f


@click.command()
@_synth_options
@click.option("--json", "as_json", is_flag=True, help="Print the truth as JSON.")
@click.option("--overwrite", is_flag=True,
              help="Replace --out if it holds an earlier synthetic movie (the whole folder; refused if it holds "
                   "anything grainplug synth did not write there).")
def synth(out: Path, fmt: str, grey: bool, bit_depth: str, as_json: bool, overwrite: bool,
          **kwargs: object) -> None:
    """Render a synthetic plug-flow movie with its ground truth (truth.json).

    --out is a folder of its own: new, empty, or (with --overwrite) one an earlier ``grainplug synth``
    wrote, which is then replaced whole.
    """
    from .._atomic import atomic_directory, check_output_place

    check_output_place(out, replace=True, kind="synthetic")  # a user's folder, a system folder: refused
    refuse_existing(out, overwrite)
    try:
        cfg = SynthConfig(rgb=not grey, bit_depth=int(bit_depth), **kwargs)
    except TypeError as exc:  # pragma: no cover - option/field mismatch is a bug
        raise ParameterError(str(exc)) from None
    if fmt in ("mraw", "cine") and cfg.rgb:
        cfg = SynthConfig(**{**cfg.as_dict(), "rgb": False, "tint": cfg.tint})
        err_console.print(f"note: {fmt} is written grey")
    with err_console.status(f"rendering {cfg.n_frames} frames"), \
            atomic_directory(out, replace=True, kind="synthetic") as tmp:
        result = synthesize(cfg, tmp, fmt=fmt)
    if as_json:
        echo_json(result.truth)
    else:
        click.echo(f"wrote {out / result.movie.name} and {result.truth_json.name}")


