"""The nonlinear 1D model in time, checked against independent computations.

- sympy: the conservative equations, linearised, have the stability matrix's roots;
- the simulation's linear phase: growth rates and frequencies of the Fourier modes
  within 1 % of the linear theory for k* = 0.05 .. 0.5, for two unstable variants;
- grain and air mass conserved to round-off through compaction fronts;
- second-order convergence on a smooth solution;
- a Riemann problem against a first-order scheme written here, on a fine grid;
- Coulomb friction never pushes grains upward; an open pipe fills at the fed flux.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import sympy as sp

from grainplug.errors import ParameterError
from grainplug.simulation import SimulationParams, SimulationResult, segment_counts, simulate
from grainplug.simulation.equations import Closure
from grainplug.simulation.measure import measure
from grainplug.simulation.scheme import Boundary, Integrator
from grainplug.simulation.validation import fit_modes
from grainplug.simulation.waves import wave_state
from grainplug.stability import ModelParams, roots

FROZEN = ModelParams(variant="frozen-friction")


# -- the equations, linearised by sympy ------------------------------------------------
def _conservative_roots(p: ModelParams, k: float) -> np.ndarray:
    """Roots omega of the sympy-linearised conservative system (c, q = c v, m = r (1 - c))."""
    c, v, P, w, kk = sp.symbols("c v P omega k")
    cl = Closure.from_params(p)
    gam, kap = sp.Float(p.gamma), sp.Float(p.kappa)
    r = (P / cl.P0) ** (1 / gam)
    U = sp.Matrix([c, c * v, r * (1 - c)])
    if p.jamming:
        pj = cl.jam_fr * (c - cl.jam_c_min) ** 2 / (cl.jam_c_max - c) ** 5
    else:
        pj = 0
    F = sp.Matrix([c * v, c * v**2 + v**2 / (2 * kap) + P + pj, r * (1 - c) * v])
    law = p.law
    fric = {"v2": cl.alpha * v**2, "v|v|": cl.alpha * v**2, "coulomb-frozen": cl.F0 + 0 * v,
            "coulomb-weight": cl.F0 * c / cl.c0}[law]
    S = sp.Matrix([0, c * cl.cos_theta + cl.balance_force - fric, 0])
    K = cl.K0 * ((1 - c) ** 3 / c**2) * (cl.c0**2 / (1 - cl.c0) ** 3)
    W = [c, v, P]
    base = {c: cl.c0, v: cl.v0, P: cl.P0}
    dU, dF, dS = (M.jacobian(W).subs(base) for M in (U, F, S))
    # air flux -r K P_z: linearised, -r0 K(c0) P~_z, so +k^2 r0 K(c0) P^ in the m equation
    Dm = sp.zeros(3, 3)
    Dm[2, 2] = (r * K).subs(base)
    M = -sp.I * w * dU + sp.I * kk * dF - dS + kk**2 * Dm
    poly = sp.Poly(sp.expand(M.det().subs(kk, k)), w)
    return np.sort_complex(np.roots([complex(a) for a in poly.all_coeffs()]))


@pytest.mark.parametrize("setup", [
    {}, {"variant": "frozen-friction"}, {"friction_law": "coulomb-weight"}, {"base_velocity": "balanced"},
    {"base_pressure_pa": 101325.0, "variant": "frozen-friction"}, {"variant": "frozen-friction", "jamming": True},
    {"theta_deg": 5.0, "friction_law": "v|v|"},
])
def test_conservative_equations_linearise_to_the_stability_matrix(setup):
    """The air-mass equation replaces the printed pressure equation without changing its linear limit."""
    p = ModelParams(**setup)
    for k in (0.07, 0.3, 1.1):
        got = _conservative_roots(p, k)
        want = np.sort_complex(roots(p, np.array([k]), track=False)[0])
        np.testing.assert_allclose(got, want, rtol=1e-8, atol=1e-10)


# -- the linear phase against the linear theory ---------------------------------------
@pytest.mark.parametrize(("setup", "n_cells"), [
    ({"variant": "frozen-friction"}, 512),
    ({"variant": "frozen-friction", "jamming": True}, 1024),
])
def test_growth_rates_match_linear_theory(setup, n_cells):
    """From small noise, each Fourier mode k* = 0.05 .. 0.5 grows and travels as the linear theory says (1 %)."""
    p = ModelParams(**setup)
    sim = SimulationParams(length_D=2 * np.pi / 0.05, n_cells=n_cells, duration_tc=40.0, output_interval_tc=0.25,
                           noise=1e-7)
    res = simulate(p, sim, rng=np.random.default_rng(1))
    fits = fit_modes(res, range(1, 11), t_from=40.0 / 3)
    assert [round(f.k, 3) for f in fits] == [round(0.05 * n, 3) for n in range(1, 11)]
    for f in fits:
        assert f.growth_linear > 0.04  # unstable modes: a growth rate worth measuring
        assert abs(f.growth_rel_error) < 0.01, (f.k, f.growth_sim, f.growth_linear)
        assert abs(f.frequency_rel_error) < 0.01, (f.k, f.omega_r_sim, f.omega_r_linear)
    assert res.c.max() - res.c.min() < 1e-2  # still linear when fitted


def test_a_stable_set_up_stays_uniform():
    """The printed set-up is linearly stable: noise decays, nothing grows in the box."""
    res = simulate(ModelParams(), SimulationParams(length_D=100.0, n_cells=128, duration_tc=60.0,
                                                   output_interval_tc=5.0, noise=1e-4),
                   rng=np.random.default_rng(2))
    spread = res.c.max(axis=1) - res.c.min(axis=1)
    assert spread[-1] < 0.5 * spread[0]


# -- conservation ---------------------------------------------------------------
def test_grain_and_air_mass_conserved_through_fronts():
    """A frozen-friction box steepens into fronts; both masses stay constant to round-off."""
    res = simulate(FROZEN, SimulationParams(length_D=100.0, n_cells=256, duration_tc=120.0, output_interval_tc=2.0,
                                            noise=1e-3), rng=np.random.default_rng(3))
    assert res.c.max() > 0.65  # compaction fronts formed
    assert res.grain_drift < 1e-12
    assert res.air_drift < 1e-12
    assert not any("drifted" in w for w in res.warnings)
    assert any("random close packing" in w for w in res.warnings)


# -- convergence ----------------------------------------------------------------
def _smooth_run(n: int) -> np.ndarray:
    p = ModelParams()
    L = 50.0
    z = (np.arange(n) + 0.5) * L / n
    cl = Closure.from_params(p)
    # a cell average of c0 + a sin(2 pi z / L), exactly
    h = L / n
    a = 0.01
    c = cl.c0 + a * np.sin(2 * np.pi * z / L) * math.sin(math.pi * h / L) / (math.pi * h / L)
    U0 = cl.conserved(c, np.full(n, cl.v0), np.full(n, cl.P0))
    res = simulate(p, SimulationParams(length_D=L, n_cells=n, duration_tc=8.0, output_interval_tc=8.0, noise=0.0,
                                       cfl=0.3), initial=U0)
    return res.c[-1]


def test_second_order_convergence_on_a_smooth_solution():
    """L1 errors against a 1024-cell solution fall by about 4 per halving of the cells."""
    ref = _smooth_run(1024)
    errs = []
    for n in (64, 128, 256):
        c = _smooth_run(n)
        coarse_ref = ref.reshape(n, -1).mean(axis=1)
        errs.append(np.mean(np.abs(c - coarse_ref)))
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(orders > 1.7), (errs, orders)


# -- a Riemann problem against an independent scheme ------------------------------------------------
def _rusanov_reference(n: int, t_end: float, left: tuple, right: tuple, p: ModelParams) -> np.ndarray:
    """A first-order Rusanov scheme for the same equations, written from the docs, without friction or diffusion."""
    L = 40.0
    dx = L / n
    z = (np.arange(n) + 0.5) * dx
    gam, kap, P0 = p.gamma, p.kappa, p.P0_star
    c = np.where(z < L / 2, left[0], right[0])
    v = np.where(z < L / 2, left[1], right[1])
    P = np.where(z < L / 2, left[2], right[2])
    U = np.stack([c, c * v, (P / P0) ** (1 / gam) * (1 - c)])

    def prim(U):
        c = U[0]
        v = U[1] / c
        P = P0 * (U[2] / (1 - c)) ** gam
        return c, v, P

    def flux(U):
        c, v, P = prim(U)
        return np.stack([c * v, c * v * v + v * v / (2 * kap) + P, U[2] * v])

    def speed(U):
        c, v, P = prim(U)
        b = v / (kap * c)
        return np.abs(v) + 0.5 * (np.abs(b) + np.sqrt(b * b + 4 * gam * P / (c * (1 - c))))

    t = 0.0
    while t < t_end:
        Ue = np.concatenate([U[:, :1], U, U[:, -1:]], axis=1)  # outflow ends
        a = np.maximum(speed(Ue[:, :-1]), speed(Ue[:, 1:]))
        dt = min(0.45 * dx / a.max(), t_end - t)
        Fe = flux(Ue)
        H = 0.5 * (Fe[:, :-1] + Fe[:, 1:]) - 0.5 * a * (Ue[:, 1:] - Ue[:, :-1])
        U = U - dt / dx * (H[:, 1:] - H[:, :-1])
        U[1] += dt * U[0] * math.cos(math.radians(p.theta_deg))
        t += dt
    return prim(U)[0]


def test_riemann_problem_of_the_grain_phase_matches_an_independent_scheme():
    """A dense plug's edge (a jump of c, no friction or air diffusion) against a fine first-order Rusanov scheme.

    The reference smears the contact over ~0.2 D (first order), so it is a reference for grids
    of 100-200 cells over 40 D only; there the difference falls by more than half per refinement.
    """
    p = ModelParams(mu_s=0.0, B1_star_override=0.0)
    left, right = (0.58, 1.0, 1.0), (0.50, 1.0, 1.0)
    ref = _rusanov_reference(8000, 2.0, left, right, p)
    cl = Closure.from_params(p, balance=False)
    errs = []
    for n in (100, 200):
        dx = 40.0 / n
        z = (np.arange(n) + 0.5) * dx
        U = cl.conserved(np.where(z < 20, left[0], right[0]), np.where(z < 20, left[1], right[1]),
                         np.where(z < 20, left[2], right[2]))
        integ = Integrator(cl, n, dx, Boundary("outflow"))
        t = 0.0
        while t < 2.0 - 1e-12:
            dt = min(0.4 * dx / integ.max_speed(U), 2.0 - t)
            U = integ.step(U, dt)
            t += dt
        errs.append(np.mean(np.abs(U[0] - ref.reshape(n, -1).mean(axis=1))))
    assert errs[1] < 0.5 * errs[0], errs
    assert errs[1] < 1e-4, errs
    assert ref.max() - ref.min() > 0.05  # a real wave pattern, not a trivial state


# -- the compiled step is the reference step --------------------------------------------------
@pytest.mark.parametrize(("setup", "kind"), [
    ({"variant": "frozen-friction"}, "periodic"),
    ({"friction_law": "coulomb-weight", "jamming": True}, "periodic"),
    ({"friction_law": "v|v|", "base_pressure_pa": 101325.0}, "open"),
    ({}, "outflow"),
])
def test_compiled_step_equals_the_numpy_reference(setup, kind):
    """On random states (stopped cells included), one step of the numba kernel equals the NumPy step."""
    from grainplug.simulation import _kernel

    rng = np.random.default_rng(7)
    cl = Closure.from_params(ModelParams(**setup))
    n, dx = 64, 0.3
    bc = Boundary(kind, inlet_c=0.5, inlet_v=0.9, P_end=cl.P0) if kind != "periodic" else Boundary()
    integ = Integrator(cl, n, dx, bc)
    consts = _kernel.pack(cl, bc.kind, integ.inlet, bc.P_end, dx)
    for _ in range(3):
        c = np.clip(0.55 + 0.05 * rng.standard_normal(n), 0.3, 0.63)
        v = 0.8 + 0.5 * rng.standard_normal(n)
        v[::7] = 0.0
        U = cl.conserved(c, v, cl.P0 * (1 + 0.1 * rng.standard_normal(n)))
        assert _kernel.max_speed(U, consts) == pytest.approx(integ.max_speed(U), rel=1e-13)
        dt = 0.4 * dx / integ.max_speed(U)
        np.testing.assert_allclose(_kernel.step(U, dt, consts), integ.step(U, dt), rtol=1e-11, atol=1e-14)


def test_engines_give_the_same_run():
    sim = SimulationParams(length_D=60.0, n_cells=64, duration_tc=20.0, output_interval_tc=5.0, noise=1e-3)
    a = simulate(FROZEN, sim, rng=np.random.default_rng(1))
    b = simulate(FROZEN, sim.replace(engine="numpy"), rng=np.random.default_rng(1))
    assert a.n_steps == b.n_steps
    np.testing.assert_allclose(a.c, b.c, rtol=1e-10)


@pytest.mark.parametrize(("setup", "boundary"), [
    ({"variant": "frozen-friction", "jamming": True}, "open"),
    ({"friction_law": "v|v|"}, "open"),
    ({"friction_law": "coulomb-weight", "jamming": True}, "periodic"),
])
def test_engines_give_the_same_run_with_every_boundary_and_law(setup, boundary):
    """The merged diffusion half-steps, the inlet and the outflow through whole runs, both engines."""
    sim = SimulationParams(boundary=boundary, length_D=40.0, n_cells=48, duration_tc=6.0, output_interval_tc=1.5,
                           noise=1e-3)
    a = simulate(ModelParams(**setup), sim, rng=np.random.default_rng(2))
    b = simulate(ModelParams(**setup), sim.replace(engine="numpy"), rng=np.random.default_rng(2))
    assert a.n_steps == b.n_steps > 0
    for x, y in ((a.c, b.c), (a.v, b.v), (a.P, b.P)):
        np.testing.assert_allclose(x, y, rtol=1e-9, atol=1e-12)


def test_a_state_that_turns_non_finite_stops_the_compiled_run():
    """NaN in one cell: the compiled loop stops (a negative step count) instead of running on, as NumPy does."""
    from grainplug.simulation import _kernel

    cl = Closure.from_params(FROZEN)
    n = 32
    U = cl.conserved(np.full(n, cl.c0), np.full(n, cl.v0), np.full(n, cl.P0))
    consts = _kernel.pack(cl, "periodic", np.zeros(3), cl.P0, 1.0)
    assert _kernel.advance(U, 0.0, 1.0, 0.4, consts, np.zeros(2))[2] > 0
    for j in (0, 1, 2):
        bad = U.copy()
        bad[j, 5] = np.nan
        assert math.isnan(_kernel.max_speed(bad, consts))
        assert _kernel.advance(bad, 0.0, 1.0, 0.4, consts, np.zeros(2))[2] < 0
    with pytest.raises(ParameterError, match="initial state"):
        simulate(FROZEN, SimulationParams(length_D=32.0, n_cells=n, duration_tc=1.0), initial=bad)


# -- friction ------------------------------------------------------------------
def test_coulomb_friction_holds_grains_at_rest_and_never_pushes_them_up():
    """Frozen Coulomb friction above the weight stops a falling column and keeps it stopped (v = 0, not < 0)."""
    p = ModelParams(variant="frozen-friction")
    cl = Closure.from_params(p, balance=False)  # friction 1.25 > weight 0.55: the grains must stop
    integ = Integrator(cl, 32, 1.0)
    U = cl.conserved(np.full(32, 0.55), np.full(32, 0.3), np.full(32, cl.P0))
    stopped_at = None
    for step in range(200):
        U = integ.sources(U, 0.01)
        v = U[1] / U[0]
        assert np.all(v >= 0.0)
        if stopped_at is None and np.all(v == 0.0):
            stopped_at = step
    assert stopped_at is not None
    # 0.3 v_c with a deceleration (1.25 - 0.55) / 0.55 stops in 0.236 t_c: at step 23
    assert stopped_at == 23


def test_v_abs_v_friction_relaxes_to_the_balanced_velocity():
    p = ModelParams(friction_law="v|v|")
    cl = Closure.from_params(p, balance=False)
    integ = Integrator(cl, 16, 1.0)
    U = cl.conserved(np.full(16, 0.55), np.full(16, 0.1), np.full(16, cl.P0))
    for _ in range(3000):
        U = integ.sources(U, 0.01)
    v_terminal = math.sqrt(0.55 / cl.alpha)
    np.testing.assert_allclose(U[1] / U[0], v_terminal, rtol=1e-6)


# -- open pipe and checks ---------------------------------------------------------------
def test_open_pipe_fills_with_the_fed_grains():
    """Grains fed at the top of an empty-ish pipe travel down it; air leaves at the held pressure."""
    p = ModelParams(friction_law="v|v|", base_velocity="balanced")
    sim = SimulationParams(boundary="open", length_D=60.0, n_cells=120, duration_tc=60.0, output_interval_tc=5.0,
                           noise=0.0)
    res = simulate(p, sim)
    assert np.all(np.isfinite(res.c))
    # the steady balanced state is the fed state all along the pipe
    np.testing.assert_allclose(res.c[-1], p.c0, atol=1e-6)
    np.testing.assert_allclose(res.v[-1], p.v0_star, rtol=1e-6)


def test_open_pipe_carries_the_fed_mass_flow_rate():
    """Fed at 0.5 g/s, the grains accelerate to their terminal velocity and thin out; once steady the grain
    flux is the fed flux all along the pipe (what goes in comes out)."""
    from grainplug.simulation.run import feed_velocity

    p = ModelParams(friction_law="v|v|", base_velocity="balanced")
    sim = SimulationParams(boundary="open", length_D=100.0, n_cells=200, duration_tc=300.0, output_interval_tc=10.0,
                           noise=0.0, feed_rate_g_s=0.5)
    res = simulate(p, sim)
    v_in = feed_velocity(p, 0.5, p.c0)
    # 0.5 g/s of glass through a 3 mm pipe at c = 0.55: 0.0514 m/s
    assert v_in * p.v_c_m_s == pytest.approx(0.5e-3 / (2500 * math.pi * 0.003**2 / 4 * 0.55), rel=1e-12)
    flux = res.c[-1] * res.v[-1]
    np.testing.assert_allclose(flux[5:], p.c0 * v_in, rtol=3e-3)  # still settling by ~1e-3
    # below the inlet the grains fall at their terminal velocity, friction = weight: 2 b mu_s v^2 = c
    np.testing.assert_allclose(res.v[-1][5:], np.sqrt(res.c[-1][5:] / (2 * p.mu_s)), rtol=0.01)
    assert res.c[-1][5:].max() < 0.9 * p.c0  # thinned out
    assert not res.warnings


def test_a_jammed_pipe_is_said_so():
    """Frozen Coulomb friction above the weight, no balancing force: the fed grains stop, with a warning."""
    sim = SimulationParams(boundary="open", length_D=50.0, n_cells=100, duration_tc=50.0, output_interval_tc=5.0,
                           noise=0.0, feed_rate_g_s=0.5)
    res = simulate(FROZEN, sim)
    assert np.mean(res.v[-1] == 0.0) > 0.5  # the lower part of the pipe is a static column
    assert any("grains stopped over" in w for w in res.warnings)


def test_bad_parameters_are_refused_in_one_line():
    with pytest.raises(ParameterError, match="n_cells"):
        SimulationParams(n_cells=4)
    with pytest.raises(ParameterError, match="boundary"):
        SimulationParams(boundary="closed")
    with pytest.raises(ParameterError, match="cfl"):
        SimulationParams(cfl=0.9)
    with pytest.raises(ParameterError, match="open pipe only"):
        SimulationParams(feed_rate_g_s=0.5)
    with pytest.raises(ParameterError, match="not both"):
        SimulationParams(boundary="open", feed_rate_g_s=0.5, feed_v=0.3)


def test_nonlinear_state_converges_between_grids():
    """The frozen variant's end state: one sawtooth wave per box; its dense segment and front speed agree
    within 2 % between 256 and 512 cells, and the compactness goes above random close packing."""
    states = []
    for n in (256, 512):
        res = simulate(FROZEN, SimulationParams(length_D=125.0, n_cells=n, duration_tc=300.0, output_interval_tc=0.25,
                                                noise=1e-6), rng=np.random.default_rng(4))
        assert segment_counts(res)[-1] == 1
        assert res.v[-1].min() >= 0.0  # friction never pushes grains upward
        states.append(wave_state(res))
    a, b = states
    assert a.n_waves == b.n_waves == 1
    assert abs(a.dense_length_D - b.dense_length_D) < 0.02 * b.dense_length_D, (a, b)
    assert abs(a.front_speed - b.front_speed) < 0.02 * b.front_speed, (a, b)
    assert b.c_max > 0.64
    assert 5.0 < b.front_speed < 15.0  # faster than the linear phase speed, 5.9 v_c


# -- the diagram measured like a movie -------------------------------------------------------
def _moving_train(speed: float, *, plug_D: float = 12.0, period_D: float = 30.0) -> SimulationResult:
    """Fields of a plug train (c = 0.55 plugs, 0.05 bubbles, fronts 0.4 D wide) moving at ``speed`` v_c."""
    p = ModelParams()
    L, n, nt = 120.0, 480, 401
    sim = SimulationParams(length_D=L, n_cells=n, duration_tc=200.0, output_interval_tc=0.5)
    z = (np.arange(n) + 0.5) * L / n
    t = np.arange(nt) * 0.5
    ph = (z[None, :] - speed * t[:, None]) % period_D
    c = (0.05 + 0.25 * (np.tanh(ph / 0.4) - np.tanh((ph - plug_D) / 0.4))
         + 0.25 * (1 + np.tanh((ph - period_D) / 0.4)))
    ones = np.ones_like(c)
    return SimulationResult(model=p, params=sim, z=z, time=t, c=c, v=ones, P=ones, grain_total=np.ones(nt),
                            air_total=np.ones(nt), n_steps=0, wall_s=0.0)


@pytest.mark.parametrize("speed", [-0.3, 0.8])
def test_a_simulated_plug_train_is_measured_like_a_movie(speed):
    """Known fields through the movie analysis' stages: celerity (sign: downstream positive), plug and
    bubble lengths, regime."""
    res = _moving_train(speed)
    m = measure(res, t_from_tc=0.0)
    assert m.regime == "propagative"
    assert m.celerity_m_s == pytest.approx(speed * res.model.v_c_m_s, rel=5e-3)
    assert m.plug_length_mm == pytest.approx(12.0 * 3.0, rel=0.01)
    assert m.bubble_length_mm == pytest.approx(18.0 * 3.0, rel=0.01)


@pytest.mark.parametrize("plug_D", [12.1, 12.37])
def test_dense_segments_are_measured_between_cells(plug_D):
    """The dense length comes from the threshold crossings, not a count of 0.25 D cells; the front speed
    from following the front."""
    res = _moving_train(0.8, plug_D=plug_D)
    w = wave_state(res)
    assert w.n_waves == 4
    assert w.dense_length_D == pytest.approx(plug_D, abs=0.01)
    assert w.front_speed == pytest.approx(0.8, abs=1e-3)


@pytest.mark.parametrize("ripple", [0.0, 1e-7])
def test_a_uniform_flow_has_no_plugs(ripple):
    """A uniform flow (exactly, or up to rounding-level ripples) is a single phase, not a failure."""
    res = _moving_train(0.5)
    c = 0.55 + ripple * np.sin(np.arange(res.c.size)).reshape(res.c.shape)
    flat = SimulationResult(**{**res.__dict__, "c": c})
    m = measure(flat, t_from_tc=0.0)
    assert m.regime == "none" and m.celerity_m_s is None
    assert "no plugs" in m.measures.statement


# -- outputs and the command line ---------------------------------------------------------------
def test_simulate_command_writes_fields_summary_and_figure(tmp_path, capsys):
    import xarray as xr

    from grainplug import __version__
    from grainplug.cli import main

    out = tmp_path / "sim"
    code = main(["simulate", "--variant", "frozen-friction", "--length-D", "60", "--cells", "96", "--duration-tc", "40",
                 "--output-interval-tc", "1", "--noise", "1e-6", "--out", str(out)])
    stdout, err = capsys.readouterr()
    assert code == 0, err
    assert "linear theory      most unstable lambda/D = 42.6" in stdout
    assert "conservation       grain" in stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["grainplug_version"] == __version__
    assert summary["run"]["n_cells"] == 96 and summary["seed"] == 0
    assert summary["model"]["friction_law_used"] == "coulomb-frozen"
    assert summary["run"]["grain_drift"] < 1e-12
    with xr.open_dataset(out / "fields.nc", engine="scipy") as ds:
        assert ds["c"].shape == (41, 96)
        np.testing.assert_allclose(ds["position_mm"].values[:2], [0.9375, 2.8125])
        assert ds["time_s"].values[-1] == pytest.approx(40 * summary["model"]["t_c_s"])
        assert ds.attrs["grainplug_version"] == __version__
    assert (out / "diagram.png").stat().st_size > 10_000


def _study(seed: int = 3):
    """A short run of the unstable frozen-friction set-up, studied."""
    from grainplug.simulation import run_study

    sim = SimulationParams(length_D=60.0, n_cells=64, duration_tc=20.0, output_interval_tc=1.0, noise=1e-6)
    return run_study(FROZEN, sim, rng=np.random.default_rng(seed), seed=seed)


def test_a_study_saves_its_fields_summary_and_figure(tmp_path):
    """``SimulationStudy.save`` writes what ``grainplug simulate`` writes: the fields as NetCDF (float32, the run's
    own values), the study's summary as strict JSON (with the seed) and the diagram; without figures, no
    diagram; in the formats asked for; a second save replaces the folder whole."""
    import xarray as xr

    from grainplug.jsonio import dumps

    study = _study()
    out = tmp_path / "study"
    written = study.save(out)
    assert set(written) == {"fields.nc", "summary.json", "diagram.png"}
    assert {f.name for f in out.iterdir() if not f.name.startswith(".")} == set(written)
    summary = json.loads((out / "summary.json").read_text())
    assert summary == json.loads(dumps(study.summary))
    assert summary["seed"] == 3 and summary["warnings"] == list(study.warnings)
    assert summary["linear"]["most_unstable_lambda_D"] == pytest.approx(42.6, abs=0.1)
    with xr.open_dataset(out / "fields.nc", engine="scipy") as ds:
        np.testing.assert_array_equal(ds["c"].values, study.result.c.astype(np.float32))
        assert ds["c"].shape == (21, 64)
    assert (out / "diagram.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    written = study.save(out, figures=False)
    assert set(written) == {"fields.nc", "summary.json"} and not (out / "diagram.png").exists()
    written = study.save(out, figure_options={"formats": ("png", "svg")})
    assert (out / "diagram.svg").read_text().lstrip().startswith("<?xml")
    with pytest.raises(ParameterError, match="dpi, formats and style"):
        study.save(out, figure_options={"colour": "red"})


def test_a_study_plots_its_run_and_is_its_pair_result_summary():
    """``SimulationStudy.plot`` returns the run's figure (the compactness diagram, the dense segments and peak
    compactness) without pyplot; ``simulate_and_measure`` is ``(study.result, study.summary)``."""
    import matplotlib.pyplot as plt
    from matplotlib.collections import QuadMesh
    from matplotlib.figure import Figure

    from grainplug.simulation import SimulationStudy, simulate_and_measure

    study = _study()
    assert isinstance(study, SimulationStudy)
    fig = study.plot()
    assert isinstance(fig, Figure) and not plt.get_fignums()
    [mesh] = [c for c in fig.axes[0].collections if isinstance(c, QuadMesh)]
    np.testing.assert_array_equal(np.asarray(mesh.get_array()).reshape(64, 21), study.result.c.T)
    [waves] = [ax for ax in fig.axes if ax.get_title(loc="left") == "(b) waves"]
    [counts] = waves.get_lines()  # the number of dense segments over time
    np.testing.assert_array_equal(counts.get_ydata(), segment_counts(study.result))
    assert "SimulationStudy periodic L=60 D, 64 cells" in repr(study)
    res, summary = simulate_and_measure(FROZEN, study.result.params, rng=np.random.default_rng(3))
    np.testing.assert_array_equal(res.c, study.result.c)
    expected = {**study.summary, "run": {**study.summary["run"], "wall_s": summary["run"]["wall_s"]}}
    del expected["seed"]  # recorded only when the study is told it
    assert json.dumps(summary, default=str) == json.dumps(expected, default=str)


@pytest.mark.parametrize(("args", "needle"), [
    (["--cells", "4"], "--cells"),
    (["--boundary", "closed"], "--boundary"),
    (["--base-pressure", "lots"], "--base-pressure"),
])
def test_simulate_refuses_bad_input_in_one_line(tmp_path, capsys, args, needle):
    from grainplug.cli import main

    out = tmp_path / "sim"
    code = main(["simulate", *args, "--out", str(out)])
    _, err = capsys.readouterr()
    assert code == 2
    assert needle in err and len(err.strip().splitlines()) == 1, err
    assert not out.exists()


def test_simulate_refuses_an_existing_folder_unless_overwrite(tmp_path, capsys):
    """A rerun into its own folder needs --overwrite; a folder holding someone else's files is never replaced."""
    from grainplug.cli import main

    out = tmp_path / "sim"
    args = ["simulate", "--length-D", "20", "--cells", "32", "--duration-tc", "2", "--output-interval-tc", "1",
            "--out", str(out)]
    assert main(args) == 0
    before = (out / "summary.json").read_bytes()
    capsys.readouterr()
    assert main(args) == 2
    assert "already exists — pass --overwrite" in capsys.readouterr().err
    assert (out / "summary.json").read_bytes() == before
    assert main([*args, "--overwrite", "--publication"]) == 0
    assert {p.name for p in out.glob("diagram.*")} == {"diagram.png", "diagram.svg", "diagram.pdf"}
    theirs = tmp_path / "theirs"
    theirs.mkdir()
    (theirs / "notes.txt").write_text("mine")
    assert main([*args[:-1], str(theirs), "--overwrite"]) == 2
    assert (theirs / "notes.txt").read_text() == "mine"


def test_the_summary_is_strict_json_when_a_measure_is_undefined(tmp_path, capsys):
    """A run without waves has no wavelength or front speed: null in summary.json, never a bare NaN."""
    from grainplug.cli import main

    out = tmp_path / "s"
    assert main(["simulate", "--cells", "64", "--length-D", "20", "--duration-tc", "5", "--out", str(out)]) == 0

    def refuse(word: str) -> None:
        raise ValueError(f"not JSON: {word}")

    summary = json.loads((out / "summary.json").read_text(), parse_constant=refuse)
    assert summary["waves"]["front_speed_m_s"] is None


def test_a_run_too_short_for_its_unstable_waves_says_so():
    """Linear theory says waves grow, the run ends before they show: a warning with the duration that would do."""
    from grainplug.simulation import simulate_and_measure

    sim = SimulationParams(length_D=60.0, n_cells=64, duration_tc=20.0, output_interval_tc=5.0, noise=1e-9)
    _, summary = simulate_and_measure(FROZEN, sim, rng=np.random.default_rng(0))
    [note] = [w for w in summary["warnings"] if "not had time to grow" in w]
    assert summary["waves"]["n_waves"] == 0 and "duration_tc=" in note and "noise=" in note
    _, stable = simulate_and_measure(ModelParams(), sim, rng=np.random.default_rng(0))  # the printed model: stable
    assert not [w for w in stable["warnings"] if "not had time to grow" in w]


def test_an_open_pipes_content_change_is_not_called_conservation(tmp_path, capsys):
    """Grains and air enter and leave an open pipe: the change of its content (41 % in the docs' example) was
    printed as "conservation", reading like a mass error."""
    from grainplug.cli import main

    code = main(["simulate", "--boundary", "open", "--length-D", "20", "--cells", "40", "--duration-tc", "5",
                 "--out", str(tmp_path / "o")])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "conservation       grain" not in out and "content change     grain" in out
    budget = next(line for line in out.splitlines() if line.startswith("grain budget"))
    assert float(budget.rsplit("= ", 1)[1]) < 1e-12  # the open pipe's check: the change is what crossed the ends


@pytest.mark.parametrize("engine", ["numba", "numpy"])
def test_an_open_pipes_grain_budget_closes_to_round_off(engine):
    """The grain content of an open pipe changes by what crossed its ends, to round-off: the feed (a constant
    flux, so exactly flux x time in) and the outflow, summed over the stages of every step as the scheme uses
    them. A budget summed with the wrong stage weights, or a flux left out, misses by far more than 1e-12."""
    from grainplug.simulation.run import feed_velocity

    p = ModelParams(friction_law="v|v|", base_velocity="balanced")
    sim = SimulationParams(boundary="open", length_D=60.0, n_cells=120, duration_tc=40.0, output_interval_tc=4.0,
                           noise=0.0, feed_rate_g_s=0.5, engine=engine)
    res = simulate(p, sim)
    change = res.grain_total - res.grain_total[0]
    assert abs(change[-1]) > 0.1 * res.grain_total[0]  # the starting column drains: a real test of the budget
    np.testing.assert_allclose(res.grain_inflow, p.c0 * feed_velocity(p, 0.5, p.c0) * res.time, rtol=1e-12)
    assert np.all(np.diff(res.grain_outflow) > 0)
    np.testing.assert_allclose(change, res.grain_inflow - res.grain_outflow, rtol=0,
                               atol=1e-12 * res.grain_total[0])
    assert res.grain_budget_residual < 1e-12
    assert not any("crossed the ends" in w for w in res.warnings)


def test_a_periodic_box_has_nothing_crossing_its_ends():
    res = simulate(FROZEN, SimulationParams(length_D=40.0, n_cells=48, duration_tc=5.0, output_interval_tc=2.5,
                                            noise=1e-3), rng=np.random.default_rng(4))
    assert not res.grain_inflow.any() and not res.grain_outflow.any()
    assert res.grain_budget_residual == pytest.approx(res.grain_drift, abs=1e-300)


def test_the_balancing_force_is_recorded_and_switchable(tmp_path, capsys):
    """The periodic box's uniform force S (+0.70 rho_s g, 127 % of the grains' weight) is in summary.json, its
    caveats and the terminal (it read "balance": null); --no-balance leaves it out."""
    from grainplug.cli import main

    for flag, force in (([], 0.6998), (["--no-balance"], 0.0)):
        out = tmp_path / f"o{len(flag)}"
        assert main(["simulate", "--length-D", "30", "--cells", "60", "--duration-tc", "2", *flag, "--out",
                     str(out)]) == 0
        printed = capsys.readouterr().out
        run = json.loads((out / "summary.json").read_text())["run"]
        assert run["balance"] is (not flag) and run["balance_force_rho_s_g"] == pytest.approx(force, abs=1e-3)
        assert ("balance force      S = +0.700 rho_s g" in printed) is (not flag)
    caveats = json.loads((tmp_path / "o0" / "summary.json").read_text())["caveats"]
    assert any("adds a uniform force S = +0.700" in c for c in caveats)


def test_ripples_and_an_open_pipes_inlet_cell_are_no_waves():
    """A train of 0.002 compactness (a grown 1e-7 noise, still linear) was reported as 23 D dense segments; an
    open pipe whose only dense cell is the fed one at the inlet as a 0.7 D wave. Neither is; a train of 0.01 is."""
    import dataclasses

    train = _moving_train(0.8)
    for amplitude, waves in ((0.002, 0), (0.012, 4)):
        c = 0.55 + amplitude * (train.c - 0.05) / 0.5
        assert wave_state(dataclasses.replace(train, c=c)).n_waves == waves, amplitude
    flat = np.full_like(train.c, 0.324)
    flat[:, 0] = 0.427
    open_pipe = dataclasses.replace(train, c=flat, params=dataclasses.replace(train.params, boundary="open"))
    none = wave_state(open_pipe)
    assert none.n_waves == 0 and "only the fed cells at the inlet" in none.why_none
    assert segment_counts(open_pipe)[-1] == 0  # the figure counts as the summary does
    flat[:, :8] = 0.427  # eight cells (2 D) dense at the inlet: a wave
    assert wave_state(dataclasses.replace(open_pipe, c=flat)).n_waves == 1
    assert segment_counts(dataclasses.replace(open_pipe, c=flat))[-1] == 1
    # a moving train in an open pipe with a dense fed cell: the inlet's still edge does not set the front speed
    moving = train.c.copy()
    moving[:, 1], moving[:, 0] = 0.05, 0.55
    w = wave_state(dataclasses.replace(open_pipe, c=moving))
    assert w.n_waves == 4 and w.front_speed == pytest.approx(0.8, abs=1e-3)
    assert "a range under 0.01" in wave_state(dataclasses.replace(train, c=np.full_like(train.c, 0.55))).why_none


def test_an_open_pipes_start_up_still_passing_is_said():
    """The start-up column draining from an open pipe was measured as a propagative wave at +0.14 m/s without a
    word: a grain content still changing over the measured part of the run is warned about."""
    import dataclasses

    from grainplug.simulation import simulate_and_measure

    p = ModelParams(friction_law="v|v|", base_velocity="balanced")
    short = SimulationParams(boundary="open", length_D=100, n_cells=200, duration_tc=80, feed_rate_g_s=0.5)
    _, summary = simulate_and_measure(p, short)
    assert any("has not left the pipe" in w for w in summary["warnings"])
    _, summary = simulate_and_measure(p, dataclasses.replace(short, duration_tc=400))
    assert not any("has not left the pipe" in w for w in summary["warnings"])


def test_the_coarsening_warning_gives_the_counts_its_panel_shows():
    """``simulate`` said "dense segments changed from 1 to 0" while its own panel showed 0 -> 1: the counts the
    warning gives are the panel's, first and last of the run's last fifth, with their range."""
    import re

    import matplotlib.pyplot as plt

    from grainplug.simulation import run_study

    sim = SimulationParams(length_D=251.0, n_cells=256, duration_tc=100.0, output_interval_tc=1.0, noise=1e-6)
    study = run_study(FROZEN, sim, rng=np.random.default_rng(3), seed=3)  # the segments still multiply
    [said] = [w for w in study.warnings if w.startswith("still coarsening")]
    first, last, low, high = map(int, re.search(r"from (\d+) to (\d+) \(between (\d+) and (\d+)\)", said).groups())
    fig = study.plot()
    [waves] = [ax for ax in fig.axes if ax.get_title(loc="left") == "(b) waves"]
    [counts] = waves.get_lines()
    shown = np.asarray(counts.get_ydata())
    plt.close(fig)
    tail = shown[-(len(shown) // 5):]
    assert (first, last) == (tail[0], tail[-1]) and (low, high) == (tail.min(), tail.max())
    assert first < last  # the case the warning turned round


def test_a_simulation_is_not_advised_to_change_its_lighting_or_file():
    """A simulated compactness too flat to part into plugs and bubbles was advised to "raise the contrast ...
    (lighting, exposure, a less compressed file)": a simulation has neither; it is told it is the model's answer."""
    from grainplug.simulation import run_study

    jam = ModelParams(variant="frozen-friction", jamming=True)
    study = run_study(jam, SimulationParams(length_D=251.0, n_cells=256, duration_tc=300.0),
                      rng=np.random.default_rng(3), seed=3)
    statement = study.summary["measured_as_movie"]["statement"]
    assert "too close to tell apart" in statement  # the case in question
    assert not any(w in statement for w in ("lighting", "exposure", "compressed file"))
    assert "the model's answer" in statement
