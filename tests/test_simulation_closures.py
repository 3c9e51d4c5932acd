"""Issue 37's closures (Coulomb wall friction on the contact stress, the Janssen term dropped, Stokes' drag
added), checked against independent computations and against the model's validity.

- sympy: the conservative equations with the new terms, linearised, have the stability matrix's roots;
- a periodic box's Fourier modes grow (or decay) at the linear theory's rates;
- grain and air mass conserved to round-off; the open pipe's grain budget closes;
- the nonlinear state converges with the grid; halving or doubling ``friction_v_eps`` moves it little;
- a column fed denser than it can flow settles (the feed backs up) instead of stalling the time step;
- runs that leave the model stop with one line; parameters out of range are refused in one line.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
import sympy as sp

from grainplug.errors import ParameterError
from grainplug.simulation import SimulationParams, simulate
from grainplug.simulation.equations import Closure
from grainplug.simulation.run import feed_velocity
from grainplug.simulation.validation import fit_modes
from grainplug.stability import ModelParams, roots
from grainplug.stability.params import P_ATM_PA

#: the closure of issue 37 with a steady, friction-balanced base state (the walls could hold it: 1.8 x weight)
JANSSEN = dict(c0=0.585, jamming=True, jamming_c_min=0.56, friction_law="coulomb-janssen", friction_v_eps=0.05,
               janssen_v2_term=False, drag="stokes-carman")


def _conservative_roots(p: ModelParams, k: float) -> np.ndarray:
    """Roots omega of the sympy-linearised conservative system, the friction ``4 mu kappa sigma_c tanh(v/ve)``,
    Stokes' factor on the permeability and the Janssen flux switch written here from the issue's formulas."""
    c, v, P, w = sp.symbols("c v P omega")
    cl = Closure.from_params(p)
    P0 = p.P0_star
    gam, kap = sp.Float(p.gamma), sp.Float(p.kappa)
    r = (P / P0) ** (1 / gam)
    fr = p.jamming_fr_pa / p.P_c_pa
    sigma = fr * (c - p.jamming_c_min) ** 2 / (p.jamming_c_max - c) ** 5
    jt = 1 if p.janssen_v2_term else 0
    F = sp.Matrix([c * v, c * v**2 + jt * v**2 / (2 * kap) + P + sigma, r * (1 - c) * v])
    tanh = sp.tanh(v / p.friction_v_eps) if p.friction_v_eps else sp.sign(v)
    fric = 4 * p.mu_s * p.kappa * sigma * tanh
    S = sp.Matrix([0, c * math.cos(math.radians(p.theta_deg)) + cl.balance_force - fric, 0])
    K_ck = (1 - c) ** 3 / c**2 * (p.c0**2 / (1 - p.c0) ** 3) * p.B1_star * (1 - p.c0) / p.gamma
    K = K_ck * (10 * c / (1 + 9 * c) if p.drag == "stokes-carman" else 1)
    U = sp.Matrix([c, c * v, r * (1 - c)])
    W = [c, v, P]
    base = {c: p.c0, v: p.v0_star, P: P0}
    dU, dF, dS = (M.jacobian(W).subs(base) for M in (U, F, S))
    Dm = sp.zeros(3, 3)
    Dm[2, 2] = (r * K).subs(base)
    M = -sp.I * w * dU + sp.I * k * dF - dS + k**2 * Dm
    poly = sp.Poly(sp.expand(M.det()), w)
    return np.sort_complex(np.roots([complex(a) for a in poly.all_coeffs()]))


@pytest.mark.parametrize("setup", [
    {"base_velocity": "balanced"},
    {"base_velocity": "balanced", "friction_v_eps": 0.5, "janssen_v2_term": True},
    {"drag": "carman-kozeny", "base_pressure_pa": P_ATM_PA},
    {"base_velocity": "balanced", "theta_deg": 10.0, "friction_v_eps": 0.2},
])
def test_the_linear_matrix_with_the_new_terms_is_the_linearised_equations(setup):
    p = ModelParams(**{**JANSSEN, **setup})
    for k in (0.07, 0.3, 1.1):
        np.testing.assert_allclose(_conservative_roots(p, k),
                                   np.sort_complex(roots(p, np.array([k]), track=False)[0]), rtol=1e-8, atol=1e-10)


# -- the linear phase -------------------------------------------------------------------
def test_fourier_modes_decay_at_the_linear_rates():
    """The friction-balanced base state is steady and linearly stable: each mode k* = 0.05 .. 0.25 decays at the
    linear theory's rate, within 1 % of |omega|. (Its unstable set-ups, e.g. with the Janssen term kept, grow
    fastest at the grid scale, with no short-wave cut-off: their long modes are swamped within a few t_c and
    cannot be fitted; that is said in docs/model.md.)"""
    duration, modes = 40.0, range(1, 6)
    p = ModelParams(**{**JANSSEN, "base_velocity": "balanced"})
    sim = SimulationParams(length_D=2 * np.pi / 0.05, n_cells=512, duration_tc=duration,
                           output_interval_tc=duration / 80, noise=1e-9)
    res = simulate(p, sim, rng=np.random.default_rng(1))
    fits = fit_modes(res, modes, t_from=duration / 4)
    for f in fits:
        err = abs(f.growth_sim - f.growth_linear) / abs(complex(f.omega_r_linear, f.growth_linear))
        assert err < 0.01, (f.k, f.growth_sim, f.growth_linear)
    assert abs(res.c[-1] - p.c0).max() < 1e-3  # still linear
    assert all(f.growth_linear < 0 for f in fits)


# -- conservation, convergence, the regularisation ------------------------------------------
def _dense_box(n_cells: int = 256, **kw: object):
    p = ModelParams(**{**JANSSEN, "base_velocity": "balanced", **kw})
    sim = SimulationParams(length_D=60.0, n_cells=n_cells, duration_tc=30.0, output_interval_tc=3.0, noise=0.0)
    z = (np.arange(n_cells) + 0.5) * sim.dx
    cl = Closure.from_params(p)
    c = p.c0 + 0.03 * np.sin(2 * np.pi * z / 60.0)  # a dense and a loose half: some cells slide, some stick
    return p, sim, cl.conserved(c, np.full(n_cells, cl.v0), np.full(n_cells, cl.P0))


@pytest.mark.parametrize("engine", ["numba", "numpy"])
def test_grain_and_air_conserved_to_round_off(engine):
    p, sim, U0 = _dense_box(128)
    res = simulate(p, sim.replace(engine=engine), initial=U0)
    assert res.c[-1].max() - res.c[-1].min() > 0.01  # not relaxed away
    assert res.grain_drift < 1e-13
    assert res.air_drift < 1e-13


def test_engines_agree_on_an_open_pipe_fed_denser_than_it_flows():
    p = ModelParams(**JANSSEN)
    sim = SimulationParams(boundary="open", length_D=20.0, n_cells=40, duration_tc=3.0, output_interval_tc=1.0,
                           feed_rate_g_s=0.5, noise=0.0)
    a = simulate(p, sim)
    b = simulate(p, sim.replace(engine="numpy"))
    assert a.n_steps == b.n_steps > 0
    np.testing.assert_allclose(a.c, b.c, rtol=1e-9, atol=1e-12)


def test_the_state_converges_with_the_grid():
    """L1 distance to a 1024-cell run falls by 4 or more from 256 to 512 cells (128 cells are not yet in the
    asymptotic range: 2.9e-3 against 2.4e-3 at 64)."""
    ref = None
    errs = []
    for n in (1024, 256, 512):
        p, sim, U0 = _dense_box(n)
        c = simulate(p, sim, initial=U0).c[-1]
        if ref is None:
            ref = c
            continue
        errs.append(np.abs(c - ref.reshape(n, -1).mean(axis=1)).mean())
    assert errs[0] / errs[1] > 3.0, errs
    assert errs[1] < 3e-4, errs


def test_the_regularisation_velocity_does_not_set_the_answer():
    """Halving or doubling friction_v_eps (0.025 .. 0.1 v_c, the base velocity 0.03 v_c held fixed as the
    balance force's) moves the compactness field by under 0.005 (mean over the box; the field spans 0.06)."""
    runs = {}
    for ve in (0.025, 0.05, 0.1):
        p = ModelParams(**{**JANSSEN, "friction_v_eps": ve})
        sim = SimulationParams(length_D=60.0, n_cells=128, duration_tc=30.0, output_interval_tc=3.0, noise=0.0)
        _, _, U0 = _dense_box(128)
        runs[ve] = simulate(p, sim, initial=U0).c[-1]
    for ve in (0.025, 0.1):
        assert np.abs(runs[ve] - runs[0.05]).mean() < 5e-3, ve


# -- the open pipe and the model's validity ------------------------------------------
def test_a_column_fed_denser_than_it_flows_backs_up_instead_of_stalling():
    """Fed at c = 0.585 (the walls can hold 1.8 times its weight), the column jams: the feed backs up (grains
    enter no faster than the column makes room), the compactness stays below close packing and the run
    finishes with a few thousand steps (before issue 37's fix the top cell packed to 0.63 and the step fell
    to 4e-5 t_c, a 2 h stall)."""
    p = ModelParams(**JANSSEN)
    sim = SimulationParams(boundary="open", length_D=30.0, n_cells=60, duration_tc=20.0, output_interval_tc=1.0,
                           feed_c=0.585, feed_rate_g_s=0.5, noise=0.0)
    res = simulate(p, sim, max_seconds=60)
    assert res.c.max() < 0.61
    assert res.n_steps < 20_000
    assert res.grain_budget_residual < 1e-12
    fed = 0.585 * sim.duration_tc * feed_velocity(p, 0.5, 0.585)
    assert res.grain_inflow[-1] < 0.5 * fed  # backed up
    # held by the walls, it creeps at the regularised law's v_eps atanh(weight / largest friction) (0.031 v_c
    # here): the regularisation, not the physics, sets a jammed column's creep (docs/model.md)
    creep = p.friction_v_eps * math.atanh(1 / p.janssen_stress_ratio)
    assert np.abs(res.v[-1]).max() < 1.01 * creep


def test_a_time_step_below_the_floor_stops_in_one_line():
    p = ModelParams(**JANSSEN)
    sim = SimulationParams(boundary="open", length_D=30.0, n_cells=60, duration_tc=5.0, output_interval_tc=1.0,
                           feed_rate_g_s=0.5, dt_floor_tc=0.5)
    with pytest.raises(ParameterError, match=r"time step fell below dt_floor_tc = 0.5 t_c .* z = .* D .*c = ") as e:
        simulate(p, sim)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize(("setup", "needle"), [
    ({"jamming_c_min": 0.66}, "c_min < c_max"),
    ({"jamming_c_max": 0.5, "c0": 0.45, "jamming_c_min": 0.4}, None),  # legal, for contrast
    ({"friction_v_eps": 0.0}, "v_eps must be positive"),
    ({"friction_v_eps": -0.1}, "v_eps must be positive"),
    ({"drag": "negative"}, "drag must be one of"),
    ({"jamming": False}, "needs jamming=True"),
    ({"friction_law": "v2"}, "regularises the coulomb-janssen friction law only"),
])
def test_closure_parameters_out_of_range_are_refused_in_one_line(setup, needle):
    if needle is None:
        ModelParams(**{**JANSSEN, **setup})
        return
    with pytest.raises(ParameterError, match=needle) as e:
        ModelParams(**{**JANSSEN, **setup})
    assert "\n" not in str(e.value)


def test_a_feed_at_close_packing_is_refused():
    with pytest.raises(ParameterError, match="close packing"):
        simulate(ModelParams(**JANSSEN), SimulationParams(boundary="open", length_D=30.0, n_cells=60,
                                                          duration_tc=1.0, feed_c=0.65, feed_rate_g_s=0.5))


def _plug_under_rain(p: ModelParams, sim: SimulationParams, top_D: float) -> tuple[np.ndarray, np.ndarray]:
    """The cells' centres (D) and a start: a still plug at c = 0.60 below ``top_D``, rain at c = 0.02 falling at
    2 v_c above it, the air at the base pressure."""
    cl = Closure.from_params(p, balance=False)
    z = (np.arange(sim.n_cells) + 0.5) * sim.dx
    return z, cl.conserved(np.where(z > top_D, 0.60, 0.02), np.where(z > top_D, 0.0, 2.0),
                           np.full(sim.n_cells, cl.P0))


def test_a_held_plug_climbs_as_the_rain_lands_on_it():
    """A plug the walls hold (c = 0.60 > c*) at the bottom, rain fed at 0.5 g/s above it: its top climbs at the
    speed mass conservation gives, -q / (c_plug - c_rain), within 15 % (q the fed volume flux per area)."""
    p = ModelParams(**{**JANSSEN, "friction_v_eps": 0.01, "base_pressure_pa": P_ATM_PA, "grain_diameter_um": 200})
    n, length = 200, 100.0
    sim = SimulationParams(boundary="open", length_D=length, n_cells=n, duration_tc=60.0, output_interval_tc=0.5,
                           feed_c=0.58, feed_rate_g_s=0.5, noise=0.0)
    z, U0 = _plug_under_rain(p, sim, 70.0)
    res = simulate(p, sim, initial=U0)
    below = z > 5.0
    top = np.array([z[below][np.argmax(row[below] > 0.5)] for row in res.c])
    sel = res.time > 0.3 / p.t_c_s
    climb = np.polyfit(res.time[sel], top[sel], 1)[0]  # D per t_c
    i = int(np.searchsorted(z, top[-1]))
    c_rain = np.median(res.c[-1][(z > top[-1] - 10.0) & (z < top[-1] - 4.0)])  # above the front's smear
    c_plug = np.median(res.c[-1][i + 2:])
    q = 0.5e-3 / (p.grain_density_kg_m3 * math.pi * p.D_m**2 / 4) / p.v_c_m_s
    assert 0.01 < c_rain < 0.1 and c_plug > 0.59
    assert climb == pytest.approx(-q / (c_plug - c_rain), rel=0.15)


# -- the model's validity: the stops -------------------------------------------------------
def _colliding(engine: str = "numba"):
    """Two streams of c = 0.8 meeting at 5 v_c each in a periodic box, no jamming pressure: they pack to c = 1."""
    p = ModelParams(c0=0.8)
    sim = SimulationParams(length_D=20.0, n_cells=32, duration_tc=5.0, output_interval_tc=1.0, engine=engine)
    cl = Closure.from_params(p)
    z = (np.arange(32) + 0.5) * sim.dx
    return p, sim, cl.conserved(np.full(32, 0.8), np.where(z < 10.0, 5.0, -5.0), np.full(32, cl.P0))


@pytest.mark.parametrize("engine", ["numba", "numpy"])
def test_a_compactness_reaching_one_stops_in_one_line(engine):
    """The streams pack to c = 1 where they meet (z = 8-10 D): the run stops there with one line naming the place
    and the fix, instead of NaNs or a time step collapsing without a word on why."""
    p, sim, U0 = _colliding(engine)
    with pytest.raises(ParameterError, match=r"^the compactness reached 1 at t = [0-9.e-]+ t_c, z = ([0-9.]+) D "
                                             r"\(cell \d+\).*use jamming=True") as e:
        simulate(p, sim, initial=U0)
    assert "\n" not in str(e.value)
    assert 7.0 < float(re.search(r"z = ([0-9.]+) D", str(e.value)).group(1)) < 12.0


def test_the_cli_stops_a_compactness_reaching_one_in_one_line(tmp_path, capsys):
    """Fed at c = 0.999 and 50 v_c into a pipe of c = 0.9: the top cells pack to 1; exit code 2, one line, no
    traceback, no output folder."""
    from test_cli_basics import assert_one_line_error, run

    out = tmp_path / "sim"
    code, _, err = run(capsys, "simulate", "--boundary", "open", "--c0", "0.9", "--feed-c", "0.999", "--feed-v", "50",
                       "--length-D", "20", "--cells", "32", "--duration-tc", "5", "--output-interval-tc", "1",
                       "--out", out)
    assert code == 2
    assert_one_line_error(code, err, "the compactness reached 1", "--jamming")
    assert not out.exists()


def test_a_negative_air_mass_stops_in_one_line(monkeypatch):
    """No input found drives the air mass negative (the central-upwind fluxes and the implicit Darcy step keep it
    positive under the Courant limit), so the guard is checked with an air step that takes more than a cell's air
    out, as an unstable step would: the run stops at that output with one line naming the cell and the fix."""
    from grainplug.simulation.scheme import Integrator

    darcy = Integrator.diffusion

    def leaky(self, U, dt):
        out = darcy(self, U, dt)
        out[2, 7] = -0.01  # the cell's air and more taken out at every step
        return out

    monkeypatch.setattr(Integrator, "diffusion", leaky)
    p = ModelParams(variant="frozen-friction")
    sim = SimulationParams(length_D=20.0, n_cells=32, duration_tc=0.2, output_interval_tc=0.1, engine="numpy")
    with pytest.raises(ParameterError, match=r"^the air mass went negative \(-[0-9.e+-]+\) at t = 0.1 t_c, "
                                             r"z = 4.69 D \(cell 7\).*more cells or a smaller cfl=") as e:
        simulate(p, sim)
    assert "\n" not in str(e.value)


# -- Janssen's stress carried down each dense stretch (wall_stress="janssen-column") -------------------
#: the carried-stress closure at the paper's conditions (exact Coulomb friction: it holds cells at their limit)
COLUMN = dict(grain_diameter_um=200, c0=0.585, base_pressure_pa=P_ATM_PA, jamming=True, jamming_c_min=0.56,
              friction_law="coulomb-janssen", janssen_v2_term=False, drag="stokes-carman", wall_stress="janssen-column")


def test_the_carried_stress_is_janssens_profile():
    """A uniform stretch of 40 cells (c = 0.58) between dilute cells: the stress obeys d sigma/dz = c - 4 mu kappa
    sigma from zero at the top (closed form ``c lambda (1 - exp(-z / lambda))``); each inner cell's weight plus the
    stress's push equals the walls' hold to round-off; the lowest cell is pushed by the stress at its top, which the
    walls cannot take; the walls hold the stretch's weight but ``c lambda (1 - exp(-L / lambda))`` (the Janssen
    deficit, released at the bottom)."""
    from grainplug.simulation.scheme import column_stress

    p = ModelParams(**COLUMN)
    wall, dx = 4 * p.mu_s * p.kappa, 0.25
    c = np.r_[np.full(5, 0.02), np.full(40, 0.58), np.full(5, 0.02)]
    push, cap = column_stress(c, c, wall, 0.56, dx, False)
    lam = 1 / wall
    faces = 0.58 * lam * (1 - np.exp(-np.arange(41) * dx / lam))  # sigma at the stretch's faces, closed form
    inner = slice(5, 44)
    np.testing.assert_allclose(push[inner], -np.diff(faces)[:-1] / dx, rtol=1e-12, atol=1e-14)
    np.testing.assert_array_equal(c[inner] + push[inner], cap[inner])  # at Coulomb's limit, exactly
    assert push[44] == pytest.approx(faces[39] / dx, rel=1e-12)  # the free bottom: pushed out
    assert push[44] + c[44] - cap[44] == pytest.approx(faces[40] / dx, rel=1e-12)
    L = 40 * dx
    assert cap.sum() * dx == pytest.approx(0.58 * L - 0.58 * lam * (1 - np.exp(-L / lam)), rel=1e-12)
    assert not push[:5].any() and not cap[:5].any() and not push[45:].any()
    # a periodic box dense all round carries the periodic (saturated) stress: no cell pushed, all at the limit
    push, cap = column_stress(np.full(16, 0.58), np.full(16, 0.58), wall, 0.56, dx, True)
    np.testing.assert_allclose(push, 0.0, atol=1e-14)
    np.testing.assert_allclose(cap, 0.58, rtol=1e-13)


@pytest.mark.parametrize("static_over_kinetic", [1.0, 2.0])
def test_the_engines_agree_on_the_carried_stress_and_conserve_grain(static_over_kinetic):
    """A plug held at the outlet of an open pipe, rain landing on it (with one friction coefficient, and with static
    friction twice the kinetic one): both engines give the same run to 1e-9, and the grain budget closes to
    round-off."""
    p = ModelParams(**COLUMN, mu_static_over_kinetic=static_over_kinetic)
    n, length = 80, 40.0
    sim = SimulationParams(boundary="open", length_D=length, n_cells=n, duration_tc=4.0, output_interval_tc=0.5,
                           feed_c=0.58, feed_rate_g_s=0.5, noise=0.0)
    _, U0 = _plug_under_rain(p, sim, 20.0)
    a = simulate(p, sim, initial=U0)
    b = simulate(p, sim.replace(engine="numpy"), initial=U0)
    assert a.n_steps == b.n_steps > 0
    np.testing.assert_allclose(a.c, b.c, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(a.v, b.v, rtol=1e-9, atol=1e-9)
    assert a.grain_budget_residual < 1e-12 and b.grain_budget_residual < 1e-12


def test_a_periodic_dense_column_decays_at_the_linear_rates_and_conserves():
    """A uniform column dense all round slides at v* = 1: weight, the carried stress's gradient and the wall
    friction cancel mode by mode (docs/model.md), so the linear theory is the stability matrix with F_c = cos theta
    and F_v = 0. The modes k* = 0.05, 0.1, 0.15 decay at its rates (0.07, 0.30, 0.75 /t_c) within 1 % of |omega|
    over 2-12 t_c (shorter waves decay as the air's diffusion, 1.7 /t_c and faster, into the round-off within a few
    t_c); grain and air are conserved to 1e-13."""
    duration = 12.0
    p = ModelParams(**COLUMN)
    assert p.base_state_residual == 0.0 and p.friction == 0.0 and p.friction_c == 1.0
    sim = SimulationParams(length_D=2 * np.pi / 0.05, n_cells=512, duration_tc=duration,
                           output_interval_tc=duration / 80, noise=1e-6)
    res = simulate(p, sim, rng=np.random.default_rng(1))
    fits = fit_modes(res, range(1, 4), t_from=2.0)
    for f in fits:
        err = abs(f.growth_sim - f.growth_linear) / abs(complex(f.omega_r_linear, f.growth_linear))
        assert err < 0.01, (f.k, f.growth_sim, f.growth_linear)
    assert all(f.growth_linear < -0.05 for f in fits)
    assert res.grain_drift < 1e-13 and res.air_drift < 1e-13


def test_a_plug_with_a_free_bottom_is_not_held():
    """The walls hold a stretch's weight but the Janssen deficit: a 30 D plug at the outlet, which the local
    stress holds for good (it climbs as rain lands on it), is released from its bottom and leaves a 100 D pipe
    within 0.3 s at 200 and 400 cells (0.19 and 0.23 s; docs/model.md): the closure forms no plug that lasts."""
    p = ModelParams(**COLUMN)
    gone = []
    for n in (200, 400):
        sim = SimulationParams(boundary="open", length_D=100.0, n_cells=n, duration_tc=20.0, output_interval_tc=0.5,
                               feed_c=0.58, feed_rate_g_s=0.5, noise=0.0)
        cl = Closure.from_params(p, balance=False)
        z = (np.arange(n) + 0.5) * sim.dx
        U0 = cl.conserved(np.where(z > 70.0, 0.60, 0.02), np.where(z > 70.0, 0.0, 2.0), np.full(n, cl.P0))
        res = simulate(p, sim, initial=U0)
        dense = (res.c[:, z > 5.0] > 0.56).any(axis=1)
        assert dense[0] and not dense[-1]
        gone.append(res.time[np.argmin(dense)] * p.t_c_s)
        assert res.grain_budget_residual < 1e-12
    assert max(gone) < 0.3, gone
    assert gone[0] == pytest.approx(gone[1], rel=0.3)


@pytest.mark.parametrize(("setup", "needle"), [
    ({"friction_law": "coulomb-weight", "jamming": False}, "is the coulomb-janssen friction's"),
    ({"friction_v_eps": 0.01}, "leave friction_v_eps= unset"),
    ({"wall_stress": "global"}, "wall stress must be one of"),
])
def test_carried_stress_parameters_out_of_range_are_refused_in_one_line(setup, needle):
    with pytest.raises(ParameterError, match=needle) as e:
        ModelParams(**{**COLUMN, **setup})
    assert "\n" not in str(e.value)


# -- the closures' switches on the command line ---------------------------------------------
def test_the_cli_takes_the_closures_switches(tmp_path, capsys):
    """stability and simulate take every switch of issue 37's closures; the set-up reaches the run's summary."""
    import json

    from test_cli_basics import run

    switches = ["--friction-law", "coulomb-janssen", "--jamming", "--jamming-c-min", "0.56", "--c0", "0.585",
                "--wall-stress", "janssen-column", "--no-janssen-v2-term", "--drag", "stokes-carman",
                "--base-pressure", "atmospheric", "--grain-diameter-um", "200"]
    code, out, err = run(capsys, "stability", *switches, "--n-k", "100", "--json")
    assert code == 0, err
    setup = json.loads(out)["setup"]
    assert setup["friction_law"] == "coulomb-janssen" and any("carried down" in c for c in setup["caveats"])
    code, out, err = run(capsys, "simulate", *switches, "--boundary", "open", "--feed-c", "0.58", "--feed-rate-g-s",
                         "0.5", "--length-D", "20", "--cells", "40", "--duration-tc", "2", "--output-interval-tc",
                         "0.5", "--out", tmp_path / "sim", "--json")
    assert code == 0, err
    inputs = json.loads(out)["model"]
    assert (inputs["wall_stress"], inputs["drag"], inputs["janssen_v2_term"], inputs["jamming_c_min"],
            inputs["friction_v_eps"]) == ("janssen-column", "stokes-carman", False, 0.56, None)
    code, out, err = run(capsys, "stability", "--friction-law", "coulomb-janssen", "--jamming", "--friction-v-eps",
                         "0.02", "--n-k", "100", "--json")
    assert code == 0 and json.loads(out)["setup"]["friction_law"] == "coulomb-janssen"


@pytest.mark.parametrize(("args", "needle"), [
    (["--wall-stress", "janssen-column"], "--friction-law coulomb-janssen"),
    (["--friction-law", "coulomb-janssen"], "--jamming"),
    (["--friction-law", "coulomb-janssen", "--jamming", "--friction-v-eps", "-1"], "--friction-v-eps"),
    (["--friction-law", "coulomb-janssen", "--jamming", "--friction-v-eps", "0.01", "--wall-stress",
      "janssen-column"], "--friction-v-eps"),
    (["--friction-v-eps", "0.01"], "coulomb-janssen"),
    (["--drag", "negative"], "--drag"),
    (["--jamming", "--jamming-c-min", "0.7"], "c_min < c_max"),
    (["--wall-stress", "everywhere"], "--wall-stress"),
])
@pytest.mark.parametrize("command", ["stability", "simulate"])
def test_the_cli_refuses_bad_closures_in_one_line(tmp_path, capsys, command, args, needle):
    from test_cli_basics import assert_one_line_error, run

    extra = ["--out", tmp_path / "sim"] if command == "simulate" else []
    code, _, err = run(capsys, command, *args, *extra)
    assert code == 2
    assert_one_line_error(code, err, needle)
    assert not (tmp_path / "sim").exists()


# -- an inlet that admits air only through a hopper's grains (SimulationParams.inlet_seal_D) ------------------
def test_a_sealed_inlet_draws_the_pressure_down_and_the_engines_agree():
    """A dense column fed at the top of a pipe whose air comes in through 30 D of the fed grains: as the grains
    fall the air pressure in the pipe drops below the atmosphere (it is held at the ends otherwise), both engines
    give the same run, and the grain budget closes to round-off; without the seal the suction is less than half."""
    p = ModelParams(**COLUMN)
    n, fc = 60, 0.5846
    cl = Closure.from_params(p, balance=False)
    U0 = cl.conserved(np.full(n, fc), np.full(n, feed_velocity(p, 0.5, fc)), np.full(n, cl.P0))
    sim = SimulationParams(boundary="open", length_D=30.0, n_cells=n, duration_tc=6.0, output_interval_tc=1.0,
                           feed_c=fc, feed_rate_g_s=0.5, noise=0.0, inlet_seal_D=30.0)
    a = simulate(p, sim, initial=U0)
    b = simulate(p, sim.replace(engine="numpy"), initial=U0)
    np.testing.assert_allclose(a.c, b.c, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(a.P, b.P, rtol=1e-9)
    assert a.grain_budget_residual < 1e-12
    open_top = simulate(p, sim.replace(inlet_seal_D=None), initial=U0)
    suction = (a.P[-1].min() - cl.P0) * p.P_c_pa
    assert suction < -500.0, suction  # -765 Pa
    assert suction < 2 * (open_top.P[-1].min() - cl.P0) * p.P_c_pa  # -328 Pa: the column draws air through itself


@pytest.mark.parametrize(("kw", "needle"), [
    ({"boundary": "open", "inlet_seal_D": -1.0}, "inlet_seal_D"),
    ({"boundary": "open", "inlet_seal_D": math.inf}, "inlet_seal_D"),
    ({"inlet_seal_D": 10.0}, "open pipe only"),
])
def test_a_bad_inlet_seal_is_refused_in_one_line(kw, needle):
    with pytest.raises(ParameterError, match=needle) as e:
        SimulationParams(**kw)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize(("args", "needle"), [
    (["--boundary", "open", "--inlet-seal-D", "-1"], "--inlet-seal-D"),
    (["--inlet-seal-D", "10"], "open pipe only"),
])
def test_the_cli_refuses_a_bad_inlet_seal_in_one_line(tmp_path, capsys, args, needle):
    from test_cli_basics import assert_one_line_error, run

    code, _, err = run(capsys, "simulate", *args, "--out", tmp_path / "sim")
    assert code == 2
    assert_one_line_error(code, err, needle)
    assert not (tmp_path / "sim").exists()


# -- static friction above kinetic friction (ModelParams.mu_static_over_kinetic) -----------------------------
#: the local contact stress with exact Coulomb friction, at the paper's conditions
LOCAL_EXACT = dict(grain_diameter_um=200, c0=0.585, base_pressure_pa=P_ATM_PA, jamming=True, jamming_c_min=0.56,
                   friction_law="coulomb-janssen", janssen_v2_term=False, drag="stokes-carman")


def _c_at_ratio(cl: Closure, ratio: float) -> float:
    """The compactness whose contact stress's wall friction is ``ratio`` times its weight (bisection)."""
    lo, hi = cl.jam_c_min + 1e-9, cl.jam_c_max - 1e-6
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if cl.wall * float(cl.jamming_pressure(np.array([mid]))[0]) / (mid * cl.cos_theta) < ratio:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@pytest.mark.parametrize("engine", ["numpy", "numba"])
def test_static_friction_holds_a_cell_at_rest_within_its_margin_and_slides_on_kinetic_friction(engine):
    """The exact set-valued law with static friction ``r F`` above the kinetic ``F`` (r = 2), one source step on
    cells whose weight is 0.8 F, 1.5 F and 3 F (their friction over weight 1.25, 0.67, 0.33): at rest, the first two
    stay (1.5 F is within the static margin, which r = 1 does not give), the third slides at ``(g - F) dt / c``;
    the same cells sliding down at 0.01 v_c: the kinetic friction F decelerates the first to rest (and static
    friction keeps it there), the others accelerate at ``(g - F) / c``."""
    from grainplug.simulation import _kernel
    from grainplug.simulation.scheme import Integrator

    dt = 1e-3
    for r, held in ((2.0, [True, True, False]), (1.0, [True, False, False])):
        p = ModelParams(**LOCAL_EXACT, mu_static_over_kinetic=r)
        cl = Closure.from_params(p, balance=False)
        c = np.array([_c_at_ratio(cl, q) for q in (1.25, 1 / 1.5, 1 / 3)])
        g = c * cl.cos_theta
        F = cl.wall * cl.jamming_pressure(c)
        for v0 in (0.0, 0.01):
            U = cl.conserved(c, np.full(3, v0), np.full(3, cl.P0))
            if engine == "numpy":
                v1 = Integrator(cl, 3, 1.0).sources(U, dt)[1] / c
            else:
                k = _kernel.pack(cl, "periodic", np.zeros(3), cl.P0, 1.0)
                U1 = U.copy()
                _kernel._sources(U1, dt, k)
                v1 = U1[1] / c
            expect = np.maximum(v0 + (g - F) * dt / c, 0.0)
            if v0 == 0.0:
                expect = np.where(held, 0.0, expect)
            np.testing.assert_allclose(v1, expect, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize(("setup", "needle"), [
    ({**COLUMN, "mu_static_over_kinetic": 0.9}, "at least the kinetic one"),
    ({**COLUMN, "mu_static_over_kinetic": math.inf}, "at least the kinetic one"),
    ({**LOCAL_EXACT, "friction_v_eps": 0.01, "mu_static_over_kinetic": 2.0}, "exact"),
    ({"mu_static_over_kinetic": 2.0}, "exact"),
])
def test_static_below_kinetic_friction_is_refused_in_one_line(setup, needle):
    with pytest.raises(ParameterError, match=needle) as e:
        ModelParams(**setup)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("command", ["stability", "simulate"])
def test_the_cli_refuses_static_below_kinetic_friction_in_one_line(tmp_path, capsys, command):
    from test_cli_basics import assert_one_line_error, run

    extra = ["--out", tmp_path / "sim"] if command == "simulate" else []
    code, _, err = run(capsys, command, "--friction-law", "coulomb-janssen", "--jamming",
                       "--mu-static-over-kinetic", "0.5", *extra)
    assert_one_line_error(code, err, "--mu-static-over-kinetic")
    assert not (tmp_path / "sim").exists()


@pytest.mark.parametrize("variant", ["printed", "frozen-friction"])
def test_simulate_says_when_the_model_run_is_stable_by_design(tmp_path, capsys, variant):
    """`grainplug simulate` with its defaults (the printed model, which is stable) ended with "no waves" and no hint
    of why; `stability` says which variant gives the paper's instability, and so does `simulate` now."""
    from test_cli_basics import run

    code, out, _ = run(capsys, "simulate", "--variant", variant, "--length-D", 40, "--cells", 64, "--duration-tc", 20,
                       "--out", tmp_path / "sim")
    assert code == 0
    assert ("--variant frozen-friction gives" in out) == (variant == "printed"), out
