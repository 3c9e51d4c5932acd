"""The study of one simulation: the run, its waves, its diagram measured as a movie's, the linear prediction.

Notes
-----
:func:`run_study` runs :func:`~grainplug.simulation.run.simulate` (the time loop), then
measures the fields (:func:`~grainplug.simulation.waves.wave_state`), the compactness
diagram through the movie analysis's own stages
(:func:`~grainplug.simulation.measure.measure`) and the set-up's linear analysis
(:func:`grainplug.stability.analyze_stability`), and adds the warnings only the comparison
can give (waves that have not had time to grow, an open pipe's start-up still in the
measured part, one wave filling the box). It returns a :class:`SimulationStudy`, which
holds all of it and gives it as ``summary.json`` (:attr:`SimulationStudy.summary`), a figure
(:meth:`SimulationStudy.plot`) and a folder (:meth:`SimulationStudy.save`), as
:class:`grainplug.AnalysisResult` does for a movie. :func:`simulate_and_measure` is the same
as the pair ``(result, summary)``.

The top layer of :mod:`grainplug.simulation`: it imports the loop (:mod:`.run`), the data
(:mod:`.state`) and the measures (:mod:`.waves`, :mod:`.measure`); none of them imports it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._version import __version__
from ..stability.params import ModelParams
from .run import simulate
from .state import MIN_WAVE_RANGE_C, RANDOM_CLOSE_PACKING, SimulationParams, SimulationResult
from .waves import WaveState, segment_counts, wave_state

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ..plotting.options import FigureOptions
    from ..stability.analysis import StabilityResult
    from .measure import SimulationMeasures

__all__ = ["GROWN_AMPLITUDE", "SETTLED_SHARE", "SimulationStudy", "run_study", "simulate_and_measure"]

#: the wavenumbers ``k*`` of the linear analysis a run is compared with
LINEAR_K_RANGE = (1e-3, 3.0)
#: and their number
LINEAR_N_K = 1000


@dataclass(frozen=True, eq=False)
class SimulationStudy:
    """One simulation and what it measured: the nonlinear run beside the linear prediction.

    Made by :func:`run_study`. Every attribute is computed once; :attr:`summary` is the
    JSON-ready ``summary.json``, :meth:`plot` draws the run and :meth:`save` writes it.

    Attributes
    ----------
    result : SimulationResult
        The fields at the output times, with the run's own checks (``result.warnings``).
    linear : StabilityResult
        The linear analysis of the set-up, ``k*`` in ``[0.001, 3]``.
    waves : WaveState
        The dense segments at the end of the run and the speed of their fronts.
    measured : SimulationMeasures
        The compactness diagram measured as a movie's (its second half).
    warnings : tuple of str
        The run's warnings, then the study's (waves not grown, start-up not left, one wave
        filling the box).
    seed : int, optional
        The seed of the generator that made the initial noise, recorded in the summary when
        given (a :class:`numpy.random.Generator` cannot tell it).
    """

    result: SimulationResult
    linear: StabilityResult
    waves: WaveState
    measured: SimulationMeasures
    warnings: tuple[str, ...]
    seed: int | None = None

    @property
    def summary(self) -> dict[str, object]:
        """The figures of ``summary.json``: the version, the set-up and its caveats, the run's parameters and
        conservation totals, the linear prediction, the waves, the measures as a movie's, the warnings (and the
        seed when known). A new dict at each call."""
        res = self.result
        p = res.model
        lin = self.linear
        mu = lin.most_unstable
        waves, seen = self.waves, self.measured
        summary: dict[str, object] = {
            "grainplug_version": __version__,
            "model": p.as_dict(),
            "caveats": [*p.caveats(), *_balance_caveats(p, res.params)],
            "run": {**dataclasses.asdict(res.params), "n_steps": res.n_steps, "wall_s": round(res.wall_s, 3),
                    "duration_s": res.params.duration_tc * p.t_c_s, "length_mm": res.params.length_D * p.diameter_mm,
                    # the uniform force added to make the base state steady (units of rho_s g), as resolved
                    "balance": res.params.balanced,
                    "balance_force_rho_s_g": p.base_state_residual if res.params.balanced else 0.0,
                    "grain_drift": res.grain_drift, "air_drift": res.air_drift,
                    "grain_total": [float(res.grain_total[0]), float(res.grain_total[-1])],
                    # what crossed the open pipe's ends (units of grain_total), and what the content's change
                    # leaves unexplained by it (relative): the conservation check of either boundary
                    "grain_inflow": float(res.grain_inflow[-1]) if res.grain_inflow is not None else 0.0,
                    "grain_outflow": float(res.grain_outflow[-1]) if res.grain_outflow is not None else 0.0,
                    "grain_budget_residual": res.grain_budget_residual,
                    "air_total": [float(res.air_total[0]), float(res.air_total[-1])]},
            "linear": {"most_unstable_lambda_D": None if mu is None else mu.wavelength_over_diameter,
                       "growth_rate_per_tc": None if mu is None else mu.growth_rate,
                       "phase_speed_m_s": None if mu is None else mu.phase_speed * p.v_c_m_s,
                       # the growth still rising at that end of k* in [0.001, 3]: no maximum inside
                       "most_unstable_at_range_edge": None if mu is None else mu.at_range_edge,
                       "cutoff_lambda_D": lin.cutoff_wavelength_over_diameter},
            "waves": waves.as_dict(D_mm=p.diameter_mm, v_c_m_s=p.v_c_m_s),
            "measured_as_movie": seen.as_dict(),
            "warnings": list(self.warnings),
        }
        if self.seed is not None:
            summary["seed"] = self.seed
        return summary

    def plot(self, *, max_rows: int = 1500) -> Figure:
        """Draw the run: (a) the compactness over position and time, (b) the dense segments and the peak
        compactness over time (:func:`grainplug.plotting.simulation.plot_simulation`).

        Parameters
        ----------
        max_rows : int
            At most this many output times drawn in (a) (every n-th beyond it).

        Returns
        -------
        matplotlib.figure.Figure
            Not registered with pyplot: shown by a notebook as it is, freed with its last reference.
        """
        from ..plotting.simulation import plot_simulation

        return plot_simulation(self.result, segment_counts(self.result), close_packing=RANDOM_CLOSE_PACKING,
                               min_range_c=MIN_WAVE_RANGE_C, max_rows=max_rows)

    def save(self, out_dir: str | Path, *, figures: bool = True,
             figure_options: FigureOptions | Mapping[str, object] | None = None) -> dict[str, Path]:
        """Write ``fields.nc``, ``summary.json`` and (unless switched off) ``diagram.png`` into ``out_dir``,
        atomically (:func:`grainplug.simulation.store.save_simulation`): an earlier run's folder there is
        replaced as a whole.

        Parameters
        ----------
        out_dir : str or Path
            The folder to write.
        figures : bool
            Draw :meth:`plot` into ``diagram.png``.
        figure_options : FigureOptions or dict, optional
            Resolution and formats of the figure (:class:`grainplug.FigureOptions`, or its fields as a
            dict); by default PNG at 200 dpi, ``grainplug.PUBLICATION`` adds SVG and PDF.

        Returns
        -------
        dict of str to Path
            Every file written.
        """
        from .store import save_simulation

        options = _figure_options(figure_options)
        fig = self.plot() if figures else None
        return save_simulation(self.result, out_dir, self.summary, figure=fig, figure_options=options)

    def __repr__(self) -> str:
        p = self.result.params
        waves = f"{self.waves.n_waves} waves" if self.waves.n_waves else "no waves"
        return (f"<SimulationStudy {p.boundary} L={p.length_D:g} D, {p.n_cells} cells, "
                f"t={self.result.time[-1]:g} t_c: {waves}, as a movie {self.measured.regime}, "
                f"{len(self.warnings)} warnings>")


def _figure_options(options: FigureOptions | Mapping[str, object] | None) -> FigureOptions | None:
    """``options`` as a :class:`~grainplug.plotting.options.FigureOptions` (a dict of its fields accepted)."""
    from ..errors import ParameterError
    from ..plotting.options import FigureOptions

    if isinstance(options, Mapping):
        try:
            return FigureOptions(**options)  # type: ignore[arg-type]
        except TypeError:
            raise ParameterError(f"the figure options are dpi, formats and style, got {sorted(options)}",
                                 param="figure_options") from None
    if options is not None and not isinstance(options, FigureOptions):
        raise ParameterError(f"must be a FigureOptions (or a dict of its fields), got a {type(options).__name__}",
                             param="figure_options")
    return options


def run_study(model: ModelParams, params: SimulationParams | None = None, *, rng: np.random.Generator | None = None,
              progress: object = None, seed: int | None = None) -> SimulationStudy:
    """:func:`~grainplug.simulation.run.simulate`, then the waves on the fields, the diagram measured as a movie's
    and the linear prediction, with the warnings of their comparison.

    Parameters
    ----------
    model : ModelParams
        The set-up.
    params : SimulationParams, optional
        How to run it (default :class:`SimulationParams`).
    rng : numpy.random.Generator, optional
        Source of the initial noise (default: a fresh generator seeded with 0).
    progress : callable, optional
        Called as ``progress(t, duration)`` at each output.
    seed : int, optional
        The seed ``rng`` was made from, only recorded (:attr:`SimulationStudy.seed`).

    Returns
    -------
    SimulationStudy
    """
    from ..stability import analyze_stability
    from .measure import measure  # the movie analysis's stages (grainplug.pipeline): loaded when first used

    res = simulate(model, params, rng=rng, progress=progress)
    lin = analyze_stability(res.model, k_min=LINEAR_K_RANGE[0], k_max=LINEAR_K_RANGE[1], n_k=LINEAR_N_K)
    waves = wave_state(res)
    seen = measure(res)
    return SimulationStudy(result=res, linear=lin, waves=waves, measured=seen,
                           warnings=tuple(_study_warnings(res, lin, waves, seen)), seed=seed)


def simulate_and_measure(model: ModelParams, params: SimulationParams | None = None, *,
                         rng: np.random.Generator | None = None,
                         progress: object = None) -> tuple[SimulationResult, dict[str, object]]:
    """:func:`~grainplug.simulation.run.simulate`, then the waves on the fields, the diagram measured as a movie's
    and the linear prediction, as one JSON-ready summary (with the version, the set-up and the run's parameters):
    :func:`run_study`'s ``(study.result, study.summary)``."""
    study = run_study(model, params, rng=rng, progress=progress)
    return study.result, study.summary


def _study_warnings(res: SimulationResult, lin: StabilityResult, waves: WaveState,
                    seen: SimulationMeasures) -> list[str]:
    """The run's warnings, then those of comparing it with the linear prediction and of measuring it."""
    mu = lin.most_unstable
    warnings = list(res.warnings)
    if mu is not None and mu.growth_rate > 0 and not waves.n_waves and res.params.boundary == "periodic":
        warnings.append(_not_grown(mu.growth_rate, res.params.duration_tc, res.params.noise))
    if res.params.boundary == "open":
        warnings.extend(_start_up_left(res, seen.t_from_tc))
    if waves.n_waves and res.params.boundary == "periodic" and waves.n_waves == 1:
        warnings.append(f"one wave fills the box ({res.params.length_D:g} D): the dense-segment length "
                        f"({waves.dense_length_D:.0f} D) is set by the box, not selected by the flow; "
                        "compare boxes of different lengths")
    return warnings


#: an open pipe whose grain content changes by more than this share over the measured part is still filling or
#: emptying: the start-up has not left it
SETTLED_SHARE = 0.02


def _start_up_left(res: SimulationResult, t_from_tc: float) -> list[str]:
    """A warning when an open pipe's grain content still changes over the part of the run measured as a movie:
    the column it started with, draining or filling to the feed, is then what the fronts measured may be."""
    j = int(np.searchsorted(res.time, t_from_tc))
    start, end = float(res.grain_total[min(j, len(res.time) - 1)]), float(res.grain_total[-1])
    change = abs(end - start) / max(abs(start), 1e-300)
    if change <= SETTLED_SHARE:
        return []
    return [f"the pipe's grain content still changes by {100 * change:.0f} % over the part of the run measured "
            f"(from {t_from_tc:g} t_c): the start-up, the column it began with draining or filling to the feed, "
            "has not left the pipe, and the fronts and celerity measured may be that transient — run longer"]


def _balance_caveats(p: ModelParams, params: SimulationParams) -> list[str]:
    """What the run did with the base state's imbalance (the set-up's caveat says the linear analysis drops it)."""
    S = p.base_state_residual
    if abs(S) <= 1e-9:
        return []
    weight = p.c0 * math.cos(math.radians(p.theta_deg))
    if params.balanced:
        return [f"this run adds a uniform force S = {S:+.3f} rho_s g ({100 * abs(S) / weight:.0f} % of the grains' "
                "weight) so that the base state is steady, as the linear analysis assumes; without it (balance "
                "off) the base flow is not steady"]
    return [f"no balancing force in this run: the base flow is not steady (friction minus weight {S:+.3f} rho_s g)"]


#: the compactness amplitude below which unstable waves are said not to have grown yet
GROWN_AMPLITUDE = 0.01


def _not_grown(rate: float, duration_tc: float, noise: float) -> str:
    """The warning for a run too short (or too quiet) for its unstable waves to show."""
    gain = math.exp(min(rate * duration_tc, 700.0))
    head = (f"the unstable waves have not had time to grow: the fastest grows by e^(σT) = {gain:.3g} in "
            f"{duration_tc:g} t_c (σ = {rate:.3g}/t_c)")
    if noise > 0:
        need = math.log(GROWN_AMPLITUDE / noise) / rate
        return (f"{head}, from noise {noise:g} to about {noise * gain:.2g} in compactness: the flow only looks "
                f"uniform; run longer (about duration_tc={math.ceil(need)} to reach {GROWN_AMPLITUDE:g}) or start "
                "from more noise (noise=)")
    return f"{head}, and the run started without noise: give noise= (and a long enough duration_tc=)"
