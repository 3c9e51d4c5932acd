"""Self-test of tests/flux_render.py: the counted mass flow rate obeys the jump condition, and the light obeys
Beer-Lambert for the rendered compactness (so the renderer's truth can be trusted by the measure's tests)."""

from __future__ import annotations

import math
from dataclasses import replace

import flux_render as fr
import numpy as np
import pytest
import tifffile

SMALL = fr.FluxScene(height_px=320, n_frames=150, plug_mm=(10.0, 16.0), bubble_mm=(6.0, 10.0))


def _jump_g_s(t: fr.FluxTruth, bore_mm: float) -> float:
    """rho_s A (c_p v_p + U (c_mean - c_p)) in g/s, from the truth's parameters (SI)."""
    area_m2 = math.pi * (0.5e-3 * bore_mm) ** 2
    q = t.c_plug * t.creep_m_s + t.celerity_m_s * (t.mean_compactness_at_section - t.c_plug)
    return fr.RHO_S * area_m2 * q * 1e3


@pytest.mark.parametrize(("scene", "seed"), [
    (SMALL, 0),
    (replace(SMALL, creep_mm_s=4.0, celerity_mm_s=-65.0, c_bubble=0.04), 1),
    (replace(SMALL, oscillation_mm=1.0, oscillation_hz=6.0, celerity_mm_s=-30.0, c_bubble=0.02), 2),
])
def test_counted_flux_obeys_the_jump_condition(scene: fr.FluxScene, seed: int) -> None:
    _, t = fr.render_frames(scene, seed)
    n = t.crossings_down - t.crossings_up
    assert n > 1000
    expected = _jump_g_s(t, scene.bore_mm) + t.oscillation_mass_flow_rate_g_s
    assert t.jump_mass_flow_rate_g_s == pytest.approx(_jump_g_s(t, scene.bore_mm))
    # the net count is Poisson (the grains' labels are): 4 standard deviations
    tol = 4.0 * math.sqrt(n) * t.grain_mass_g / t.duration_s
    assert abs(t.mass_flow_rate_g_s - expected) < tol, (t.mass_flow_rate_g_s, expected, tol)
    # the compactness counted in a 2 mm slab about the section agrees with the pattern's time fraction there
    # (within the slab's end effects over this short record and the grains' sampling)
    assert t.counted_compactness_at_section == pytest.approx(t.mean_compactness_at_section, abs=0.035)
    # mass conservation at the edges sets the falling grains' speed
    assert t.c_bubble * (t.fall_m_s - t.celerity_m_s) == pytest.approx(t.c_plug * (t.creep_m_s - t.celerity_m_s))
    if scene.oscillation_mm == 0:
        assert t.crossings_up == 0


def test_a_steady_column_without_flux_counts_zero() -> None:
    """Grains creeping at the celerity (no exchange at the edges) cross the section only with the pattern."""
    scene = replace(SMALL, creep_mm_s=0.0, celerity_mm_s=0.0, c_bubble=0.03)
    _, t = fr.render_frames(scene, 3)
    assert t.crossings_down == t.crossings_up == 0
    assert t.mass_flow_rate_g_s == 0.0


def _core(scene: fr.FluxScene) -> tuple[np.ndarray, np.ndarray]:
    """Columns within half the bore's radius of the axis, and their chord (mm)."""
    x = (np.arange(scene.width_px) + 0.5 - 0.5 * scene.width_px) * scene.mm_per_px
    r = 0.5 * scene.bore_mm
    cols = np.abs(x) < 0.5 * r
    return cols, 2.0 * np.sqrt(r ** 2 - x[cols] ** 2)


def test_light_in_plugs_and_bubbles_follows_beer_lambert() -> None:
    scene = SMALL
    frames, t = fr.render_frames(scene, 4)
    empty = fr.empty_image(scene, 4).astype(float)
    cols, chord = _core(scene)
    tau = -np.log(np.clip(frames[..., cols].astype(float), 0.5, None) / empty[None][..., cols])
    # away from the plug edges (two grains either side)
    m = t.plug_mask
    grow = int(math.ceil(2 * scene.grain_mm / scene.mm_per_px))
    inner = m.copy()
    outer = ~m
    for s in range(1, grow + 1):
        inner[:, s:] &= m[:, :-s]
        inner[:, :-s] &= m[:, s:]
        outer[:, s:] &= ~m[:, :-s]
        outer[:, :-s] &= ~m[:, s:]
    assert inner.sum() > 20 * scene.n_frames and outer.sum() > 20 * scene.n_frames
    expected_per_mm = t.sigma / scene.grain_mm
    plug_tau = tau[inner].mean(axis=0)                  # per core column (the texture's own scatter: ~4 %)
    assert float(np.mean(plug_tau / chord)) == pytest.approx(expected_per_mm * scene.c_plug, rel=0.03)
    bubble_tau = tau[outer].mean(axis=0)
    assert bubble_tau.mean() / chord.mean() == pytest.approx(expected_per_mm * scene.c_bubble, rel=0.15)
    # the packed chord at the centre transmits what the scene asked for (through the mean optical depth)
    centre = float(np.exp(-plug_tau[len(plug_tau) // 2]))
    assert centre == pytest.approx(scene.packed_centre_transmission, abs=0.02)
    assert 0.15 <= centre <= 0.35


def test_references_give_the_packed_compactness(tmp_path) -> None:
    scene = SMALL
    e_path, p_path, c = fr.write_references(tmp_path, scene, 5)
    empty, packed = tifffile.imread(e_path), tifffile.imread(p_path)
    assert empty.shape == packed.shape == (scene.height_px, scene.width_px)
    assert empty.dtype == packed.dtype == np.uint8
    assert c == pytest.approx(scene.c_plug, abs=0.01)
    cols, chord = _core(scene)
    sigma = -math.log(scene.packed_centre_transmission) * scene.grain_mm / (scene.c_plug * scene.bore_mm)
    tau = -np.log(packed[:, cols].astype(float) / empty[:, cols].astype(float)).mean(axis=0)
    assert float(np.mean(tau / chord)) == pytest.approx(sigma / scene.grain_mm * c, rel=0.03)
    assert (packed[:, cols] < empty[:, cols]).mean() > 0.95


@pytest.mark.parametrize("fmt", ["tif", "h264"])
def test_movies_are_written_readably(tmp_path, fmt: str) -> None:
    scene = replace(SMALL, n_frames=12, fmt=fmt)
    path = tmp_path / ("m.tif" if fmt == "tif" else "m.mp4")
    truth = fr.render_movie(path, scene, 6)
    assert truth.duration_s == pytest.approx(11 / scene.fps)
    if fmt == "tif":
        with tifffile.TiffFile(path) as tif:
            assert tif.asarray().shape == (12, scene.height_px, scene.width_px)
            assert 1.0 / tif.imagej_metadata["finterval"] == pytest.approx(scene.fps)
    else:
        av = pytest.importorskip("av")
        with av.open(str(path)) as c:
            got = [f.to_ndarray(format="gray") for f in c.decode(video=0)]
        assert len(got) == 12 and got[0].shape == (scene.height_px, scene.width_px)


def test_cases_span_the_issue_targets() -> None:
    for name, scene, _seed in fr.CASES + fr.HELD_OUT:
        assert 4.0 <= scene.creep_mm_s <= 6.0, name
        assert -65.0 <= scene.celerity_mm_s <= -30.0, name
        assert 250.0 <= scene.fps <= 500.0, name
        assert 500.0 <= scene.fall_mm_s <= 1500.0, name
        assert 0.01 <= scene.c_bubble <= 0.05, name
        assert 0.15 <= scene.packed_centre_transmission <= 0.35, name
        assert fr.case(name)[0] == scene
    fmts = {s.fmt for _, s, _ in fr.CASES}
    assert fmts == {"tif", "h264"}
    assert any(s.shake_px >= 1.5 for _, s, _ in fr.CASES)
    assert any(s.oscillation_mm > 0 for _, s, _ in fr.CASES)


def test_the_view_averaged_count_is_the_section_count_averaged_over_sections():
    """Averaged over the view, the counted flux is the jump-condition flux with the view's mean compactness: on
    a record long enough for one section's count to settle, the two counts agree."""
    scene = fr.FluxScene(height_px=200, n_frames=1200, celerity_mm_s=-60.0, plug_mm=(6.0, 10.0),
                         bubble_mm=(4.0, 8.0), grain_mm=0.4)
    _, truth = fr.render_frames(scene, 3)
    assert truth.view_mass_flow_rate_g_s == pytest.approx(truth.mass_flow_rate_g_s, rel=0.05)
