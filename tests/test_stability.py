"""The 1D model's stability analysis, checked against independent computations."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import sympy as sp

from grainplug.errors import ParameterError
from grainplug.stability import (
    ModelParams,
    analyze_stability,
    dispersion_coefficients,
    max_growth,
    normal_mode_matrix,
    roots,
    sweep,
)

PAPER = ModelParams()


# -- symbolic ---------------------------------------------------------------
def _printed_symbols():
    w, k, c0, kap, mu, B, g, th = sp.symbols("omega k c0 kappa mu_s B1 gamma theta")
    return w, k, c0, kap, mu, B, g, th


def test_det_of_printed_matrix_is_printed_cubic():
    """sympy: det(eq. 'eigenvalue') == eq. 'det', term by term."""
    w, k, c0, kap, mu, B, g, th = _printed_symbols()
    j = sp.I
    M = sp.Matrix([[j * k - j * w, j * k * c0, 0],
                   [-sp.cos(th), -j * w * c0 + j * k * c0 + j * k / kap + 4 * mu, j * k],
                   [0, g / (1 - c0) * j * k, -j * w + j * k + B * k**2]])
    printed = (j * c0 * w**3 + w**2 * (k * (-3 * j * c0 - j / kap) - k**2 * c0 * B - 4 * mu)
               + w * (k**3 * (2 * c0 * B + B / kap) + j * k**2 * (2 / kap - g / (1 - c0) + 3 * c0 - 4 * mu * B)
                      + k * (c0 * sp.cos(th) + 8 * mu))
               + j * k**3 * (-c0 - 1 / kap + 4 * mu * B + c0 * sp.cos(th) * B + g / (1 - c0))
               + k**2 * (-4 * mu - c0 * sp.cos(th)) + B * k**4 * (-1 / kap - c0))
    assert sp.simplify(sp.expand(M.det() - printed)) == 0


def test_linearisation_gives_printed_matrix():
    """sympy: linearising the dimensionless eqs (mass2, motion3, pressure3) about
    c0, v*=1, P*=1 with normal modes gives the printed matrix."""
    z, t, eps = sp.symbols("z t epsilon")
    w, k, c0, kap, mu, B, g, th = _printed_symbols()
    ch, vh, ph = sp.symbols("chat vhat phat")
    e = sp.exp(sp.I * (k * z - w * t))
    c = c0 + eps * ch * e
    v = 1 + eps * vh * e
    P = 1 + eps * ph * e
    mass = sp.diff(c, t) + c * sp.diff(v, z) + v * sp.diff(c, z)
    motion = (c * sp.diff(v, t) + c * v * sp.diff(v, z) - c * sp.cos(th) + sp.diff(P, z)
              + v / kap * sp.diff(v, z) + 2 * mu * v**2)
    pressure = sp.diff(P, t) + v * sp.diff(P, z) + g * P / (1 - c) * sp.diff(v, z) - B * sp.diff(P, z, 2)
    rows = []
    for eq in (mass, motion, pressure):
        lin = sp.simplify(sp.diff(eq, eps).subs(eps, 0) / e)
        rows.append([sp.expand(lin).coeff(x) for x in (ch, vh, ph)])
    M = sp.Matrix(rows)
    printed = sp.Matrix([[sp.I * k - sp.I * w, sp.I * k * c0, 0],
                         [-sp.cos(th), -sp.I * w * c0 + sp.I * k * c0 + sp.I * k / kap + 4 * mu, sp.I * k],
                         [0, g / (1 - c0) * sp.I * k, -sp.I * w + sp.I * k + B * k**2]])
    assert sp.simplify(M - printed) == sp.zeros(3, 3)
    # and the O(1) part of the momentum equation does not vanish: the base state is not steady
    base = sp.simplify(motion.subs(eps, 0))
    assert sp.simplify(base - (-c0 * sp.cos(th) + 2 * mu)) == 0


# -- numerics against a second method ------------------------------------------
@pytest.mark.parametrize("variant", ["printed", "frozen-friction"])
@pytest.mark.parametrize("theta", [0.0, 5.0])
def test_eigen_roots_match_numpy_roots_of_cubic(variant, theta):
    p = ModelParams(variant=variant, theta_deg=theta)
    k = np.linspace(1e-3, 3, 400)
    w = roots(p, k)
    coef = dispersion_coefficients(p, k)
    for i in range(len(k)):
        ref = np.roots(coef[i])
        got = w[i]
        # same multiset of roots
        for r in ref:
            assert np.min(np.abs(got - r)) < 1e-9 * max(1, abs(r))
        # each root annuls the determinant of the matrix
        dets = np.linalg.det(normal_mode_matrix(p, k[i], got))
        assert np.all(np.abs(dets) < 1e-9 * (1 + np.abs(got) ** 3))


def test_roots_are_continuous_along_k():
    k = np.linspace(1e-3, 3, 20000)
    w = roots(ModelParams(variant="frozen-friction"), k)
    jumps = np.abs(np.diff(w, axis=0)).max(axis=0)
    assert np.all(jumps < 0.01)


def test_vectorised_many_wavenumbers():
    k = np.linspace(1e-3, 3, 100_000)
    w = roots(PAPER, k)
    assert w.shape == (100_000, 3)
    assert np.all(np.isfinite(w))


# -- analytic limits -------------------------------------------------------------
def test_long_wave_limit():
    """k* -> 0: two neutral roots and the friction-damped one, omega = -4 i b mu_s / c0."""
    p = PAPER
    w = roots(p, np.array([1e-7]))[0]
    damped = w[np.argmin(w.imag)]
    assert damped == pytest.approx(-4j * p.b * p.mu_s / p.c0, abs=1e-5)
    neutral = np.sort(np.abs(w))[:2]
    assert np.all(neutral < 1e-5)


def test_no_diffusion_characteristic_speeds():
    """B1* = 0, mu_s = 0: at large k* the phase speeds tend to the characteristics of
    the hyperbolic system, 1 and 1 - x with c0 x^2 + x/kappa - gamma/(1 - c0) = 0."""
    p = ModelParams(B1_star_override=0.0, mu_s=0.0)
    kbig = 1e5
    w = roots(p, np.array([kbig]), track=False)[0]
    speeds = np.sort(w.real / kbig)
    x = np.roots([p.c0, 1 / p.kappa, -p.gamma / (1 - p.c0)])
    expected = np.sort(np.concatenate([[1.0], 1 - x]))
    np.testing.assert_allclose(speeds, expected, rtol=1e-4)
    # and the growth rates stay bounded (no k-dependence at leading order)
    assert np.all(np.abs(w.imag) < 10)


def test_diffusion_dominated_short_waves():
    """Large k*: the pressure root decays as -B1* k*^2."""
    p = PAPER
    k = 300.0
    w = roots(p, np.array([k]), track=False)[0]
    assert w.imag.min() == pytest.approx(-p.B1_star * k**2, rel=1e-2)


def test_no_friction_is_the_frozen_variant():
    k = np.linspace(1e-3, 2, 50)
    a = roots(ModelParams(mu_s=0.0), k)
    b = roots(ModelParams(variant="frozen-friction"), k)
    np.testing.assert_allclose(a, b)


def test_B1_star_formula():
    """B1* = gamma rho_s g^1/2 d^2 (1-c0)^2 / (180 mu_a c0^2 D^1/2), computed by hand."""
    p = PAPER
    hand = 1.4 * 2500 * math.sqrt(9.81) * (225e-6) ** 2 * 0.45**2 / (180 * 1.8e-5 * 0.55**2 * math.sqrt(3e-3))
    assert p.B1_star == pytest.approx(hand, rel=1e-12)
    assert p.B1_star == pytest.approx(2.0934, abs=1e-3)
    assert p.P_c_pa == pytest.approx(2500 * 9.81 * 3e-3)
    assert p.t_c_s == pytest.approx(math.sqrt(3e-3 / 9.81))
    assert p.v_c_m_s == pytest.approx(math.sqrt(9.81 * 3e-3))


# -- what the model says -----------------------------------------------------------------
def test_printed_model_is_stable_with_paper_parameters():
    """The honest reproduction: with the printed equations and the paper's inputs no k*
    in (0, 3] grows (the paper claims a long-wave instability)."""
    res = analyze_stability(PAPER, k_min=1e-3, k_max=3.0, n_k=3000)
    assert res.most_unstable is None
    assert res.cutoff_k == []
    assert res.omega.imag.max() <= 1e-12


def test_frozen_friction_reproduces_the_claim():
    res = analyze_stability(ModelParams(variant="frozen-friction"), k_min=1e-3, k_max=3.0, n_k=3000)
    m = res.most_unstable
    assert m is not None
    assert 0.1 < m.k < 0.25  # the paper: k* ~ 0.2
    assert len(res.cutoff_k) == 1 and 0.5 < res.cutoff_k[0] < 0.75  # the paper: ~ 0.6
    assert max_growth(res.params, res.cutoff_k[0]) == pytest.approx(0.0, abs=1e-9)
    assert m.wavelength_over_diameter == pytest.approx(2 * math.pi / m.k)
    assert res.cutoff_wavelength_over_diameter[0] == pytest.approx(2 * math.pi / res.cutoff_k[0])
    # the refined maximum beats the grid
    assert m.growth_rate >= res.omega.imag.max() - 1e-12


def test_sweep_over_grain_diameter():
    rows = sweep(ModelParams(variant="frozen-friction"), "grain_diameter_um", [110, 225, 300],
                 n_k=800)
    ks = [r["most_unstable_k"] for r in rows]
    assert ks[0] > ks[1] > ks[2]  # bigger grains, more permeable: longer waves
    assert rows[1]["B1_star"] == pytest.approx(PAPER.B1_star)


def test_bad_inputs():
    for bad in (dict(c0=1.2), dict(kappa=0), dict(variant="magic"), dict(diameter_mm=-1)):
        with pytest.raises(ParameterError):
            ModelParams(**bad)


# -- CLI -------------------------------------------------------------------------------------
def test_cli_json_and_plot(tmp_path, capsys):
    from grainplug.cli import main

    fig = tmp_path / "fig9.png"
    code = main(["stability", "--json", "--n-k", "200", "--plot", str(fig)])
    out, err = capsys.readouterr()
    assert code == 0, err
    d = json.loads(out)
    for key in ("B1_star", "k", "omega_real", "omega_imag", "most_unstable", "cutoff_k", "inputs"):
        assert key in d
    assert len(d["omega_real"]) == 3 and len(d["omega_imag"][0]) == 200 == len(d["k"])
    assert d["most_unstable"] is None and d["inputs"]["c0"] == 0.55
    assert fig.stat().st_size > 10_000
    code = main(["stability", "--variant", "frozen-friction", "--json", "--n-k", "300"])
    d = json.loads(capsys.readouterr()[0])
    assert set(d["most_unstable"]) >= {"k", "growth_rate", "phase_speed", "wavelength_over_diameter"}
    code = main(["stability"])
    out = capsys.readouterr()[0]
    assert "does not give the paper's long-wave instability" in out
    code = main(["stability", "--B1-star", "0.5", "--variant", "frozen-friction", "--json", "--n-k", "100"])
    assert json.loads(capsys.readouterr()[0])["B1_star"] == 0.5


def test_cli_bad_input(capsys):
    from grainplug.cli import main

    code = main(["stability", "--c0", "1.5"])
    err = capsys.readouterr()[1]
    assert code == 2 and err.startswith("error: ") and "c0" in err
    code = main(["stability", "--k-min", "2", "--k-max", "1"])
    assert code == 2


def test_cli_sweep(tmp_path, capsys):
    from grainplug.cli import main

    fig = tmp_path / "sweep.png"
    code = main(["stability", "--variant", "frozen-friction", "--sweep", "grain_diameter_um=110:300:3",
                 "--n-k", "600", "--json", "--plot", str(fig)])
    out, err = capsys.readouterr()
    assert code == 0, err
    d = json.loads(out)
    rows = d["rows"]
    assert [r["grain_diameter_um"] for r in rows] == [110.0, 205.0, 300.0]
    lam = [r["most_unstable_wavelength_over_diameter"] for r in rows]
    assert lam[0] < lam[1] < lam[2]
    assert fig.stat().st_size > 5000
    assert main(["stability", "--sweep", "c0=0.5"]) == 2
    assert main(["stability", "--sweep", "size=1:2:3"]) == 2


# -- set-ups: every switch derived symbolically ------------------------------------
def _general_linearisation(law: str):
    """sympy: the dimensionless equations with friction law ``law`` and a jamming pressure
    linearised about (c0, v0, P0); the matrix M(k, omega) and the O(1) residual of the momentum
    equation, as functions of symbols (``Fr = 0``: no jamming)."""
    z, t, eps = sp.symbols("z t epsilon")
    w, k, c0, kap, mu, B1, g, th = _printed_symbols()
    v0, P0, b = sp.symbols("v0 P0 b", positive=True)
    Fr, cmin, cmax = sp.symbols("Fr c_min c_max", positive=True)
    ch, vh, ph = sp.symbols("chat vhat phat")
    e = sp.exp(sp.I * (k * z - w * t))
    c = c0 + eps * ch * e
    v = v0 + eps * vh * e
    P = P0 + eps * ph * e
    F0 = 2 * b * mu * v0**2  # the base friction the Coulomb laws hold or scale
    # |v| = v sign(v0) near the base state (the perturbation is a complex normal mode: Abs would
    # take its modulus)
    F = {"v2": 2 * b * mu * v**2, "v|v|": 2 * b * mu * v * (v * sp.sign(v0)), "coulomb-frozen": F0,
         "coulomb-weight": F0 * c / c0}[law]
    # B is proportional to P and to (1 - c)^2 / c^2 (Carman-Kozeny); B1 is its value at P* = 1, c = c0
    B = B1 * P * ((1 - c) / c) ** 2 / ((1 - c0) / c0) ** 2
    mass = sp.diff(c, t) + c * sp.diff(v, z) + v * sp.diff(c, z)
    p_jam = Fr * (c - cmin) ** 2 / (cmax - c) ** 5  # Johnson & Jackson, above c_min (dimensionless Fr)
    motion = (c * sp.diff(v, t) + c * v * sp.diff(v, z) - c * sp.cos(th) + sp.diff(P, z)
              + v / kap * sp.diff(v, z) + F + sp.diff(p_jam, z))
    pressure = sp.diff(P, t) + v * sp.diff(P, z) + g * P / (1 - c) * sp.diff(v, z) - B * sp.diff(P, z, 2)
    rows = []
    for eq in (mass, motion, pressure):
        # first order in epsilon, at z = t = 0 (the mode's factor is then 1): linear in the amplitudes
        # (coefficients by differentiation: expanding would lose digits near c_max)
        lin = sp.diff(eq, eps).subs(eps, 0).subs({z: 0, t: 0})
        rows.append([sp.diff(lin, x) for x in (ch, vh, ph)])
    residual = motion.subs(eps, 0)
    return sp.Matrix(rows), residual, (w, k, c0, kap, mu, B1, g, th, v0, P0, b, Fr, cmin, cmax)


SETUPS = [(law, vel, pres) for law in ("v2", "v|v|", "coulomb-frozen", "coulomb-weight")
          for vel in ("printed", "balanced") for pres in (None, 101_325.0, 2_000.0)
          if not (vel == "balanced" and law.startswith("coulomb"))]


@pytest.mark.parametrize("law", ["v2", "v|v|", "coulomb-frozen", "coulomb-weight"])
def test_every_setup_is_the_symbolic_linearisation(law):
    """The matrix solved for each friction law, base velocity and base pressure equals sympy's
    linearisation of the equations with that set-up, at random (k, omega); so does the residual."""
    M, residual, syms = _general_linearisation(law)
    c0, mu, th, v0, b, Fr, cmin, cmax = (syms[i] for i in (2, 4, 7, 8, 10, 11, 12, 13))
    f = sp.lambdify(syms, M, "numpy")
    fr = sp.lambdify((c0, th, mu, v0, b, Fr, cmin, cmax), residual, "numpy")
    rng = np.random.default_rng(3)
    for l_, vel, pres in SETUPS:
        if l_ != law:
            continue
        for jam in (False, True):
            p = ModelParams(friction_law=law, base_velocity=vel, base_pressure_pa=pres, theta_deg=3.0, b=1.2,
                            jamming=jam, jamming_fr_pa=0.07, jamming_c_max=0.63)
            fr_star = 0.07 / p.P_c_pa if jam else 0.0
            for _ in range(3):
                kk = float(rng.uniform(0.01, 3))
                ww = complex(rng.normal(), rng.normal())
                expected = np.array(f(ww, kk, p.c0, p.kappa, p.mu_s, p.B1_star, p.gamma, math.radians(p.theta_deg),
                                      p.v0_star, p.P0_star, p.b, fr_star, 0.50, 0.63), complex)
                assert np.allclose(normal_mode_matrix(p, kk, ww), expected, rtol=1e-12, atol=1e-12), (
                    law, vel, pres, jam)
            assert p.base_state_residual == pytest.approx(
                float(fr(p.c0, math.radians(p.theta_deg), p.mu_s, p.v0_star, p.b, fr_star, 0.50, 0.63)), abs=1e-12)


def test_balanced_base_velocity_is_steady_and_stays_stable():
    p = ModelParams(base_velocity="balanced")
    assert p.base_state_residual == pytest.approx(0.0, abs=1e-12)
    assert p.v0_star == pytest.approx(math.sqrt(0.55 / (2 * math.tan(math.radians(32)))), rel=1e-12)
    assert analyze_stability(p, k_min=1e-4, k_max=3.0, n_k=4000).stable


def test_atmospheric_base_pressure_sends_the_frozen_variant_beyond_the_pipe():
    """With the air at atmospheric pressure (1377 P_c), the frozen-friction variant's unstable
    band moves to wavelengths beyond 3000 D (9 m in a 3 mm pipe)."""
    printed = analyze_stability(ModelParams(variant="frozen-friction"), k_min=1e-5, k_max=3.0, n_k=20_000)
    atm = ModelParams(variant="frozen-friction", base_pressure_pa=101_325.0)
    assert atm.P0_star == pytest.approx(101_325.0 / atm.P_c_pa) and 1370 < atm.P0_star < 1385
    r = analyze_stability(atm, k_min=1e-5, k_max=3.0, n_k=20_000)
    assert r.most_unstable is not None and printed.most_unstable is not None
    assert min(r.cutoff_wavelength_over_diameter) > 3000 > 10 * printed.most_unstable.wavelength_over_diameter


def test_setup_switches_are_checked():
    with pytest.raises(ParameterError, match="no velocity balances"):
        ModelParams(friction_law="coulomb-frozen", base_velocity="balanced")
    with pytest.raises(ParameterError, match="one or the other"):
        ModelParams(variant="frozen-friction", friction_law="v2")
    with pytest.raises(ParameterError, match="base pressure"):
        ModelParams(base_pressure_pa=-5.0)
    with pytest.raises(ParameterError, match="printed cubic"):
        dispersion_coefficients(ModelParams(base_pressure_pa=101_325.0), np.array([0.1]))
    caveats = " ".join(ModelParams(variant="frozen-friction").caveats())
    assert "not steady" in caveats and "74 Pa" in caveats and "contradicts" in caveats


def test_cli_setup_switches(capsys):
    from grainplug.cli import main

    code = main(["stability", "--variant", "frozen-friction", "--base-pressure", "atmospheric", "--k-min", "1e-5",
                 "--n-k", "20000", "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    d = json.loads(out)
    setup = d["setup"]
    assert setup["friction_law"] == "coulomb-frozen" and setup["base_pressure_pa"] == pytest.approx(101_325.0)
    assert setup["B_star"] == pytest.approx(2883, rel=2e-3)  # the "about 2880"
    assert min(d["cutoff_wavelength_over_diameter"]) > 3000
    assert any("contradicts" in c for c in setup["caveats"])
    code = main(["stability", "--base-velocity", "balanced"])
    out = capsys.readouterr()[0]
    assert code == 0 and "= +0.0000 (0 if the base state were steady)" in out and "every k*" in out
    code = main(["stability", "--jamming", "--variant", "frozen-friction", "--json", "--n-k", "3000"])
    d = json.loads(capsys.readouterr()[0])
    assert code == 0 and d["setup"]["jamming"] and d["setup"]["jamming_slope"] == pytest.approx(27.49, rel=1e-3)
    assert d["most_unstable"]["wavelength_over_diameter"] == pytest.approx(71.9, rel=0.01)
    for bad, word in ((["--base-pressure", "lots"], "--base-pressure"),
                      (["--friction-law", "coulomb-weight", "--base-velocity", "balanced"], "no velocity")):
        code = main(["stability", *bad])
        err = capsys.readouterr()[1]
        assert code == 2 and err.startswith("error: ") and word in err and len(err.strip().splitlines()) == 1


def test_jamming_pressure_switch():
    """Off by default; on, it adds its slope at c0 (steep near random close packing) and is stated."""
    off, on = ModelParams(), ModelParams(jamming=True)
    assert off.jamming_slope == 0.0 and off.is_printed and not on.is_printed
    assert on.jamming_slope == pytest.approx(0.05 * (2 * 0.05 / 0.09**5 + 5 * 0.05**2 / 0.09**6) / on.P_c_pa)
    assert ModelParams(jamming=True, c0=0.45).jamming_slope == 0.0  # below c_min: no lasting contacts
    assert any("Johnson & Jackson" in c for c in on.caveats())
    with pytest.raises(ParameterError, match="c_max"):
        ModelParams(jamming=True, c0=0.66)


def test_a_largest_growth_at_the_end_of_the_range_is_not_called_most_unstable(capsys):
    """Growth still rising at k_max (Coulomb friction following the weight) or at k_min (frozen friction at
    atmospheric pressure) was reported as "most unstable" with the range's end as its wavelength; it is flagged,
    with a warning, and a wider range finds the interior maximum (k* = 0.00029, as docs/stability.md says)."""
    from grainplug.cli import main

    short = analyze_stability(ModelParams(friction_law="coulomb-weight")).most_unstable
    assert short.at_range_edge == "k_max" and short.k == pytest.approx(3.0)
    atm = ModelParams(variant="frozen-friction", base_pressure_pa=101_325.0)
    res = analyze_stability(atm)
    assert res.most_unstable.at_range_edge == "k_min" and res.warnings[0].endswith("move its lower end (k_min=)")
    wide = analyze_stability(atm, k_min=1e-5).most_unstable
    assert wide.at_range_edge is None and wide.k == pytest.approx(2.9e-4, rel=0.02)
    frozen = analyze_stability(ModelParams(variant="frozen-friction"))
    assert frozen.most_unstable.at_range_edge is None and frozen.warnings == []
    # the edge is judged on the refined maximum: an interior one between the first two grid points is the model's
    coarse = analyze_stability(atm, k=np.linspace(1e-5, 3.0, 50)).most_unstable
    assert coarse.at_range_edge is None
    assert main(["stability", "--friction-law", "coulomb-weight"]) == 0
    out, err = capsys.readouterr()
    assert "largest in range" in out and "most unstable" not in out and "warning: the growth rate is largest" in err
    assert err.rstrip().endswith("(--k-max)")  # the library's keyword, named as the command's flag
    assert main(["stability", "--friction-law", "coulomb-weight", "--sweep", "c0=0.5:0.6:3", "--json"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["rows"][0]["most_unstable_at_range_edge"] == "k_max" and "largest at an end" in err


def test_absurd_model_inputs_are_refused_or_said():
    """Grains wider than the pipe are refused (B1* = 1034 was given); a c0 above random close packing and
    fewer than 6 grains across the pipe are caveats."""
    with pytest.raises(ParameterError, match="smaller than the pipe"):
        ModelParams(grain_diameter_um=5000)
    assert any("random close packing" in c for c in ModelParams(c0=0.99).caveats())
    assert any("D/d = 3" in c for c in ModelParams(grain_diameter_um=1000).caveats())
    assert not any("D/d" in c or "close packing" in c for c in PAPER.caveats())
