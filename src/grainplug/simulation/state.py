"""What a simulation is: how to run it (:class:`SimulationParams`) and the fields it gives
(:class:`SimulationResult`), with the constants the measures of the fields share.

Notes
-----
The data layer of :mod:`grainplug.simulation`, after pyclaw's split of state, solver and
controller: it imports nothing of the time loop (:mod:`.run`), the measures of the fields
(:mod:`.waves`, :mod:`.measure`, :mod:`.validation`) or the study that runs and measures
(:mod:`.study`); they all import it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import ParameterError
from ..stability.params import ModelParams

__all__ = ["BOUNDARIES", "ENGINES", "INLET_CELLS", "MIN_WAVE_RANGE_C", "RANDOM_CLOSE_PACKING", "SimulationParams",
           "SimulationResult"]

#: random close packing of monodisperse spheres: compactness above it is unphysical
RANDOM_CLOSE_PACKING = 0.64
BOUNDARIES = ("periodic", "open")
ENGINES = ("numba", "numpy")

#: the least range of compactness (max - min at the end) called waves: below it the field is the base flow
#: with small, still linear ripples (a 0.002 ripple of a 1e-7 noise was reported as 23 D dense segments)
MIN_WAVE_RANGE_C = 0.01
#: an open pipe's dense run of at most this many cells at the inlet is the fed cell, not a wave
INLET_CELLS = 2



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
    dt_floor_tc : float
        The shortest time step allowed, in ``t_c``: a run whose Courant-limited step falls below it
        stops with a one-line message naming the cell and the wave that limit it (a nearly emptied
        cell, where the air's compressibility acts on almost no grain, or grains packed near close
        packing, where the jamming pressure stiffens): the model has left its validity there, and
        going on would take hours.
    inlet_seal_D : float, optional
        Open pipe: the air enters the top only through a column of this many ``D`` of the fed grains (a hopper
        full of grains), in series with the pipe, the atmosphere beyond it; its resistance is ``H / K(feed_c)``.
        None (default): the air pressure is held at the base pressure at the top face.
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
    dt_floor_tc: float = 1e-5
    inlet_seal_D: float | None = None

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
            (math.isfinite(self.dt_floor_tc) and 0 <= self.dt_floor_tc < self.output_interval_tc,
             "dt_floor_tc must be at least 0 and below the output interval"),
            (self.feed_rate_g_s is None or (math.isfinite(self.feed_rate_g_s) and self.feed_rate_g_s > 0),
             "the feed rate must be positive (g/s)"),
            (self.feed_rate_g_s is None or self.feed_v is None, "give the feed velocity or the feed rate, not both"),
            (self.inlet_seal_D is None or (math.isfinite(self.inlet_seal_D) and 0 <= self.inlet_seal_D <= 1e6),
             "inlet_seal_D (the hopper's grain column the air crosses, in D) must be between 0 and 1e6"),
            (self.boundary == "open" or self.inlet_seal_D is None, "inlet_seal_D applies to the open pipe only"),
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
