"""What an analysis found: :class:`AnalysisResult`, with tables, a plot and a summary.

The result is a frozen dataclass of the pipeline's stage outputs (arrays and
frozen dataclasses). On top of them it offers what a researcher looks at in a
notebook:

- tables as pandas DataFrames: :attr:`~AnalysisResult.edges` (plug edges per
  frame), :attr:`~AnalysisResult.tracks` (one row per plug track),
  :attr:`~AnalysisResult.plugs` and :attr:`~AnalysisResult.bubbles` (the lengths
  that enter the means);
- the diagram as an ``xarray.DataArray`` (:meth:`~AnalysisResult.to_xarray`);
- :attr:`~AnalysisResult.summary`, the figures of ``summary.json``;
- a short ``repr``, an HTML view for Jupyter, :meth:`~AnalysisResult.plot` and
  :meth:`~AnalysisResult.save` (read back with :func:`grainplug.load_result`).
"""

from __future__ import annotations

import base64
import html
import io
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ._format import with_interval
from ._version import __version__
from .calibration.tube import TubeGeometry
from .calibration.tube_model import BoreEstimate
from .diagram import Diagram, Normalized
from .measures import Lengths, Motion
from .params import AnalysisParams, runs_backwards
from .plugs import Runs, Tracks
from .readers.base import MovieInfo

if TYPE_CHECKING:
    import pandas as pd
    import xarray as xr
    from matplotlib.axes import Axes

    from .corrections import Corrections
    from .plotting.options import FigureOptions
    from .plotting.worker import FigureWorker

CONVENTIONS = ("positions in mm along the tube from the upstream end of the view, increasing "
               "with the flow; celerity in m/s, positive downstream (negative: plugs climb)")


@dataclass(frozen=True, eq=False)
class AnalysisResult:
    """Everything :func:`grainplug.analyze` found in one movie.

    Attributes
    ----------
    params : AnalysisParams
        The parameters of the run.
    input : dict
        Identity of the input (path, size, hash of its ends; or shape and hash of an array).
    info : MovieInfo
        What the movie says about itself.
    tube : TubeGeometry
        Where the tube is in the frames.
    mm_per_px : float
        Scale of the frames along the tube.
    scale_source : str
        Where the scale came from, in words (given, a calibration image, the tube model...).
    flow_direction : {"down", "up", "left", "right"}
        Direction of the flow in the image.
    flow_direction_source : str
        How the flow direction was decided (given, from the grains falling through the
        bubbles, assumed).
    diagram : Diagram
        Spatiotemporal diagram (grey level, time x position); see :meth:`to_xarray`.
    normalized : Normalized
        The diagram's contrast (0 bubble, 1 plug) and illumination model.
    runs : Runs
        Plugs seen in each frame (one row per plug per frame).
    links : Tracks
        Plug tracks: which runs belong to one plug over time.
    motion, lengths : Motion, Lengths or None
        Celerity and oscillation; plug and bubble lengths (None without plugs).
    has_plugs : bool
        Whether plugs were found.
    statement : str
        Why there are no measures (no plugs, a single phase...), or a note on them; empty
        when there is nothing to say.
    sample_frame : ndarray
        One frame of the movie, the annotated figure's.
    sample_frame_index : int
        Its index among the analysed frames.
    timings : dict
        Seconds spent in each stage.
    falling_grain_speed_m_s : float or None
        Speed of the grains falling through the bubbles.
    warnings : list of str
        Anything doubtful about this run, with what to do about it.
    scale_rel_sd : float
        Relative standard uncertainty of the scale (included in the confidence intervals).
    bore : BoreEstimate or None
        The tube model's estimates of the bore's width in pixels (None when the
        scale was given).
    detected : (Runs, Tracks) or None
        What was detected, before a reviewer's corrections (None when uncorrected:
        ``runs`` and ``links`` are then what was detected).
    corrections : Corrections or None
        The corrections applied (:func:`grainplug.corrections.apply_corrections`).
    """

    params: AnalysisParams
    input: dict[str, object]
    info: MovieInfo
    tube: TubeGeometry
    mm_per_px: float
    scale_source: str
    flow_direction: str
    flow_direction_source: str
    diagram: Diagram
    normalized: Normalized
    runs: Runs
    links: Tracks
    motion: Motion | None
    lengths: Lengths | None
    has_plugs: bool
    statement: str
    sample_frame: np.ndarray = field(repr=False)
    sample_frame_index: int = 0
    timings: dict[str, float] = field(default_factory=dict)
    falling_grain_speed_m_s: float | None = None
    warnings: list[str] = field(default_factory=list)
    scale_rel_sd: float = 0.0
    bore: BoreEstimate | None = None
    detected: tuple[Runs, Tracks] | None = field(default=None, repr=False)
    corrections: Corrections | None = None

    # -- figures --------------------------------------------------------------
    @property
    def summary(self) -> dict[str, object]:
        """The figures of ``summary.json`` (JSON-ready, with provenance).

        What the result knows: ``summary.json`` also lists the files written (``outputs``)
        and the figure settings (``figures``), which a result does not keep; read that file
        for them.
        """
        return build_summary(self)

    @property
    def celerity_m_s(self) -> float | None:
        """Mean celerity of the plugs, positive downstream (None without plugs)."""
        return None if self.motion is None else self.motion.celerity_m_s

    @property
    def plug_length_mm(self) -> float | None:
        """Mean plug length (None without measured plugs)."""
        return None if self.lengths is None else self.lengths.plug_length_mm

    @property
    def bubble_length_mm(self) -> float | None:
        """Mean bubble length (None without measured bubbles)."""
        return None if self.lengths is None else self.lengths.bubble_length_mm

    @property
    def regime(self) -> str:
        """``"propagative"``, ``"oscillating"``, ``"static"`` (no motion of a pixel over the record) or
        ``"none"`` when no plug was followed over time."""
        return "none" if self.motion is None else self.motion.regime

    @property
    def first_movie_frame(self) -> int:
        """The movie's number of the first analysed frame (the start of a ``--start`` window, else 0)."""
        from .readers.window import first_movie_frame

        return first_movie_frame(self.info)

    # -- tables -----------------------------------------------------------------
    @cached_property
    def edges(self) -> pd.DataFrame:
        """Plug edges in every frame: ``frame, movie_frame, time_s, plug_id, top_mm, bottom_mm``.

        One row per plug per frame; ``top_mm``/``bottom_mm`` are NaN where the plug
        is cut by the end of the view. ``plug_id`` is the track (see :attr:`tracks`).
        """
        import pandas as pd

        r = self.runs
        return pd.DataFrame({"frame": r.frame.astype(np.int64),
                             "movie_frame": r.frame.astype(np.int64) + self.first_movie_frame,
                             "time_s": self.diagram.time_s[r.frame],
                             "plug_id": self.links.run_track.astype(np.int64), "top_mm": r.top_mm,
                             "bottom_mm": r.bottom_mm})

    @cached_property
    def tracks(self) -> pd.DataFrame:
        """One row per plug track: when it was seen, its celerity and length, how it began and ended."""
        import pandas as pd

        rows = track_rows(self)
        table = pd.DataFrame(rows, columns=list(TRACK_COLUMNS))
        if not rows:  # the columns' types of a table with rows, not object
            table = table.astype({k: "str" if t == "string" else t for k, (t, _) in TRACK_SCHEMA.items()})
        return table

    @cached_property
    def plugs(self) -> pd.DataFrame:
        """The plug lengths that enter the mean: ``plug_id, length_mm`` (median over the
        frames a whole plug was seen in; composite tracks left out)."""
        import pandas as pd

        per = self.lengths.per_track_mm if self.lengths else {}
        return pd.DataFrame({"plug_id": np.asarray(list(per), np.int64),
                             "length_mm": np.asarray(list(per.values()), float)})

    @cached_property
    def bubbles(self) -> pd.DataFrame:
        """The bubble lengths that enter the mean: ``upstream_plug_id, downstream_plug_id, length_mm``."""
        import pandas as pd

        ln = self.lengths
        pairs = ln.bubble_tracks if ln is not None else np.zeros((0, 2), np.int64)
        vals = ln.per_bubble_mm if ln is not None else np.zeros(0)
        return pd.DataFrame({"upstream_plug_id": pairs[:, 0].astype(np.int64),
                             "downstream_plug_id": pairs[:, 1].astype(np.int64), "length_mm": vals})

    def to_xarray(self, *, contrast: bool = False) -> xr.DataArray:
        """The spatiotemporal diagram as an ``xarray.DataArray`` (``time_s`` x ``position_mm``).

        Parameters
        ----------
        contrast : bool
            The normalised contrast (0 bubble level, 1 plug level) instead of the grey level.
        """
        import xarray as xr

        d = self.diagram
        values = self.normalized.z if contrast else d.values
        return xr.DataArray(
            values, dims=("time_s", "position_mm"), coords={"time_s": d.time_s, "position_mm": d.position_mm},
            name="contrast" if contrast else "grey_level",
            attrs={"mm_per_px": self.mm_per_px, "scale_source": self.scale_source,
                   "flow_direction": self.flow_direction, "movie": self.info.path,
                   "conventions": CONVENTIONS, "grainplug_version": __version__},
        )

    # -- display ----------------------------------------------------------------
    def _headline(self) -> list[str]:
        name = Path(self.info.path).name or self.info.path
        lines = [f"grainplug analysis of {name}: {self.diagram.n_frames} frames at {self.info.fps:g} fps, "
                 f"{self.mm_per_px:.4g} mm/px ({self.scale_source})"]
        if not self.has_plugs:
            lines.append(self.statement)
            return lines
        m, ln = self.motion, self.lengths
        if m is not None:
            value, lo, hi = with_interval(m.celerity_m_s, *m.celerity_ci95_m_s)
            lines.append(f"{m.regime}: celerity {value} m/s (95% CI {lo} to {hi})"
                         + (f", oscillation {m.oscillation_frequency_hz:.2f} Hz" if m.oscillation_frequency_hz
                            else ""))
        if ln is not None and ln.plug_length_mm is not None:
            b = f", bubbles {ln.bubble_length_mm:.2f} mm" if ln.bubble_length_mm is not None else ""
            lines.append(f"plugs {ln.plug_length_mm:.2f} mm = {ln.plug_length_mm / self.params.tube_diameter_mm:.2f} D"
                         f" ({ln.n_plugs_measured} plugs){b}; {len(self.links)} tracks")
        if self.statement:
            lines.append(self.statement)
        return lines

    def __repr__(self) -> str:
        lines = self._headline()
        lines += [f"warning: {w}" for w in self.warnings]
        return "<AnalysisResult " + "\n  ".join(lines) + ">"

    def _thumbnail_png(self, size: tuple[int, int] = (360, 120)) -> bytes:
        """A small grey image of the diagram (time across, position down), as PNG bytes."""
        from PIL import Image

        v = np.asarray(self.diagram.values, np.float32)
        st = max(1, v.shape[0] // (2 * size[0]))
        ss = max(1, v.shape[1] // (2 * size[1]))
        v = v[::st, ::ss].T
        lo, hi = np.nanpercentile(v, [1, 99]) if v.size else (0.0, 1.0)
        img = np.clip((v - lo) / max(hi - lo, 1e-9) * 255, 0, 255).astype(np.uint8)
        buf = io.BytesIO()
        Image.fromarray(img).resize(size, Image.BILINEAR).save(buf, format="PNG")
        return buf.getvalue()

    def _repr_html_(self) -> str:
        """Key numbers with their confidence intervals, warnings and a thumbnail, for Jupyter."""
        s = self.summary

        def num(v: object, nd: int) -> str:
            return "—" if v is None else f"{v:.{nd}f}"

        def ci(v: object, nd: int) -> str:
            return "" if not v else f" (95% CI {num(v[0], nd)} to {num(v[1], nd)})"

        rows = [
            ("regime", s["regime"]),
            ("celerity", "—" if s["celerity_m_s"] is None else
             "{} m/s (95% CI {} to {})".format(*with_interval(s["celerity_m_s"],
                                                               *(s["celerity_ci95_m_s"] or [None, None])))),
            ("plug length", f"{num(s['plug_length_mm'], 2)} mm{ci(s['plug_length_ci95_mm'], 2)}, "
                            f"{num(s['plug_length_over_diameter'], 2)} D, {s['n_plugs']} plugs"),
            ("bubble length", f"{num(s['bubble_length_mm'], 2)} mm{ci(s['bubble_length_ci95_mm'], 2)}"),
            ("oscillation", "none" if not s["oscillation_frequency_hz"] else
             f"{num(s['oscillation_frequency_hz'], 2)} Hz, amplitude {num(s['oscillation_amplitude_mm'], 2)} mm"),
            ("frames", f"{s['n_frames']} at {s['fps']:g} fps ({s['duration_s']:.3f} s)"),
            ("scale", f"{s['mm_per_px']:.5g} mm/px — {s['scale_source']}"),
            ("flow", f"{s['flow_direction']} — {s['flow_direction_source']}"),
        ]
        body = "".join(f"<tr><th style='text-align:left'>{html.escape(k)}</th>"
                       f"<td style='text-align:left'>{html.escape(str(v))}</td></tr>" for k, v in rows)
        warn = "".join(f"<li>{html.escape(w)}</li>" for w in self.warnings)
        statement = f"<p>{html.escape(self.statement)}</p>" if self.statement else ""
        thumb = base64.b64encode(self._thumbnail_png()).decode()
        return (f"<div><b>grainplug analysis</b> of <code>{html.escape(self.info.path)}</code>{statement}"
                f"<table>{body}</table>"
                + (f"<p style='color:#a40'>warnings:</p><ul style='color:#a40'>{warn}</ul>" if warn else "")
                + f"<img alt='spatiotemporal diagram' src='data:image/png;base64,{thumb}'/></div>")

    def plot(self, *, ax: Axes | None = None) -> Axes:
        """Draw the spatiotemporal diagram with the plug edges and the mean-celerity line.

        Parameters
        ----------
        ax : matplotlib Axes, optional
            Where to draw; by default a new pyplot figure (shown inline in a notebook).

        Returns
        -------
        matplotlib Axes
        """
        from .plotting import plot_diagram

        if ax is None:
            import matplotlib.pyplot as plt

            _, ax = plt.subplots(figsize=(9, 5.5), layout="constrained")
        plot_diagram(self, ax=ax)
        return ax

    def save(self, out_dir: str | Path, *, figures: bool = True, report: bool = True,
             figure_worker: FigureWorker | None = None, figure_options: FigureOptions | None = None,
             ) -> dict[str, Path]:
        """Write every output into ``out_dir`` (atomically); read back with :func:`grainplug.load_result`.

        Writes ``summary.json``, ``plug_edges.csv``, ``tracks.csv``, ``diagram.npz``,
        ``result.npz`` (everything :func:`~grainplug.load_result` needs) and, unless
        switched off, the figures and ``report.html``. An earlier result in ``out_dir`` is
        replaced as a whole (a folder holding files grainplug did not write is refused,
        naming them).

        Parameters
        ----------
        out_dir : str or Path
            The folder to write (created; replaced whole if it holds an earlier result).
        figures, report : bool
            Draw the figures, write ``report.html``.
        figure_worker : FigureWorker, optional
            A :class:`grainplug.plotting.worker.FigureWorker` started before the analysis:
            it draws the figures in another process meanwhile.
        figure_options : FigureOptions or dict, optional
            Resolution, formats (PNG, SVG, PDF) and a matplotlib style sheet
            (:class:`grainplug.FigureOptions`, or its fields as a dict); by default PNG at
            200 dpi, ``grainplug.PUBLICATION`` adds SVG and PDF.

        Returns
        -------
        dict of str to Path
            Every file written, by its output key.
        """
        from collections.abc import Mapping

        from .errors import ParameterError
        from .outputs import FigureOptions, write_outputs

        if isinstance(figure_options, Mapping):
            try:
                figure_options = FigureOptions(**figure_options)
            except TypeError:
                raise ParameterError(f"the figure options are dpi, formats and style, got {sorted(figure_options)}",
                                     param="figure_options") from None
        elif figure_options is not None and not isinstance(figure_options, FigureOptions):
            raise ParameterError(f"must be a FigureOptions (or a dict of its fields), got a "
                                 f"{type(figure_options).__name__}", param="figure_options")
        return write_outputs(self, out_dir, figures=figures, report=report, figure_worker=figure_worker,
                             figure_options=figure_options)


#: version of the run's tables (``plug_edges.csv``, ``tracks.csv``; in ``summary.json``): it changes
#: whenever a column changes meaning or type
TABLES_SCHEMA_VERSION = 2  # 2: movie_frame, first_movie_frame, last_movie_frame

#: ``plug_edges.csv``: column -> (type as ``pandas.read_csv`` reads it, meaning)
EDGE_SCHEMA: dict[str, tuple[str, str]] = {
    "frame": ("int64", "index among the analysed frames (0 = the first)"),
    "movie_frame": ("int64", "the frame's number in the movie (frame plus the first frame of a --start window)"),
    "time_s": ("float64", "time of the frame on the movie's clock, s"),
    "plug_id": ("int64", "the plug's track (tracks.csv)"),
    "top_mm": ("float64", "upstream edge, mm from the upstream end of the view; empty where cut by the view"),
    "bottom_mm": ("float64", "downstream edge, mm; empty where cut by the view"),
}

#: ``tracks.csv``: column -> (type as ``pandas.read_csv`` reads it: int64, float64, bool or string; meaning)
TRACK_SCHEMA: dict[str, tuple[str, str]] = {
    "plug_id": ("int64", "the track's id (plug_edges.csv)"),
    "first_frame": ("int64", "first frame it is seen in (an index among the analysed frames, as in plug_edges.csv)"),
    "last_frame": ("int64", "last frame it is seen in (the same index)"),
    "first_movie_frame": ("int64", "the number of its first frame in the movie"),
    "last_movie_frame": ("int64", "the number of its last frame in the movie"),
    "first_time_s": ("float64", "time of its first frame, s"),
    "last_time_s": ("float64", "time of its last frame, s"),
    "n_frames": ("int64", "frames it is seen in"),
    "n_frames_whole": ("int64", "frames where both its edges are in view"),
    "celerity_m_s": ("float64", "slope of its upstream edge (downstream edge if fewer than two seen), m/s, positive "
                                "downstream; empty with fewer than two edges"),
    "mean_length_mm": ("float64", "mean length over the frames where it is whole, mm; empty if never whole"),
    "median_length_mm": ("float64", "median of the same, mm"),
    "started_by": ("string", "start (first frame), entered (the view), merge, split or cut (a reviewer's split)"),
    "ended_by": ("string", "end (last frame), left (the view), merge, split or cut (a reviewer's split)"),
    "composite": ("bool", "True when born of a merge or ended by a split (left out of length averages)"),
}

#: columns of :attr:`AnalysisResult.tracks` and ``tracks.csv``
TRACK_COLUMNS = tuple(TRACK_SCHEMA)


def track_rows(res: AnalysisResult) -> list[dict[str, Any]]:
    """One dict per plug track (:data:`TRACK_COLUMNS`; NaN where a figure cannot be had).

    Notes
    -----
    A track's celerity is the slope of a straight line fitted to its upper edges (its lower
    edges when fewer than two upper ones are in view), in m/s; its lengths are over the
    frames where both edges are in view. Tracks left without a plug by a reviewer's
    corrections (excluded, or merged into another) have no row.
    """
    r, tr, t = res.runs, res.links, res.diagram.time_s
    off = res.first_movie_frame
    rows = []
    for tid in range(len(tr)):
        sel = tr.run_track == tid
        if not sel.any() and tr.first_frame[tid] < 0:
            continue
        frames = r.frame[sel]
        top, bot = r.top_mm[sel], r.bottom_mm[sel]
        whole = np.isfinite(top) & np.isfinite(bot)
        edge = top if np.isfinite(top).sum() >= 2 else bot
        ok = np.isfinite(edge)
        cel = np.nan
        if ok.sum() >= 2 and np.ptp(t[frames[ok]]) > 0:
            cel = float(np.polyfit(t[frames[ok]], edge[ok], 1)[0] / 1000)
        lengths = (bot - top)[whole]
        rows.append({
            "plug_id": tid, "first_frame": int(tr.first_frame[tid]), "last_frame": int(tr.last_frame[tid]),
            "first_movie_frame": int(tr.first_frame[tid]) + off, "last_movie_frame": int(tr.last_frame[tid]) + off,
            "first_time_s": float(t[tr.first_frame[tid]]), "last_time_s": float(t[tr.last_frame[tid]]),
            "n_frames": int(sel.sum()), "n_frames_whole": int(whole.sum()), "celerity_m_s": cel,
            "mean_length_mm": float(lengths.mean()) if lengths.size else np.nan,
            "median_length_mm": float(np.median(lengths)) if lengths.size else np.nan,
            "started_by": tr.started_by[tid], "ended_by": tr.ended_by[tid], "composite": bool(tr.composite(tid)),
        })
    return rows


def _r(x: float | None, nd: int = 6) -> float | None:
    return None if x is None or not np.isfinite(x) else round(float(x), nd)


def _tube_model(res: AnalysisResult) -> dict[str, object] | None:
    """The tube model's estimates for summary.json (None when the scale was given)."""
    b = res.bore
    if b is None:
        return None
    walls = res.tube.walls
    return {
        "method": b.method, "bore_px": {k: _r(v, 3) for k, v in b.estimates_px.items()},
        "agreement": _r(b.agreement, 4), "visible_fraction": _r(b.visible_fraction, 4),
        "lamp_half_angle_deg": _r(b.lamp_half_angle_deg, 2), "back_lit": res.tube.back_lit,
        "outer_width_px": _r(2 * walls.outer_half_px, 3) if walls else None,
        "stripe_separation_px": _r(2 * walls.stripe_half_px, 3) if walls else None,
        "glass_index": res.params.glass_index, "outer_diameter_mm": res.params.tube_outer_diameter_mm,
    }


def flow_angle_deg(tube: TubeGeometry, direction: str) -> float:
    """Direction of the flow in the image, degrees from +x towards +y (y down)."""
    a = np.radians(tube.tilt_deg)
    ex, ey = np.sin(a), np.cos(a)
    if runs_backwards(direction):
        ex, ey = -ex, -ey
    if tube.orientation == "horizontal":
        ex, ey = ey, ex
    return float(np.degrees(np.arctan2(ey, ex)))


def build_summary(res: AnalysisResult) -> dict[str, Any]:
    """JSON-ready summary with provenance (see ``summary.json`` in the docs)."""
    m, ln, tube = res.motion, res.lengths, res.tube
    D = res.params.tube_diameter_mm
    plug_len = ln.plug_length_mm if ln else None
    return {
        "grainplug_version": __version__,
        "tables_schema_version": TABLES_SCHEMA_VERSION,
        "input": res.input,
        "movie": res.info.as_dict(),
        "parameters": res.params.as_record(),
        "has_plugs": res.has_plugs,
        "statement": res.statement or None,
        "celerity_m_s": _r(m.celerity_m_s) if m else None,
        "celerity_ci95_m_s": [_r(x) for x in m.celerity_ci95_m_s] if m else None,
        "plug_length_mm": _r(plug_len, 4),
        "plug_length_ci95_mm": [_r(x, 4) for x in ln.plug_length_ci95_mm] if ln and ln.plug_length_ci95_mm else None,
        "plug_length_sd_mm": _r(ln.plug_length_sd_mm, 4) if ln else None,
        "plug_length_over_diameter": _r(plug_len / D, 4) if plug_len else None,
        "bubble_length_mm": _r(ln.bubble_length_mm, 4) if ln else None,
        "bubble_length_ci95_mm": (
            [_r(x, 4) for x in ln.bubble_length_ci95_mm] if ln and ln.bubble_length_ci95_mm else None
        ),
        "oscillation_frequency_hz": _r(m.oscillation_frequency_hz, 4) if m and m.oscillation_frequency_hz else None,
        "oscillation_amplitude_mm": _r(m.oscillation_amplitude_mm, 4) if m else None,
        "oscillation_explained_fraction": _r(m.explained_fraction, 4) if m else None,
        "regime": m.regime if m else "none",
        "n_plugs": int(ln.n_plugs_measured) if ln else 0,
        "n_tracks": len(res.links),
        "n_bubbles": int(ln.n_bubbles_measured) if ln else 0,
        "n_edges_used": m.n_edges if m else 0,
        "n_frames": int(res.diagram.n_frames),
        "fps": res.info.fps,
        "duration_s": _r(res.diagram.n_frames / res.info.fps, 6),
        "mm_per_px": _r(res.mm_per_px, 6),
        "scale_source": res.scale_source,
        "scale_rel_sd": _r(res.scale_rel_sd, 6),
        "tube_diameter_mm": D,
        "tube_diameter_px": _r(res.bore.diameter_px if res.bore else res.params.tube_diameter_mm / res.mm_per_px, 4),
        "tube_visible_width_px": _r(tube.inner_diameter_px, 4),
        "tube_model": _tube_model(res),
        "tube_axis_angle_deg": _r(flow_angle_deg(tube, res.flow_direction), 4),
        "tube_tilt_deg": _r(tube.tilt_deg, 4),
        "tube_orientation": tube.orientation,
        "tube_detection": tube.method,
        "flow_direction": res.flow_direction,
        "flow_direction_source": res.flow_direction_source,
        "falling_grain_speed_m_s": _r(res.falling_grain_speed_m_s, 4),
        "warnings": list(res.warnings),
        **_corrections_fields(res),
        "corrections_applied": res.corrections.as_dict()["edits"] if res.corrections is not None else [],
        "view_length_mm": _r(float(res.diagram.position_mm[-1] + 0.5 * res.mm_per_px), 4),
        "illumination": {
            "plugs_darker_than_bubbles": res.normalized.plugs_darker,
            "plug_bubble_separation_eta": _r(res.normalized.separation_eta, 4),
            # where the separation alone was short: the same along the tube averaged over a third of the shortest plug
            "plug_bubble_separation_eta_averaged": (None if res.normalized.averaged_eta is None
                                                    else _r(res.normalized.averaged_eta, 4)),
            "flicker_sd": _r(float(np.std(res.normalized.frame_gain)), 5),
            "gradient_along_view": _r(float(res.normalized.position_gain[-1] / res.normalized.position_gain[0] - 1), 4),
        },
        "timings_s": dict(res.timings),
        "conventions": CONVENTIONS,
    }


def _corrections_fields(res: AnalysisResult) -> dict[str, object]:
    """The edits applied, in words, and the times the measures use: the record, or what its corrections keep
    of it (``kept_window_s``, ``not_plugs_s``); the corrections replayed once."""
    t0, t1 = float(res.diagram.time_s[0]), float(res.diagram.time_s[-1])
    if res.corrections is None:
        return {"corrections": [], "kept_window_s": [_r(t0, 6), _r(t1, 6)], "not_plugs_s": []}
    from .corrections import replayed  # imported here: only a corrected result needs the replay

    st = replayed(res)
    lo, hi = st.window
    lo = t0 if lo is None else max(lo, t0)
    hi = t1 if hi is None else min(hi, t1)
    window = [_r(lo, 6), _r(hi, 6)] if lo <= hi else None  # None: the window holds none of the record
    merged: list[list[float]] = []  # the spans within the record, overlaps joined
    for a, b in sorted((max(a, t0), min(b, t1)) for a, b in st.spans):
        if a > b:
            continue
        if merged and a <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], b)
        else:
            merged.append([a, b])
    return {"corrections": [e.describe() for e in st.applied], "kept_window_s": window,
            "not_plugs_s": [[_r(a, 6), _r(b, 6)] for a, b in merged]}
