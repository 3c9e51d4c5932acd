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
from typing import TYPE_CHECKING

import numpy as np

from ._format import oscillation_phrase, with_interval
from ._version import __version__
from .calibration.tube import TubeGeometry
from .calibration.tube_model import BoreEstimate
from .diagram import Diagram, Normalized
from .diagram.light import Lamp
from .measures import Lengths, Motion
from .measures.compactness import PhaseCompactness
from .measures.creep import GrainVelocity
from .measures.mass_flow import MassFlow, mass_flow_rate, mean_compactness
from .measures.motion import Oscillation
from .measures.shake import Shake
from .measures.still import BlindStretch
from .params import AnalysisParams
from .plugs import Runs, Tracks
from .readers.base import MovieInfo

# EDGE_SCHEMA, TRACK_SCHEMA, TABLES_SCHEMA_VERSION, track_rows: re-exported from here for one release (now in
# grainplug.summary)
from .summary import (  # noqa: F401
    CONVENTIONS,
    EDGE_SCHEMA,
    TABLES_SCHEMA_VERSION,
    TRACK_COLUMNS,
    TRACK_SCHEMA,
    build_summary,
    track_rows,
)

if TYPE_CHECKING:
    import pandas as pd
    import xarray as xr
    from matplotlib.axes import Axes

    from .corrections import Corrections
    from .plotting.options import FigureOptions
    from .plotting.worker import FigureWorker


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
    blind : tuple of BlindStretch
        Stretches of the tube whose contents are hidden (given as ``mask_mm``, or found where
        nothing changed over the record), left out of the plugs and bubbles measured.
    shake : Shake or None
        The tube's motion in the image (camera shake), measured on its walls and what is still beside it.
    lamp : Lamp or None
        The lamp's light read beside the tube, and whether the diagram was divided by it.
    tube_unseen : tuple of (int, int)
        Stretches of frames (first, last analysed frame) in which the tube was not in view (its walls not seen:
        something in front of it, the camera knocked off it): no plug is found there
        (:mod:`grainplug.measures.view`).
    compactness : PhaseCompactness or None
        The plugs' and the bubbles' compactness, read from the light between an empty and a packed
        reference (:mod:`grainplug.measures.compactness`); None when not measured.
    compactness_field : ndarray or None
        The compactness at every frame and position (the diagram's shape).
    compactness_note : str
        Why the compactness was not measured (empty when it was).
    grain_velocity : GrainVelocity or None
        The packed grains' velocity inside the plugs, window by window, and its mean
        (:mod:`grainplug.measures.creep`); None when not measured (a result read back from a file).
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
    blind: tuple[BlindStretch, ...] = ()
    shake: Shake | None = None
    lamp: Lamp | None = None
    tube_unseen: tuple[tuple[int, int], ...] = ()
    compactness: PhaseCompactness | None = None
    compactness_field: np.ndarray | None = field(default=None, repr=False)
    compactness_note: str = ""
    grain_velocity: GrainVelocity | None = field(default=None, repr=False)

    # -- figures --------------------------------------------------------------
    @property
    def summary(self) -> dict[str, object]:
        """The figures of ``summary.json`` (JSON-ready, with provenance).

        What the result knows: ``summary.json`` also lists the files written (``outputs``)
        and the figure settings (``figures``), which a result does not keep; read that file
        for them.
        """
        return build_summary(self)

    @cached_property
    def mass_flow(self) -> MassFlow:
        """The grains' mass flow rate from the movie (:mod:`grainplug.measures.mass_flow`), or why it is not
        given: it needs the compactness (``background=`` and ``packed=``), the grains' velocity in the plugs
        and the celerity."""
        from .measures.compactness import LIGHT_MODEL_HALF_WIDTH

        comp, g, m = self.compactness, self.grain_velocity, self.motion
        c_mean, c_mean_ci = (None, None) if self.compactness_field is None else mean_compactness(
            self.compactness_field, half_width_floor=LIGHT_MODEL_HALF_WIDTH)
        missing = "" if comp is not None else (self.compactness_note or "no references given")
        return mass_flow_rate(
            c_plug=None if comp is None else comp.plug, c_plug_ci95=None if comp is None else comp.plug_ci95,
            v_plug_m_s=None if g is None else g.mean_m_s, v_plug_ci95_m_s=None if g is None else g.ci95_m_s,
            celerity_m_s=None if m is None else m.celerity_m_s,
            celerity_ci95_m_s=None if m is None else m.celerity_ci95_m_s, c_mean=c_mean, c_mean_ci95=c_mean_ci,
            bore_mm=self.params.tube_diameter_mm, grain_density_kg_m3=self.params.grain_density_kg_m3,
            oscillating=m is not None and m.oscillation_frequency_hz is not None, missing=missing)

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

    def fields(self) -> xr.Dataset:
        """The fields over ``(time, z)``, with ``time_s`` and ``position_mm`` coordinates, as
        ``grainplug simulate`` writes its own (``fields.nc``): ``grey_level`` (the diagram), ``contrast``
        (0 bubble, 1 plug) and, when measured, ``c`` (the grains' compactness) and ``v_m_s`` (the grains'
        velocity in the plugs, where measured, NaN elsewhere), the same names and units as the simulation's."""
        import xarray as xr

        d = self.diagram
        dims = ("time", "z")
        data = {"grey_level": (dims, d.values.astype(np.float32), {"long_name": "the band's grey level"}),
                "contrast": (dims, self.normalized.z.astype(np.float32),
                             {"long_name": "plug contrast (0 bubble, 1 plug)", "units": "1"})}
        if self.compactness_field is not None:
            data["c"] = (dims, self.compactness_field.astype(np.float32),
                         {"long_name": "compactness", "units": "1",
                          "packed_reference": float(self.params.packed_compactness)})
        g = self.grain_velocity
        if g is not None and g.mean_m_s is not None and len(g.velocity_m_s):
            # each window's velocity at its centre and at the middle of its pair of frames; NaN where none was
            v = np.full(d.values.shape, np.nan, np.float32)
            k = np.clip(np.asarray(g.frame) + np.asarray(g.lag) // 2, 0, d.n_frames - 1)
            at = np.clip(np.searchsorted(d.position_mm, np.asarray(g.position_mm)), 0, len(d.position_mm) - 1)
            v[k, at] = np.asarray(g.velocity_m_s, np.float32)
            data["v_m_s"] = (dims, v, {"long_name": "grain velocity in the plugs (positive downstream), where a "
                                                    "window of the plugs' texture was correlated; NaN elsewhere",
                                       "units": "m s-1"})
        return xr.Dataset(
            data, coords={"time_s": ("time", d.time_s, {"units": "s"}),
                          "position_mm": ("z", d.position_mm, {"units": "mm",
                                                               "long_name": "from the upstream end of the view"})},
            attrs={"grainplug_version": __version__, "movie": self.info.path, "mm_per_px": self.mm_per_px,
                   "scale_source": self.scale_source, "flow_direction": self.flow_direction,
                   "conventions": CONVENTIONS})

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
            ("oscillation", "none" if not s["oscillation_frequency_hz"] else oscillation_phrase(
                s["oscillation_frequency_hz"], s.get("oscillation_frequency_ci95_hz"), s["oscillation_amplitude_mm"],
                s.get("oscillation_amplitude_ci95_mm"), s.get("oscillation_kind"),
                s.get("oscillation_stick_fraction"))),
            ("compactness", s["compactness"]["note"] or
             f"plugs {num(s['compactness']['plugs'], 3)}{ci(s['compactness']['plugs_ci95'], 3)}, "
             f"bubbles {num(s['compactness']['bubbles'], 3)}{ci(s['compactness'].get('bubbles_ci95'), 3)}"),
            ("mass flow rate", s["mass_flow_rate_note"] if s["mass_flow_rate_g_s"] is None else
             f"{num(s['mass_flow_rate_g_s'], 3)} g/s{ci(s['mass_flow_rate_ci95_g_s'], 3)}"),
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


def result_types() -> dict[str, type]:
    """The classes a ``result.npz`` is made of, by name (what :func:`grainplug.store.read_result` builds)."""
    from .calibration.background import Background
    from .calibration.pattern import Calibration
    from .calibration.tube_model import WallMeasure
    from .corrections import Corrections, Edit

    return {t.__name__: t for t in (AnalysisResult, AnalysisParams, MovieInfo, TubeGeometry, Calibration, Diagram,
                                    Normalized, Runs, Tracks, Motion, Lengths, WallMeasure, BoreEstimate,
                                    Background, Corrections, Edit, BlindStretch, Shake, Lamp, PhaseCompactness,
                                    GrainVelocity, Oscillation)}


def load_result(folder: str | Path) -> AnalysisResult:
    """Read back an analysis saved by :meth:`AnalysisResult.save` or ``grainplug analyze``.

    Parameters
    ----------
    folder : str or Path
        The output folder (or its ``result.npz``, or another of its files).

    Returns
    -------
    AnalysisResult
        Equal, field by field, to the result that was saved.

    Examples
    --------
    >>> res = gp.load_result("out/run1")   # doctest: +SKIP
    >>> res.tracks.head()                  # doctest: +SKIP
    """
    from .store import read_result, result_file

    return read_result(result_file(folder), result_types())
