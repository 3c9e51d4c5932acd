"""Run a simulation: initial state, time loop and the checks a user needs.

Notes
-----
:func:`simulate` integrates the conservative 1D model (:mod:`.equations`) with the
finite-volume scheme of :mod:`.scheme` and returns a :class:`SimulationResult` of
fields on the grid at regular output times, with its checks: grain and air mass
drift (periodic box), compactness above random close packing, cells emptied, and
coarsening (the number of dense segments still changing at the end of the run).

The time loop of :mod:`grainplug.simulation`: it imports the data (:mod:`.state`), the
scheme and the dense-segment count of :mod:`.waves`; the study that measures a run
(:mod:`.study`, :func:`~grainplug.simulation.study.simulate_and_measure`) imports it.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time

import numpy as np

from ..errors import ParameterError
from ..stability.params import ModelParams
from .equations import C_FLOOR, Closure
from .scheme import Boundary, Integrator
from .state import (  # the data's names, imported from here before the split, still are
    BOUNDARIES,
    ENGINES,
    INLET_CELLS,
    MIN_WAVE_RANGE_C,
    RANDOM_CLOSE_PACKING,
    SimulationParams,
    SimulationResult,
)
from .waves import segment_counts

log = logging.getLogger(__name__)

__all__ = ["AIR_NEGATIVE", "BOUNDARIES", "DRIFT_WARN", "ENGINES", "INLET_CELLS", "MIN_WAVE_RANGE_C",
           "RANDOM_CLOSE_PACKING", "SimulationParams", "SimulationResult", "feed_velocity", "initial_state",
           "segment_counts", "simulate"]

#: relative drift of a conserved total that is reported
DRIFT_WARN = 1e-10
#: an air mass below minus this (units of the base state's) is reported
AIR_NEGATIVE = 1e-9


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


#: bytes a saved state costs per cell: 3 fields of float64, kept, then copied once to be written (fields.nc)
SAVED_BYTES_PER_CELL = 3 * 8 * 2
#: the share of the free memory a simulation's saved fields may take
MEMORY_SHARE = 0.8
#: the longest simulation started unasked, seconds (``max_seconds=None`` lifts it)
MAX_SECONDS = 3600.0
#: a simulation's duration is estimated once its time steps (the compiled kernel built) ran this long, seconds
ESTIMATE_AFTER_S = 2.0


def check_simulation_size(params: SimulationParams) -> None:
    """Refuse, before anything is allocated, a simulation whose saved fields would not fit in the free memory.

    Raises
    ------
    ParameterError
        Naming the memory it would need (``n_outputs x n_cells x 3 fields x 8 bytes``, and a copy to write
        them) and the fix.
    """
    from .._system import free_memory_bytes

    n_out = math.floor(params.duration_tc / params.output_interval_tc + 0.5) + 1
    need = float(n_out) * params.n_cells * SAVED_BYTES_PER_CELL
    free = free_memory_bytes()
    if need > MEMORY_SHARE * free:
        raise ParameterError(f"{n_out:,} saved states of {params.n_cells:,} cells would take about "
                             f"{need / 2**30:.3g} GiB, more than the {free / 2**30:.3g} GiB free — give fewer "
                             "n_cells=, a shorter duration_tc= or a longer output_interval_tc=")


def _check_time(elapsed: float, done_tc: float, left_tc: float, max_seconds: float | None) -> None:
    """Refuse a simulation that the pace of its time steps so far says would run longer than ``max_seconds``."""
    if max_seconds is None or done_tc <= 0:
        return
    estimate = elapsed / done_tc * left_tc
    log.info("simulation: about %.0f s more", estimate)
    if estimate > max_seconds:
        raise ParameterError(f"the simulation would take about {estimate / 3600:.3g} h more ({elapsed:.1f} s for "
                             f"its first {done_tc:.3g} t_c), over the limit of {max_seconds / 3600:g} h — give fewer "
                             "n_cells= or a shorter duration_tc= (in Python, max_seconds=None lifts the limit)")


def simulate(model: ModelParams, params: SimulationParams | None = None, *, rng: np.random.Generator | None = None,
             initial: np.ndarray | None = None, progress: object = None,
             max_seconds: float | None = MAX_SECONDS) -> SimulationResult:
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
    max_seconds : float or None
        Refuse a run that the pace of its first seconds of time steps says would take longer (None: no limit).

    Returns
    -------
    SimulationResult

    Raises
    ------
    ParameterError
        Before anything is allocated, saved fields that would not fit in the free memory
        (:func:`check_simulation_size`); after its first seconds, a run estimated longer than ``max_seconds``.
    """
    params = params or SimulationParams()
    check_simulation_size(params)
    closure = Closure.from_params(model, balance=params.balanced)
    bc = Boundary()
    if params.boundary == "open":
        feed_c = model.c0 if params.feed_c is None else params.feed_c
        feed_v = closure.v0 if params.feed_v is None else params.feed_v
        if params.feed_rate_g_s is not None:
            feed_v = feed_velocity(model, params.feed_rate_g_s, feed_c)
        seal = 0.0
        if params.inlet_seal_D:  # the air enters through a column of the fed grains (a hopper), at P_end beyond it
            rk = float(closure.permeability(np.array([feed_c]))[0])  # r = 1 at P_end = P0
            seal = params.inlet_seal_D / rk
        bc = Boundary("open", inlet_c=feed_c, inlet_v=feed_v, P_end=closure.P0, inlet_seal=seal)
    if params.boundary == "open" and model.jamming and bc.inlet_c >= model.jamming_c_max:
        raise ParameterError(f"the feed compactness {bc.inlet_c:g} is at or above close packing "
                             f"(jamming_c_max = {model.jamming_c_max:g}): no grain can be fed that dense")
    integ = Integrator(closure, params.n_cells, params.dx, bc, dt_floor=params.dt_floor_tc)
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

        consts = _kernel.pack(closure, bc.kind, integ.inlet, bc.P_end, params.dx, params.dt_floor_tc, bc.inlet_seal)

        def advance(U: np.ndarray, t: float, t_end: float) -> tuple[np.ndarray, float, int]:
            return _kernel.advance(U, t, t_end, params.cfl, consts, budget)
    else:
        def advance(U: np.ndarray, t: float, t_end: float) -> tuple[np.ndarray, float, int]:
            return integ.advance(U, t, t_end, params.cfl, budget)
    crossed = np.zeros((n_out, 2))
    paced: tuple[float, float] | None = None  # (clock, t) once the first output is done (the kernel built)
    for j in range(1, n_out):
        U, t, n = advance(U, t, float(times[j]))
        if paced is None:
            paced = (time.perf_counter(), t)
        elif paced[0] > 0 and time.perf_counter() - paced[0] >= ESTIMATE_AFTER_S:
            _check_time(time.perf_counter() - paced[0], t - paced[1], params.duration_tc - t, max_seconds)
            paced = (-1.0, 0.0)  # estimated once
        if not np.isfinite(U).all():
            raise ParameterError(f"the simulation blew up at t = {t:.3g} t_c (a non-finite state): "
                                 "try more cells or a smaller cfl=")
        if n < 0:
            _check_validity(U, closure, params, t)  # grains packed to c = 1 stall the step too: say that first
            raise ParameterError(_time_step_collapse(U, closure, params, t))
        _check_validity(U, closure, params, t)
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


#: a compactness this close to 1 was clipped by the scheme: the run left the model
C_CLIPPED = 1.0 - 1e-6


def _where(params: SimulationParams, i: int, t: float) -> str:
    return f"at t = {t:.4g} t_c, z = {(i + 0.5) * params.dx:.3g} D (cell {i})"


def _check_validity(U: np.ndarray, closure: Closure, params: SimulationParams, t: float) -> None:
    """Stop, in one line, a run whose state left the model: a compactness reaching 1 (clipped by the scheme,
    so no longer conserved) or a negative air mass."""
    i = int(np.argmax(U[0]))
    if U[0, i] >= C_CLIPPED:
        raise ParameterError(f"the compactness reached 1 {_where(params, i, t)}: the grains overlap, the model "
                             "no longer holds (use jamming=True, which caps it below close packing)")
    i = int(np.argmin(U[2]))
    if U[2, i] < -AIR_NEGATIVE:
        raise ParameterError(f"the air mass went negative ({U[2, i]:.3g}) {_where(params, i, t)}: the state left "
                             "the model (use more cells or a smaller cfl=)")


def _time_step_collapse(U: np.ndarray, closure: Closure, params: SimulationParams, t: float) -> str:
    """The one-line message of a run stopped because its time step fell below ``params.dt_floor_tc``: the cell
    whose waves limit it and which term of their speed (air or jamming) makes them fast."""
    c, v, P = closure.primitive(U)
    lo, hi = closure.speeds(c, v, P)
    s = np.maximum(np.abs(lo), np.abs(hi))
    i = int(np.argmax(s))
    cs = max(float(c[i]), C_FLOOR)
    air = closure.gamma * float(P[i]) / (cs * (1 - float(c[i])))
    jam = float(closure.jamming_slope(c[i:i + 1])[0])
    if air < jam:
        why = "the jamming pressure's stiffness (grains packed near close packing)"
    elif float(c[i]) > 0.5:
        why = "the air's compressibility in a cell packed almost solid (its air squeezed out: 1 - c is nearly 0)"
    else:
        why = ("the air's compressibility acting on almost no grain (a nearly emptied cell: the model has no air "
               "inertia, so its waves there are unbounded)")
    return (f"the time step fell below dt_floor_tc = {params.dt_floor_tc:g} t_c {_where(params, i, t)}, "
            f"c = {float(c[i]):.4g}: its waves travel at {float(s[i]):.3g} v_c, from {why}; the run left the "
            "model's validity")


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
            out.append(f"still coarsening: the number of dense segments changed from {tail[0]} to {tail[-1]} "
                       f"(between {tail.min()} and {tail.max()}) over the last fifth of the run; its wavelengths are "
                       "not settled (run longer)")
    return out
