"""Run a simulation: initial state, time loop, outputs and the checks a user needs.

Notes
-----
:func:`simulate` integrates the conservative 1D model (:mod:`.equations`) with the
finite-volume scheme of :mod:`.scheme` and returns a :class:`SimulationResult` of
fields on the grid at regular output times, with its checks: grain and air mass
drift (periodic box), compactness above random close packing, cells emptied, and
coarsening (the number of dense segments still changing at the end of the run).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import ParameterError
from ..stability.params import ModelParams
from .equations import C_FLOOR, Closure
from .scheme import Boundary, Integrator

log = logging.getLogger(__name__)

#: random close packing of monodisperse spheres: compactness above it is unphysical
RANDOM_CLOSE_PACKING = 0.64
#: relative drift of a conserved total that is reported
DRIFT_WARN = 1e-10
#: an air mass below minus this (units of the base state's) is reported
AIR_NEGATIVE = 1e-9
BOUNDARIES = ("periodic", "open")
ENGINES = ("numba", "numpy")


@dataclass(frozen=True)
class SimulationParams:
    """How to run a simulation (lengths in pipe diameters ``D``, times in ``t_c``).

    Attributes
    ----------
    boundary : str
        ``"periodic"`` (a box that repeats) or ``"open"`` (a pipe fed at the top).
    length_D : float
        Box or pipe length.
    n_cells : int
        Number of finite-volume cells.
    duration_tc : float
        Simulated time.
    output_interval_tc : float
        Time between saved fields.
    cfl : float
        Courant number of each stage of the explicit fluxes (at most 0.5); a time step is
        ``SSP_STAGES - 1`` such stages long (:mod:`grainplug.simulation.scheme`).
    noise : float
        Standard deviation of the initial compactness perturbation (white noise, zero
        mean: the grain content is exactly ``c0`` times the box).
    balance : bool, optional
        Add the uniform force that makes the base state steady (see
        :class:`~grainplug.simulation.equations.Closure`). Default: on in a periodic box
        (as the linear analysis assumes), off in an open pipe.
    feed_c : float, optional
        Open pipe: compactness of the grains fed at the top (default ``c0``).
    feed_v : float, optional
        Open pipe: their velocity in units of ``v_c`` (default: the base velocity, or
        the one that carries ``feed_rate_g_s``).
    feed_rate_g_s : float, optional
        Open pipe: the grains' mass flow rate fed at the top, g/s (the paper's runs:
        0.25-1.05 g/s); sets ``feed_v = rate / (rho_s A feed_c)`` with ``A = pi D^2 / 4``.
    engine : str
        ``"numba"`` (compiled, the default) or ``"numpy"`` (the readable reference,
        6.5 times slower on 2048 cells); they agree to round-off.
    """

    boundary: str = "periodic"
    length_D: float = 251.0
    n_cells: int = 1024
    duration_tc: float = 600.0
    output_interval_tc: float = 0.5
    cfl: float = 0.4
    noise: float = 1e-9
    balance: bool | None = None
    feed_c: float | None = None
    feed_v: float | None = None
    feed_rate_g_s: float | None = None
    engine: str = "numba"

    def __post_init__(self) -> None:
        checks = [
            (self.boundary in BOUNDARIES, f"boundary must be one of {', '.join(BOUNDARIES)}"),
            (math.isfinite(self.length_D) and self.length_D > 0, "the length must be positive (in D)"),
            (16 <= self.n_cells <= 1_000_000, "n_cells must be between 16 and 1e6"),
            (math.isfinite(self.duration_tc) and self.duration_tc > 0, "the duration must be positive (in t_c)"),
            (math.isfinite(self.output_interval_tc) and 0 < self.output_interval_tc <= self.duration_tc,
             "the output interval must be positive and at most the duration"),
            (0 < self.cfl <= 0.5, "cfl must be in (0, 0.5]"),
            (math.isfinite(self.noise) and 0 <= self.noise < 0.1, "noise must be in [0, 0.1)"),
            (self.feed_c is None or 0 < self.feed_c < 1, "the feed compactness must be in (0, 1)"),
            (self.feed_v is None or (math.isfinite(self.feed_v) and self.feed_v > 0),
             "the feed velocity must be positive (downward)"),
            (self.engine in ENGINES, f"engine must be one of {', '.join(ENGINES)}"),
            (self.feed_rate_g_s is None or (math.isfinite(self.feed_rate_g_s) and self.feed_rate_g_s > 0),
             "the feed rate must be positive (g/s)"),
            (self.feed_rate_g_s is None or self.feed_v is None, "give the feed velocity or the feed rate, not both"),
            (self.boundary == "open" or (self.feed_c is None and self.feed_v is None and self.feed_rate_g_s is None),
             "the feed (compactness, velocity, rate) applies to the open pipe only (boundary=\"open\")"),
        ]
        for ok, msg in checks:
            if not ok:
                raise ParameterError(msg)

    @property
    def dx(self) -> float:
        return self.length_D / self.n_cells

    @property
    def balanced(self) -> bool:
        return self.boundary == "periodic" if self.balance is None else self.balance

    def replace(self, **kw: object) -> SimulationParams:
        return dataclasses.replace(self, **kw)


@dataclass(frozen=True)
class SimulationResult:
    """Fields of one simulation at the output times, dimensionless.

    Attributes
    ----------
    model, params : ModelParams, SimulationParams
    z : ndarray, shape (n_cells,)
        Cell centres, units of ``D``, increasing downward (with the flow).
    time : ndarray, shape (n_out,)
        Output times, units of ``t_c`` (the first is 0, the initial state).
    c, v, P : ndarray, shape (n_out, n_cells)
        Compactness, grain velocity (``v_c``, positive downward) and absolute air
        pressure (``P_c``).
    grain_total, air_total : ndarray, shape (n_out,)
        ``sum(c) dx`` and ``sum(m) dx`` (grain and air content per pipe section).
    grain_inflow, grain_outflow : ndarray, shape (n_out,)
        The grain that entered through the top face and left through the bottom face of an
        open pipe since the start, in the units of ``grain_total`` (zeros in a periodic box).
        ``grain_total - grain_total[0] = grain_inflow - grain_outflow`` to round-off while
        no cell's compactness was clipped to ``[0, 1)``: the open pipe's conservation check.
    n_steps : int
    wall_s : float
    warnings : tuple of str
    """

    model: ModelParams
    params: SimulationParams
    z: np.ndarray
    time: np.ndarray
    c: np.ndarray
    v: np.ndarray
    P: np.ndarray
    grain_total: np.ndarray
    air_total: np.ndarray
    n_steps: int
    wall_s: float
    warnings: tuple[str, ...] = field(default=())
    grain_inflow: np.ndarray | None = None
    grain_outflow: np.ndarray | None = None

    @property
    def grain_drift(self) -> float:
        """Relative change of the grain content over the run (periodic: round-off)."""
        return float(abs(self.grain_total[-1] - self.grain_total[0]) / abs(self.grain_total[0]))

    @property
    def grain_budget_residual(self) -> float:
        """Relative change of the grain content over the run not accounted for by what crossed the ends:
        round-off in a periodic box and in an open pipe alike (:attr:`grain_drift` in a periodic box)."""
        inflow = 0.0 if self.grain_inflow is None else float(self.grain_inflow[-1])
        outflow = 0.0 if self.grain_outflow is None else float(self.grain_outflow[-1])
        change = float(self.grain_total[-1] - self.grain_total[0])
        return abs(change - (inflow - outflow)) / abs(float(self.grain_total[0]))

    @property
    def air_drift(self) -> float:
        """Relative change of the air content over the run."""
        return float(abs(self.air_total[-1] - self.air_total[0]) / abs(self.air_total[0]))

    def __repr__(self) -> str:
        p = self.params
        return (f"<SimulationResult {p.boundary} L={p.length_D:g} D, {p.n_cells} cells, t={self.time[-1]:g} t_c, "
                f"{len(self.time)} outputs, c in [{self.c.min():.3f}, {self.c.max():.3f}], "
                f"{len(self.warnings)} warnings>")


def feed_velocity(model: ModelParams, rate_g_s: float, feed_c: float) -> float:
    """Velocity (units of ``v_c``) of grains at compactness ``feed_c`` carrying ``rate_g_s`` through the pipe."""
    area = math.pi * model.D_m**2 / 4
    return rate_g_s * 1e-3 / (model.grain_density_kg_m3 * area * feed_c) / model.v_c_m_s


def initial_state(closure: Closure, params: SimulationParams, rng: np.random.Generator) -> np.ndarray:
    """The uniform base state with zero-mean white noise of std ``params.noise`` on ``c``."""
    n = params.n_cells
    c = np.full(n, closure.c0)
    if params.noise > 0:
        e = rng.standard_normal(n)
        c = c + params.noise * (e - e.mean())
    return closure.conserved(c, np.full(n, closure.v0), np.full(n, closure.P0))


def simulate(model: ModelParams, params: SimulationParams | None = None, *, rng: np.random.Generator | None = None,
             initial: np.ndarray | None = None, progress: object = None) -> SimulationResult:
    """Integrate the nonlinear 1D model in time.

    Parameters
    ----------
    model : ModelParams
        The set-up (every switch of :class:`~grainplug.stability.ModelParams` applies).
    params : SimulationParams
    rng : numpy.random.Generator
        Source of the initial noise (default: a fresh generator seeded with 0).
    initial : ndarray, shape (3, n_cells), optional
        The conserved variables ``(c, c v, m)`` to start from, instead of the noisy base state.
    progress : callable, optional
        Called as ``progress(t, duration)`` at each output.

    Returns
    -------
    SimulationResult
    """
    params = params or SimulationParams()
    closure = Closure.from_params(model, balance=params.balanced)
    bc = Boundary()
    if params.boundary == "open":
        feed_c = model.c0 if params.feed_c is None else params.feed_c
        feed_v = closure.v0 if params.feed_v is None else params.feed_v
        if params.feed_rate_g_s is not None:
            feed_v = feed_velocity(model, params.feed_rate_g_s, feed_c)
        bc = Boundary("open", inlet_c=feed_c, inlet_v=feed_v, P_end=closure.P0)
    integ = Integrator(closure, params.n_cells, params.dx, bc)
    rng = rng if rng is not None else np.random.default_rng(0)
    U = initial_state(closure, params, rng) if initial is None else np.array(initial, dtype=float)
    if U.shape != (3, params.n_cells):
        raise ParameterError(f"the initial state must have shape (3, {params.n_cells})")
    if not np.isfinite(U).all() or U[0].min() < 0 or U[0].max() >= 1 or U[2].min() < 0:
        raise ParameterError("the initial state must be finite, with a compactness in [0, 1) and no negative "
                             "air mass")
    n_out = int(round(params.duration_tc / params.output_interval_tc)) + 1
    times = np.linspace(0.0, params.output_interval_tc * (n_out - 1), n_out)
    fields = np.empty((n_out, 3, params.n_cells))
    totals = np.empty((n_out, 2))
    fields[0] = np.stack(closure.primitive(U))
    totals[0] = U[0].sum() * params.dx, U[2].sum() * params.dx
    t, steps, t0 = 0.0, 0, time.perf_counter()
    c_peak = float(U[0].max())
    m_low = float(U[2].min())
    budget = np.zeros(2)  # the grain in through the top and out through the bottom so far (open pipe)
    if params.engine == "numba":
        from . import _kernel

        consts = _kernel.pack(closure, bc.kind, integ.inlet, bc.P_end, params.dx)

        def advance(U: np.ndarray, t: float, t_end: float) -> tuple[np.ndarray, float, int]:
            return _kernel.advance(U, t, t_end, params.cfl, consts, budget)
    else:
        def advance(U: np.ndarray, t: float, t_end: float) -> tuple[np.ndarray, float, int]:
            return integ.advance(U, t, t_end, params.cfl, budget)
    crossed = np.zeros((n_out, 2))
    for j in range(1, n_out):
        U, t, n = advance(U, t, float(times[j]))
        if n < 0 or not np.isfinite(U).all():
            raise ParameterError(f"the simulation blew up at t = {t:.3g} t_c (a non-finite state): "
                                 "try more cells or a smaller cfl=")
        steps += n
        fields[j] = np.stack(closure.primitive(U))
        totals[j] = U[0].sum() * params.dx, U[2].sum() * params.dx
        crossed[j] = budget
        c_peak = max(c_peak, float(U[0].max()))
        m_low = min(m_low, float(U[2].min()))
        if callable(progress):
            progress(t, params.duration_tc)
    wall = time.perf_counter() - t0
    res = SimulationResult(model=model, params=params, z=(np.arange(params.n_cells) + 0.5) * params.dx,
                           time=times, c=fields[:, 0], v=fields[:, 1], P=fields[:, 2], grain_total=totals[:, 0],
                           air_total=totals[:, 1], n_steps=steps, wall_s=wall, grain_inflow=crossed[:, 0],
                           grain_outflow=crossed[:, 1])
    log.info("simulated %g t_c in %d steps, %.1f s", params.duration_tc, steps, wall)
    return dataclasses.replace(res, warnings=tuple(_checks(res, closure, c_peak, m_low)))


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


def _checks(res: SimulationResult, closure: Closure, c_peak: float, m_low: float) -> list[str]:
    out = []
    if m_low < -AIR_NEGATIVE:
        out.append(f"the air mass went negative ({m_low:.3g}) in a saved state: the state left the model "
                   "(emptied cells, or a step too long); use more cells or a smaller cfl=")
    p = res.params
    if p.boundary == "periodic":
        for name, drift in (("grain", res.grain_drift), ("air", res.air_drift)):
            if drift > DRIFT_WARN:
                out.append(f"{name} mass drifted by {drift:.2g} (relative) in a periodic box: the scheme should "
                           "conserve it to round-off; report this with the parameters")
    elif res.grain_budget_residual > DRIFT_WARN:
        out.append(f"the grain content changed by {res.grain_budget_residual:.2g} (relative) more than the grain that "
                   "crossed the ends: the scheme should conserve it to round-off (a compactness clipped to [0, 1)?); "
                   "report this with the parameters")
    if c_peak > RANDOM_CLOSE_PACKING:
        fix = ("add jamming=True to cap it" if not res.model.jamming else
               "the jamming pressure did not hold it: use more cells")
        out.append(f"the compactness reached {c_peak:.3f}, above random close packing ({RANDOM_CLOSE_PACKING}): "
                   f"the model lets grains pack tighter than spheres can; {fix}")
    if np.any(res.c[-1] <= C_FLOOR * 10):
        out.append("some cells emptied completely: the model is written for a compact flow and does not describe "
                   "free-falling grains there")
    if closure.law == "coulomb-weight":
        out.append("Coulomb friction following the local weight has no short-wave cut-off (growth 0.35/t_c as k -> "
                   "infinity): its simulation picks the grid scale, and changes with the number of cells")
    if closure.law == "v2":
        out.append("the simulation gives the printed v^2 friction the sign of the velocity (v|v|), so that friction "
                   "never pushes grains; identical while grains fall")
    stopped = float(np.mean(np.abs(res.v[-1]) < 1e-3 * max(abs(closure.v0), 1e-9)))
    if stopped >= 0.1:
        place = "box" if p.boundary == "periodic" else "pipe"
        where = f"the whole {place}" if stopped == 1.0 else f"{stopped:.0%} of the {place}"
        out.append(f"the grains stopped over {where}: the wall friction holds them against their weight (a jammed "
                   "column is the model's answer for this set-up)")
    n_seg = segment_counts(res)
    if p.boundary == "periodic" and len(n_seg) >= 8 and n_seg[-1] > 0:
        tail = n_seg[-max(len(n_seg) // 5, 2):]
        if tail.max() != tail.min():
            out.append(f"still coarsening: the number of dense segments changed from {tail.max()} to {tail.min()} "
                       "over the last fifth of the run; its wavelengths are not settled (run longer)")
    return out


#: the least range of compactness (max - min at the end) called waves: below it the field is the base flow
#: with small, still linear ripples (a 0.002 ripple of a 1e-7 noise was reported as 23 D dense segments)
MIN_WAVE_RANGE_C = 0.01
#: an open pipe's dense run of at most this many cells at the inlet is the fed cell, not a wave
INLET_CELLS = 2


def segment_counts(res: SimulationResult, *, threshold: float | None = None) -> np.ndarray:
    """Number of dense segments (``c`` above ``threshold``, default halfway between min and max) at each output;
    none while the final range is under :data:`MIN_WAVE_RANGE_C`, and not an open pipe's fed inlet cells alone
    (:data:`INLET_CELLS`), as :func:`~grainplug.simulation.waves.wave_state` counts them."""
    c = res.c
    lo, hi = float(c[-1].min()), float(c[-1].max())
    if hi - lo < MIN_WAVE_RANGE_C:
        return np.zeros(len(c), int)
    thr = 0.5 * (lo + hi) if threshold is None else threshold
    dense = c > thr
    if res.params.boundary == "periodic":
        starts = dense & ~np.roll(dense, 1, axis=1)
    else:
        starts = dense & ~np.concatenate([np.zeros((len(c), 1), bool), dense[:, :-1]], axis=1)
        starts[:, 0] &= dense[:, : INLET_CELLS + 1].all(axis=1)  # the fed cells alone are no segment
    return starts.sum(axis=1)


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


def simulate_and_measure(model: ModelParams, params: SimulationParams | None = None, *,
                         rng: np.random.Generator | None = None,
                         progress: object = None) -> tuple[SimulationResult, dict[str, object]]:
    """:func:`simulate`, then the waves on the fields, the diagram measured as a movie's and the linear
    prediction, as one JSON-ready summary (with the version, the set-up and the run's parameters)."""
    from .._version import __version__
    from ..stability import analyze_stability
    from .measure import measure
    from .waves import wave_state

    res = simulate(model, params, rng=rng, progress=progress)
    p = res.model
    lin = analyze_stability(p, k_min=1e-3, k_max=3.0, n_k=1000)
    mu = lin.most_unstable
    waves = wave_state(res)
    seen = measure(res)
    warnings = list(res.warnings)
    if mu is not None and mu.growth_rate > 0 and not waves.n_waves and res.params.boundary == "periodic":
        warnings.append(_not_grown(mu.growth_rate, res.params.duration_tc, res.params.noise))
    if res.params.boundary == "open":
        warnings.extend(_start_up_left(res, seen.t_from_tc))
    if waves.n_waves and res.params.boundary == "periodic" and waves.n_waves == 1:
        warnings.append(f"one wave fills the box ({res.params.length_D:g} D): the dense-segment length "
                        f"({waves.dense_length_D:.0f} D) is set by the box, not selected by the flow; "
                        "compare boxes of different lengths")
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
        "warnings": warnings,
    }
    return res, summary
