"""Figures of one analysis: the spatiotemporal diagram (the paper's Figs 5-8), the
oscillation spectrum, and an annotated frame (the paper's Fig 4)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure

from .._format import signed
from ..diagram.extract import display_stride
from ..params import runs_backwards
from . import palette
from ._figure import new_figure, pt

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from ..result import AnalysisResult


def plot_diagram(res: AnalysisResult, *, ax: Axes | None = None, max_markers: int = 4000) -> Figure:
    """Spatiotemporal diagram with the detected upper (vermillion squares) and lower (blue
    circles) plug edges, the mean-celerity line (dashed, green) and a colour bar, as in the
    paper's Figs 5-8 (which draw the upper edges black, invisible here over dark plugs).
    Colours: :mod:`grainplug.plotting.palette`.

    Drawn into ``ax`` when given (its figure is returned), else into a new figure.
    """
    d = res.diagram
    own_figure = ax is None
    if ax is None:
        # fixed margins (this layout never changes): a layout engine would double the drawing time
        fig, ax = new_figure(figsize=(9, 5.5))
        # room above the axes for the title and, under it, the legend (inside, it hid edges)
        fig.subplots_adjust(left=0.075, right=0.9, bottom=0.09, top=0.9)
    else:
        fig = ax.figure
    t, s = d.time_s, d.position_mm
    # at most ~1200 samples a side (a no-op when the values were already thinned for display)
    step_t, step_s = display_stride(d.values.shape)
    # the data's own pixels in SVG and PDF ("none"); in PNG, nearest samples of the data coloured after
    # resampling ("data"): matplotlib's automatic choice coloured first and resampled RGBA floats, 3x the
    # time and 100 MB more for a long record at 200 dpi (docs/performance.md)
    im = ax.imshow(d.values[::step_t, ::step_s].T, aspect="auto", cmap="gray", origin="upper",
                   interpolation="none", interpolation_stage="data", extent=(t[0], t[-1], s[-1], s[0]))
    if own_figure:  # a colour bar in someone else's axes would take their space
        cbar = fig.colorbar(im, cax=fig.add_axes((0.91, 0.09, 0.012, 0.81)))
        cbar.set_label("grey level, the light divided out (camera units at its median)", fontsize=pt(8))
        cbar.ax.tick_params(labelsize=pt(7))
    runs = res.runs
    if len(runs):
        step = max(1, len(runs) // max_markers)
        tt = t[runs.frame[::step]]
        top, bottom = runs.top_mm[::step], runs.bottom_mm[::step]
        if np.isfinite(top).any():  # no legend entry for edges that are all out of view
            ax.plot(tt, top, "s", ms=2.2, mfc="none", mec=palette.UPPER, mew=0.6, label="upper edge")
        if np.isfinite(bottom).any():
            ax.plot(tt, bottom, "o", ms=2.2, mfc="none", mec=palette.LOWER, mew=0.6, label="lower edge")
    m = res.motion
    title = "no plugs" if not res.has_plugs else ""
    if m is not None:
        c_mm_s = m.celerity_m_s * 1000
        # one dashed line per track start, like the paper's mean-celerity line
        ok = np.isfinite(runs.top_mm)
        if ok.any():
            t0 = t[runs.frame[ok]]
            y0 = runs.top_mm[ok]
            k = int(np.argmin(np.abs(t0 - t0.mean())))
            ax.plot(t, y0[k] + c_mm_s * (t - t0[k]), "--", color=palette.FIT, lw=1.4,
                    label=f"mean celerity {signed(m.celerity_m_s, 4)} m s⁻¹".replace("-", "−"))
        L = res.lengths.plug_length_mm if res.lengths else None
        title = f"{m.regime}: v_p = {signed(m.celerity_m_s, 4)} m s⁻¹"  # the paper's symbol (c is compactness)
        # in someone else's axes (a panel of their figure), on two lines: the full one is 9 inches wide
        sep = ", " if own_figure else "\n"
        if L:
            title += f"{sep}plug length λ = {L:.2f} mm (λ/D = {L / res.params.tube_diameter_mm:.1f})"
        if m.oscillation_frequency_hz:
            title += f", f = {m.oscillation_frequency_hz:.2f} Hz"
        title = title.replace("-", "−")
    ax.set_ylim(s[-1], s[0])
    ax.set_xlim(t[0], t[-1])
    if t[-1] - t[0] < 0.1:  # a short record: ticks in ms (0.25 ms, not 0.00025 s); the data stay in s
        from matplotlib.ticker import FuncFormatter

        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v * 1000:.6g}"))
        ax.set_xlabel("time t (ms)")
    else:
        ax.set_xlabel("time t (s)")
    ax.set_ylabel(f"position z along the tube (mm; flow {res.flow_direction} in the image)" if own_figure
                  else "position z (mm)")
    if len(runs) and own_figure:  # one row between the axes and the title, over no data
        ax.legend(loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=3, fontsize=pt(7), frameon=False,
                  borderaxespad=0.15, handletextpad=0.4, columnspacing=1.6)
        ax.set_title(title, fontsize=pt(10), pad=pt(7) * 2 + 6)
    else:  # a panel of someone else's figure keeps its own space: the legend inside
        ax.set_title(title, fontsize=pt(10))
        if len(runs):
            ax.legend(loc="upper right", fontsize=pt(7), framealpha=0.8)
    return fig


def plot_spectrum(res: AnalysisResult) -> Figure:
    """Displacement of the plug train about its drift, and its amplitude spectrum."""
    m = res.motion
    # fixed margins, as the diagram's: a layout engine costs ~40 ms a figure, on every run's critical path
    fig, (a1, a2) = new_figure(2, 1, figsize=(8, 5.5))
    fig.subplots_adjust(left=0.1, right=0.97, bottom=0.09, top=0.94, hspace=0.36)
    x = m.displacement_mm - m.celerity_m_s * 1000 * m.time_s
    a1.plot(m.time_s, x - np.nanmean(x), "-", color=palette.foreground(), lw=0.8)
    a1.set_xlabel("time t (s)")
    a1.set_ylabel("displacement about the drift (mm)")
    sel = m.spectrum_hz <= min(60.0, m.spectrum_hz[-1])
    a2.plot(m.spectrum_hz[sel], m.spectrum_mm[sel], "-", color=palette.foreground(), lw=0.8)
    if m.oscillation_frequency_hz:
        # A is half the peak-to-peak of the period-averaged motion (summary.json's); the spectrum's peak is the
        # fundamental's amplitude alone, lower for a stick-slip whose harmonics carry part of the swing
        a2.axvline(m.oscillation_frequency_hz, color=palette.FIT, ls="--", lw=1,
                   label=f"f = {m.oscillation_frequency_hz:.3f} Hz; A = {m.oscillation_amplitude_mm:.2f} mm "
                         "(half peak-to-peak)")
        a2.legend(fontsize=pt(8))
    a2.set_xlabel("frequency f (Hz)")
    a2.set_ylabel("spectral amplitude (mm)")
    kind = f", {m.oscillation.kind}" if m.oscillation is not None and m.oscillation_frequency_hz else ""
    a1.set_title(f"oscillation of the plugs ({m.regime}{kind})", fontsize=pt(10))
    return fig


def crop_box(res: AnalysisResult) -> tuple[int, int]:
    """Columns (vertical tube) or rows (horizontal) ``[lo, hi)`` shown around the tube: six diameters
    either side, not the whole sensor (the annotated frame, the overlay video)."""
    tube = res.tube
    h, width = tube.canonical_shape[:2]
    ends = tube.axis_x(np.array([0.0, h - 1.0]))
    margin = 6 * tube.inner_diameter_px + 10
    return int(max(0, np.floor(ends.min() - margin))), int(min(width, np.ceil(ends.max() + margin) + 1))


def plot_annotated_frame(res: AnalysisResult, *, frame: np.ndarray | None = None,
                         index: int | None = None) -> Figure:
    """One frame with the detected tube (inner walls, axis) and plugs (edges), the paper's Fig 4.

    By default the frame kept in the result; ``frame`` (frame ``index`` of the analysis) for another.
    """
    if frame is None:
        frame, index = res.sample_frame, res.sample_frame_index
    elif index is None:
        raise ValueError("give the index of the frame")
    tube = res.tube
    h = tube.canonical_shape[0]
    vertical = tube.orientation == "vertical"
    lo, hi = crop_box(res)
    crop = frame[:, lo:hi] if vertical else frame[lo:hi]
    img = crop.astype(np.float32)
    if img.ndim == 3:
        img = img / max(float(img.max()), 1.0)
    extent = (lo - 0.5, lo + crop.shape[1] - 0.5, crop.shape[0] - 0.5, -0.5) if vertical else (
        -0.5, crop.shape[1] - 0.5, lo + crop.shape[0] - 0.5, lo - 0.5)
    # the figure takes the crop's shape (a horizontal tube used to float in a mostly empty page):
    # the image 7.4 in tall (vertical tube) or 8.6 in wide (horizontal), and room for the two-line title
    aspect = crop.shape[1] / crop.shape[0]
    title_in, foot_in = 0.5, 0.08
    if vertical:
        fig_w, img_h = min(max(7.4 * aspect + 0.2, 4.5), 12.0), 7.4
    else:
        fig_w, img_h = 9.0, min(max(8.6 / aspect, 1.2), 8.0)
    fig_h = img_h + title_in + foot_in
    fig, ax = new_figure(figsize=(fig_w, fig_h))
    fig.subplots_adjust(left=0.02, right=0.98, bottom=foot_in / fig_h, top=1 - title_in / fig_h)
    ax.imshow(img, cmap="gray", interpolation="none", interpolation_stage="data", extent=extent)
    rows = np.arange(h, dtype=float)
    axis = tube.axis_x(rows)
    half = 0.5 * tube.inner_diameter_px / np.cos(np.radians(tube.tilt_deg))

    def draw(xc, yc, *args, **kw):
        if vertical:
            ax.plot(xc, yc, *args, **kw)
        else:
            ax.plot(yc, xc, *args, **kw)

    draw(axis - half, rows, "-", color=palette.WALL, lw=0.8, label="inner walls")
    draw(axis + half, rows, "-", color=palette.WALL, lw=0.8)
    draw(axis, rows, ":", color=palette.WALL, lw=0.6)
    runs = res.runs
    sel = runs.frame == index
    cos_t = np.cos(np.radians(tube.tilt_deg))
    reverse = runs_backwards(res.flow_direction)
    for top, bot in zip(runs.top_mm[sel], runs.bottom_mm[sel], strict=True):
        for pos, color in ((top, palette.UPPER), (bot, palette.LOWER)):
            if not np.isfinite(pos):
                continue
            row = pos / res.mm_per_px * cos_t - 0.5
            if reverse:
                row = h - 1 - row
            xc = tube.axis_x(row)
            draw([xc - half, xc + half], [row, row], "-", color=color, lw=1.6)
            draw([xc], [row], "*", color=color, ms=7)
    # the bore at the scale in use (a calibration's, a typed one or the tube's own), and what the tube model read
    # when that is another width
    bore_px = res.params.tube_diameter_mm / res.mm_per_px
    read = res.bore.diameter_px if res.bore else float("nan")
    model = f", the tube model reads {read:.2f} px" if np.isfinite(read) and abs(read / bore_px - 1) > 0.005 else ""
    ax.set_title(f"frame {index}: bore {res.params.tube_diameter_mm:g} mm = {bore_px:.2f} px{model} "
                 f"(seen {tube.inner_diameter_px:.2f} px wide), tilt {round(tube.tilt_deg, 2) + 0.0:+.2f}°\n"
                 + ("vermillion: upper edges, blue: lower edges" if res.flow_direction == "down" else
                    # in the image, the upstream edge is not the upper one (a rising or horizontal flow)
                    "vermillion: upstream edges, blue: downstream edges"), fontsize=pt(8))
    ax.set_xticks([])
    ax.set_yticks([])
    _scale_bar(ax, res.mm_per_px, vertical=vertical, along_px=h)
    ax.legend(loc="lower right", fontsize=pt(7))
    return fig


def _scale_bar(ax: Axes, mm_per_px: float, *, vertical: bool, along_px: int) -> None:
    """A bar of a round length (1, 2 or 5 times a power of ten mm, about a tenth of the tube in view), drawn
    along the tube near its start, in image pixels, labelled in mm."""
    target = 0.1 * along_px * mm_per_px
    mm = min((m * 10.0**e for e in range(-2, 4) for m in (1, 2, 5)), key=lambda x: abs(math.log(x / target)))
    n_px = mm / mm_per_px
    x0, x1 = sorted(ax.get_xlim())
    y1, y0 = sorted(ax.get_ylim(), reverse=True)  # image axes: y grows downwards
    if vertical:  # a vertical bar at the left edge of the crop
        x = x0 + 0.12 * (x1 - x0)
        y = y0 + 0.03 * (y1 - y0)
        ax.plot([x, x], [y, y + n_px], "-", color="black", lw=4, solid_capstyle="butt")
        ax.plot([x, x], [y, y + n_px], "-", color="white", lw=2, solid_capstyle="butt")
        ax.text(x + 0.05 * (x1 - x0), y + n_px / 2, f"{mm:g} mm", color="white", fontsize=pt(7), rotation=90,
                va="center", ha="left", bbox={"facecolor": "black", "alpha": 0.6, "lw": 0, "pad": 1})
    else:  # a horizontal bar at the top edge of the crop
        x = x0 + 0.03 * (x1 - x0)
        y = y0 + 0.12 * (y1 - y0)
        ax.plot([x, x + n_px], [y, y], "-", color="black", lw=4, solid_capstyle="butt")
        ax.plot([x, x + n_px], [y, y], "-", color="white", lw=2, solid_capstyle="butt")
        ax.text(x + n_px / 2, y + 0.06 * (y1 - y0), f"{mm:g} mm", color="white", fontsize=pt(7),
                va="top", ha="center", bbox={"facecolor": "black", "alpha": 0.6, "lw": 0, "pad": 1})
