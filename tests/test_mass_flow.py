"""The grains' mass flow rate from compactness, grain velocity and celerity (issue 35, item 3)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from grainplug.measures.mass_flow import mass_flow_rate, mean_compactness

RHO, BORE_MM = 2500.0, 3.0
AREA_M2 = math.pi * (BORE_MM * 1e-3) ** 2 / 4.0


def travelling_pattern(*, c_p: float, c_b: float, v_p: float, u: float, plug_mm: float, bubble_mm: float,
                       t_s: np.ndarray, z_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """c(t, z) and v(t, z) of plugs and bubbles travelling rigidly at ``u``, the bubbles' grains at the speed
    that conserves them at the edges."""
    v_b = u + c_p * (v_p - u) / c_b
    wave = plug_mm + bubble_mm
    phase = np.mod(z_mm[None, :] - 1000.0 * u * t_s[:, None], wave)
    plug = phase < plug_mm
    return np.where(plug, c_p, c_b), np.where(plug, v_p, v_b)


@pytest.mark.parametrize("u, v_p, c_b", [(-0.045, 0.005, 0.03), (-0.065, 0.004, 0.01), (-0.03, 0.006, 0.05),
                                         (0.02, 0.03, 0.02)])
def test_the_formula_is_the_flux_through_a_fixed_section(u, v_p, c_b):
    """The formula against the flux c v through a fixed section averaged over many passing plugs, computed
    from the fields themselves (no jump condition used), and the record's mean compactness from the field."""
    c_p, plug_mm, bubble_mm = 0.58, 27.0, 19.0
    t = np.linspace(0.0, 40.0 * (plug_mm + bubble_mm) / (1000.0 * abs(u)), 40001)
    z = np.linspace(0.0, 120.0, 241)
    c, v = travelling_pattern(c_p=c_p, c_b=c_b, v_p=v_p, u=u, plug_mm=plug_mm, bubble_mm=bubble_mm, t_s=t, z_mm=z)
    flux_at_section = RHO * AREA_M2 * 1000.0 * float(np.mean(c[:, 100] * v[:, 100]))  # g/s
    c_mean, c_ci = mean_compactness(c[::50])
    assert c_mean == pytest.approx((c_p * plug_mm + c_b * bubble_mm) / (plug_mm + bubble_mm), abs=0.005)
    q = mass_flow_rate(c_plug=c_p, c_plug_ci95=(c_p - 0.02, c_p + 0.02), v_plug_m_s=v_p,
                       v_plug_ci95_m_s=(v_p - 0.0005, v_p + 0.0005), celerity_m_s=u,
                       celerity_ci95_m_s=(u - 0.001, u + 0.001), c_mean=c_mean, c_mean_ci95=c_ci,
                       bore_mm=BORE_MM, grain_density_kg_m3=RHO)
    assert q.rate_g_s == pytest.approx(flux_at_section, rel=0.01)
    assert q.creep_g_s + q.pattern_g_s == pytest.approx(q.rate_g_s)
    assert q.ci95_g_s[0] < q.rate_g_s < q.ci95_g_s[1]
    assert not q.note


def test_the_interval_is_the_first_order_propagation():
    """The half-width against a Monte Carlo of the inputs drawn within their intervals (normal, 1.96 sd)."""
    args = dict(c_plug=0.58, v_plug_m_s=0.005, celerity_m_s=-0.05, c_mean=0.33)
    cis = dict(c_plug_ci95=(0.55, 0.61), v_plug_ci95_m_s=(0.004, 0.006), celerity_ci95_m_s=(-0.053, -0.047),
               c_mean_ci95=(0.31, 0.35))
    q = mass_flow_rate(**args, **cis, bore_mm=BORE_MM, grain_density_kg_m3=RHO)
    rng = np.random.default_rng(4)
    draws = {k: rng.normal(args[k], (cis[ci][1] - cis[ci][0]) / 2 / 1.96, 200_000)
             for k, ci in zip(args, cis, strict=True)}
    rates = [mass_flow_rate(**{k: float(v[i]) for k, v in draws.items()}, c_plug_ci95=None, v_plug_ci95_m_s=None,
                            celerity_ci95_m_s=None, c_mean_ci95=None, bore_mm=BORE_MM,
                            grain_density_kg_m3=RHO).rate_g_s for i in range(20_000)]
    lo, hi = np.percentile(rates, [2.5, 97.5])
    assert q.ci95_g_s[0] == pytest.approx(lo, rel=0.03)
    assert q.ci95_g_s[1] == pytest.approx(hi, rel=0.03)


def test_without_an_input_there_is_no_rate_and_the_note_says_which():
    q = mass_flow_rate(c_plug=None, c_plug_ci95=None, v_plug_m_s=0.005, v_plug_ci95_m_s=None, celerity_m_s=-0.05,
                       celerity_ci95_m_s=None, c_mean=None, c_mean_ci95=None, bore_mm=BORE_MM,
                       grain_density_kg_m3=RHO, missing="no references given")
    assert q.rate_g_s is None and q.ci95_g_s is None
    assert "compactness" in q.note and "no references given" in q.note


@pytest.mark.parametrize("weighed, warned", [(0.30, False), (0.27, False), (0.40, True), (0.20, True), (None, False)])
def test_a_weighed_rate_outside_the_movies_interval_is_warned_about(weighed, warned):
    from grainplug.campaigns.batch import weighed_disagrees
    from grainplug.warning_codes import codes_of

    rec = {"mass_flow_rate_g_s": weighed, "mass_flow_rate_images_g_s": 0.29,
           "mass_flow_rate_images_ci95_low_g_s": 0.26, "mass_flow_rate_images_ci95_high_g_s": 0.32}
    out = weighed_disagrees(rec)
    assert codes_of(out) == (["mass_flow.disagrees"] if warned else [])
    # no measured rate (no references given): nothing to compare
    assert weighed_disagrees({**rec, "mass_flow_rate_images_ci95_low_g_s": None}) == []
    # the weighing's own interval, when the manifest gives it: disagreeing is beyond both
    if weighed is not None:
        assert codes_of(weighed_disagrees({**rec, "mass_flow_rate_uncertainty_g_s": 0.09})) == []


def _measured(tmp_path, name: str):
    import flux_render as fr

    import grainplug as gp

    scene, seed = fr.case(name)
    movie = tmp_path / ("movie.tif" if scene.fmt == "tif" else "movie.mp4")
    truth = fr.render_movie(movie, scene, seed)
    empty, packed, c_ref = fr.write_references(tmp_path, scene, seed)
    res = gp.analyze(movie, gp.AnalysisParams(mm_per_px=scene.mm_per_px, background=gp.read_background(empty),
                                              packed=gp.read_background(packed), packed_compactness=c_ref))
    return res, truth


FAST_CASE = "flux: creep 5 mm/s, climb 45 mm/s, 250 fps, H.264"
SLOW_CASES = ["flux: creep 4 mm/s, climb 30 mm/s, 250 fps, TIFF", "flux: creep 6 mm/s, climb 65 mm/s, 250 fps, TIFF",
              "flux: oscillating 1 mm at 6 Hz, creep 5 mm/s, climb 30 mm/s, TIFF",
              "flux: shake 1.5 px, creep 5 mm/s, climb 45 mm/s, 250 fps, H.264"]


@pytest.mark.parametrize("name", [FAST_CASE, *(pytest.param(n, marks=pytest.mark.slow) for n in SLOW_CASES)])
def test_the_rate_from_the_movie_is_the_counted_one(tmp_path, name):
    """On an independent particle renderer (tests/flux_render.py: grains creeping in climbing plugs and falling
    through the bubbles, Beer-Lambert light, the truth counted crossing the view's rows), within the issue's
    10 %, its interval holding the count; the summary and the CLI's keys carry it."""
    res, truth = _measured(tmp_path, name)
    q = res.mass_flow
    assert q.rate_g_s == pytest.approx(truth.view_mass_flow_rate_g_s, rel=0.10)
    assert q.ci95_g_s[0] <= truth.view_mass_flow_rate_g_s <= q.ci95_g_s[1]
    s = res.summary
    assert s["mass_flow_rate_g_s"] == pytest.approx(q.rate_g_s, rel=1e-3)
    # the fields beside the simulation's: the compactness, and the grains' velocity where it was measured
    f = res.fields()
    assert float(f["c"].mean()) == pytest.approx(q.mean_compactness, abs=1e-4)
    v = f["v_m_s"].values
    assert np.isfinite(v).sum() >= 500 and np.isfinite(v).mean() < 0.5  # where windows were correlated
    assert float(np.nanmean(v)) == pytest.approx(truth.creep_m_s, rel=0.1)
    assert s["mass_flow_rate_terms_g_s"]["creep"] > 0 and s["mass_flow_rate_terms_g_s"]["pattern"] > 0


def test_without_references_the_summary_says_why_there_is_no_rate(tmp_path):
    import flux_render as fr

    import grainplug as gp

    scene, seed = fr.case(FAST_CASE)
    small = dataclasses.replace(scene, n_frames=120, fmt="tif")
    fr.render_movie(tmp_path / "movie.tif", small, seed)
    s = gp.analyze(tmp_path / "movie.tif", gp.AnalysisParams(mm_per_px=scene.mm_per_px)).summary
    assert s["mass_flow_rate_g_s"] is None and s["mass_flow_rate_ci95_g_s"] is None
    assert "compactness" in s["mass_flow_rate_note"]
