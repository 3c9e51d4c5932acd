"""Experiment and model side by side: one call, :func:`compare`, in the same quantities and units.

Notes
-----
A movie's analysis (:class:`~grainplug.result.AnalysisResult`) and a simulation
(:class:`~grainplug.simulation.study.SimulationStudy`, or its bare
:class:`~grainplug.simulation.state.SimulationResult`) are each reduced to the same figures:

- the pattern, measured alike (the simulation's compactness diagram is measured as a movie's,
  :mod:`grainplug.simulation.measure`): regime, celerity (m/s, positive downstream), plug and bubble
  lengths (mm);
- the grains' compactness: in the plugs and in the bubbles, and its distribution over time and position
  (quantiles), for an analysis only when it was read from the light (``packed=``);
- the grains' velocity in the plugs (m/s, positive downstream), when measured.

The simulation's dense (plug) and dilute (bubble) cells are told apart as the movie's plugs are: by the
midpoint between the two modes of the compactness (the 10th and 90th percentiles over the run's second
half); a run with one dense wave and no bubble then has "bubbles" no denser than random loose packing
only where the compactness really drops. What one side does not have is None, and :attr:`Comparison.notes`
says why.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING

import numpy as np

from .errors import ParameterError

if TYPE_CHECKING:
    from .result import AnalysisResult
    from .simulation.state import SimulationResult
    from .simulation.study import SimulationStudy

#: the quantiles of the compactness's distribution given for each side
QUANTILES = (0.05, 0.25, 0.5, 0.75, 0.95)


@dataclass(frozen=True)
class Side:
    """One side's figures (see module notes); None where that side has none."""

    regime: str | None = None
    celerity_m_s: float | None = None
    plug_length_mm: float | None = None
    bubble_length_mm: float | None = None
    compactness_plugs: float | None = None
    compactness_bubbles: float | None = None
    #: the compactness at :data:`QUANTILES` over time and position
    compactness_quantiles: tuple[float, ...] | None = None
    grain_velocity_in_plugs_m_s: float | None = None


#: the rows of :meth:`Comparison.table`: (attribute, what it is, unit)
ROWS = (("regime", "regime", ""), ("celerity_m_s", "celerity (positive downstream)", "m/s"),
        ("plug_length_mm", "plug length", "mm"), ("bubble_length_mm", "bubble length", "mm"),
        ("compactness_plugs", "compactness in the plugs", "1"),
        ("compactness_bubbles", "compactness in the bubbles", "1"),
        ("grain_velocity_in_plugs_m_s", "grain velocity in the plugs (positive downstream)", "m/s"))


@dataclass(frozen=True)
class Comparison:
    """An experiment and a model reduced to the same figures (:func:`compare`).

    Attributes
    ----------
    experiment, model : Side
    notes : tuple of str
        What a side could not give, and why.
    experiment_compactness, model_compactness : ndarray or None
        The compactness values each side's distribution was taken from (a sample, for figures).
    """

    experiment: Side
    model: Side
    notes: tuple[str, ...] = ()
    experiment_compactness: np.ndarray | None = field(default=None, repr=False)
    model_compactness: np.ndarray | None = field(default=None, repr=False)

    def table(self) -> list[dict[str, object]]:
        """One row per quantity: ``quantity``, ``unit``, ``experiment``, ``model``."""
        return [{"quantity": label, "unit": unit, "experiment": getattr(self.experiment, key),
                 "model": getattr(self.model, key)} for key, label, unit in ROWS]

    def as_dict(self) -> dict[str, object]:
        """JSON-ready: both sides and the notes."""
        def side(s: Side) -> dict[str, object]:
            return {f.name: (list(v) if isinstance(v := getattr(s, f.name), tuple) else v) for f in fields(s)}

        return {"experiment": side(self.experiment), "model": side(self.model), "quantiles": list(QUANTILES),
                "notes": list(self.notes)}

    def plot(self):  # -> matplotlib Figure
        """The compactness distributions of both sides, and the pattern's figures, side by side."""
        import matplotlib.pyplot as plt

        fig, (ax, bx) = plt.subplots(1, 2, figsize=(9.0, 3.4), layout="constrained")
        bins = np.linspace(0.0, 0.75, 61)
        for values, label, colour in ((self.experiment_compactness, "experiment", "#D55E00"),
                                      (self.model_compactness, "model", "#0072B2")):
            if values is not None and values.size:
                ax.hist(values, bins=bins, density=True, histtype="step", lw=1.6, color=colour, label=label)
        ax.set_xlabel("compactness c")
        ax.set_ylabel("share (density)")
        if ax.has_data():
            ax.legend(frameon=False)
        else:
            ax.text(0.5, 0.5, "no compactness on either side", ha="center", va="center", transform=ax.transAxes)
        short = {"celerity_m_s": "celerity (m/s)", "plug_length_mm": "plug length (mm)",
                 "bubble_length_mm": "bubble length (mm)", "compactness_plugs": "compactness, plugs",
                 "compactness_bubbles": "compactness, bubbles", "grain_velocity_in_plugs_m_s": "grains in plugs (m/s)",
                 "regime": "regime"}

        def fmt(v: object) -> str:
            return "—" if v is None else v if isinstance(v, str) else f"{v:.4g}"

        text = [f"{'':22s} {'experiment':>11s} {'model':>11s}"]
        for key, label in short.items():
            text.append(f"{label:22s} {fmt(getattr(self.experiment, key)):>11s} {fmt(getattr(self.model, key)):>11s}")
        text.append("celerity and velocities positive downstream")
        bx.axis("off")
        bx.text(0.0, 0.95, "\n".join(text), family="monospace", fontsize=8, va="top", transform=bx.transAxes)
        return fig


def _split(c: np.ndarray) -> float:
    """The compactness between the dense and the dilute mode (module notes)."""
    lo, hi = np.nanpercentile(c, [10, 90])
    return float(0.5 * (lo + hi))


def _experiment(res: AnalysisResult, notes: list[str]) -> tuple[Side, np.ndarray | None]:
    m, ln, comp = res.motion, res.lengths, res.compactness
    values = None
    quantiles = None
    if res.compactness_field is not None:
        finite = res.compactness_field[np.isfinite(res.compactness_field)]
        values = finite[:: max(1, finite.size // 200_000)]
        quantiles = tuple(float(q) for q in np.quantile(finite, QUANTILES)) if finite.size else None
    else:
        notes.append("experiment: no compactness (" + (res.compactness_note or "not measured") + ")")
    velocity = getattr(res, "grain_velocity_in_plugs_m_s", None)
    if velocity is None:
        notes.append("experiment: no grain velocity in the plugs measured")
    return Side(regime=None if m is None else m.regime, celerity_m_s=None if m is None else m.celerity_m_s,
                plug_length_mm=None if ln is None else ln.plug_length_mm,
                bubble_length_mm=None if ln is None else ln.bubble_length_mm,
                compactness_plugs=None if comp is None else comp.plug,
                compactness_bubbles=None if comp is None else comp.bubble,
                compactness_quantiles=quantiles, grain_velocity_in_plugs_m_s=velocity), values


def _model(sim: SimulationStudy | SimulationResult, notes: list[str]) -> tuple[Side, np.ndarray]:
    from .simulation.measure import measure

    study = sim if hasattr(sim, "measured") else None
    res = study.result if study is not None else sim
    seen = study.measured if study is not None else measure(res)
    half = res.time >= 0.5 * float(res.time[-1])  # the pattern settled, as the movie measures take it
    c = np.asarray(res.c[half], float)
    v = np.asarray(res.v[half], float) * res.model.v_c_m_s
    split = _split(c)
    dense = c >= split
    finite = c[np.isfinite(c)]
    if not (~dense).any() or float(np.ptp(finite)) < 0.05:
        notes.append(f"model: the compactness hardly varies ({np.min(finite):.2f} to {np.max(finite):.2f}): "
                     "no bubble to tell from the plugs")
    plugs = float(np.mean(c[dense])) if dense.any() else None
    bubbles = float(np.mean(c[~dense])) if (~dense).any() else None
    return Side(regime=seen.regime, celerity_m_s=seen.celerity_m_s, plug_length_mm=seen.plug_length_mm,
                bubble_length_mm=seen.bubble_length_mm, compactness_plugs=plugs, compactness_bubbles=bubbles,
                compactness_quantiles=tuple(float(q) for q in np.quantile(finite, QUANTILES)),
                grain_velocity_in_plugs_m_s=float(np.mean(v[dense])) if dense.any() else None), \
        finite[:: max(1, finite.size // 200_000)]


def compare(result: AnalysisResult, simulation: SimulationStudy | SimulationResult) -> Comparison:
    """An analysis and a simulation in the same figures (see module notes).

    Parameters
    ----------
    result : AnalysisResult
        A movie's analysis (``gp.analyze``, or ``gp.load_result``).
    simulation : SimulationStudy or SimulationResult
        A run of the model (``gp.simulation.run_study``, ``gp.simulate``).

    Returns
    -------
    Comparison
    """
    if not hasattr(result, "diagram") or not hasattr(result, "motion"):
        raise ParameterError(f"result must be an analysis (gp.analyze or gp.load_result), got a "
                             f"{type(result).__name__}", param="result")
    if not (hasattr(simulation, "measured") or hasattr(simulation, "c")):
        raise ParameterError(f"simulation must be a simulation (gp.simulation.run_study or gp.simulate), got a "
                             f"{type(simulation).__name__}", param="simulation")
    notes: list[str] = []
    experiment, exp_values = _experiment(result, notes)
    model, model_values = _model(simulation, notes)
    return Comparison(experiment, model, tuple(notes), exp_values, model_values)
