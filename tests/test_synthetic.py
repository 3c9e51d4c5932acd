"""The synthetic renderer: determinism, truth consistency, hard cases render."""

from __future__ import annotations

import json

import numpy as np
import pytest

from grainplug.errors import ParameterError
from grainplug.synthetic import SynthConfig, displacement_mm, synthesize
from grainplug.synthetic.render import Renderer


@pytest.mark.parametrize("fmt", ["tiff", "png", "avi", "ffv1", "h264", "mjpeg", "mraw"])
def test_same_seed_same_bytes(tmp_path, fmt):
    cfg = SynthConfig(n_frames=6, seed=9, rgb=fmt != "mraw", merge_split=True, flicker=0.08)
    a = synthesize(cfg, tmp_path / "a", fmt=fmt)
    b = synthesize(cfg, tmp_path / "b", fmt=fmt)

    def blobs(p):
        files = sorted(p.iterdir()) if p.is_dir() else [p]
        return [f.read_bytes() for f in files]

    assert blobs(a.movie) == blobs(b.movie)
    assert a.truth_json.read_text() == b.truth_json.read_text()
    c = synthesize(SynthConfig(n_frames=6, seed=10, rgb=fmt != "mraw"), tmp_path / "c", fmt=fmt)
    assert blobs(c.movie) != blobs(a.movie)


@pytest.mark.parametrize("regime", ["propagative", "oscillating", "stick-slip"])
def test_displacement_mean_velocity(regime):
    t = np.linspace(0, 10, 100001)
    x = displacement_mm(t, regime=regime, celerity_m_s=-0.04, frequency_hz=5.0, amplitude_mm=2.0,
                        stick_fraction=0.4, phase_rad=1.0)
    assert x[0] == pytest.approx(0.0, abs=1e-9)
    slope = np.polyfit(t, x, 1)[0]
    assert slope == pytest.approx(-40.0, rel=0.01)


def test_stick_slip_stands_still():
    t = np.linspace(0, 1, 10001)
    x = displacement_mm(t, regime="stick-slip", celerity_m_s=0.03, frequency_hz=4.0, amplitude_mm=0,
                        stick_fraction=0.5)
    v = np.gradient(x, t)
    assert np.mean(np.abs(v) < 1e-6) == pytest.approx(0.5, abs=0.02)
    assert np.all(v >= -1e-9)


def test_truth_matches_rendered_image(tmp_path):
    """Edges in truth_edges.csv sit where the rendered column changes brightness."""
    cfg = SynthConfig(n_frames=3, rgb=False, noise_sigma=0, edge_roughness_mm=0.0,
                      falling_grains_per_mm=0.0, seed=11)
    r = Renderer(cfg)
    img = r.render_grey(1)
    col = img[:, cfg.width_px // 2 - 2: cfg.width_px // 2 + 3].mean(axis=1)
    tops, bots = r.plug_edges_mm(1)
    dark = col < 0.5 * (col.max() + col.min())
    s = (np.arange(cfg.height_px) + 0.5) * cfg.mm_per_px
    for top, bot in zip(tops, bots, strict=True):
        inner = (s > top + 0.3) & (s < bot - 0.3)
        outer = ((s > top - 3) & (s < top - 0.3)) | ((s > bot + 0.3) & (s < bot + 3))
        if inner.any():
            assert dark[inner].all()
        if outer.any():
            assert not dark[outer].any()


def test_truth_file(tmp_path):
    res = synthesize(SynthConfig(n_frames=50, seed=1), tmp_path)
    truth = json.loads(res.truth_json.read_text())
    assert truth["regime"] == "propagative"
    assert truth["celerity_m_s"] == -0.05
    assert 25 < truth["plug_length_mm"] < 35
    assert truth["tube_axis_angle_deg"] == pytest.approx(90.0)
    lines = res.truth_edges_csv.read_text().splitlines()
    assert lines[0] == "frame,time_s,plug_id,top_mm,bottom_mm"
    assert len(lines) > 50


def test_orientation_and_no_plugs(tmp_path):
    for direction, angle in (("up", -90.0), ("right", 0.0), ("left", 180.0)):
        cfg = SynthConfig(n_frames=2, flow_direction=direction)
        res = synthesize(cfg, tmp_path / direction)
        assert res.truth["tube_axis_angle_deg"] == pytest.approx(angle)
        frame = Renderer(cfg).frame(0)
        assert frame.shape[:2] == cfg.shape
    res = synthesize(SynthConfig(n_frames=2, regime="none", no_plug_fill="compact"), tmp_path / "c")
    assert res.truth["regime"] == "none" and res.truth["celerity_m_s"] is None


@pytest.mark.parametrize("bad", [dict(tilt_deg=7), dict(fps=0), dict(regime="chaos"),
                                 dict(width_px=20), dict(bit_depth=12)])
def test_bad_config(bad):
    with pytest.raises(ParameterError):
        SynthConfig(**bad)
