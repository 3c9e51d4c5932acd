"""The flow's direction from the grains falling through the bubbles, at any frame rate (issue 34, item 6)."""

from __future__ import annotations

import pytest

import grainplug as gp
from grainplug.synthetic import SynthConfig, synthesize


@pytest.mark.parametrize("direction", ["up", "left"])
def test_the_direction_is_found_at_5000_fps(tmp_path, direction):
    """At 5000 fps the grains move under 2 px between frames; a movie whose flow runs up (or left) is read so,
    and its celerity keeps its sign (negative: climbing against the flow)."""
    cfg = SynthConfig(n_frames=240, fps=5000.0, flow_direction=direction, seed=5, height_px=400,
                      celerity_m_s=-0.5, noise_sigma=2)
    synthesize(cfg, tmp_path / "m", fmt="tiff")
    res = gp.analyze(tmp_path / "m" / "movie.tif", gp.AnalysisParams(mm_per_px=cfg.mm_per_px))
    assert res.flow_direction == direction
    assert res.falling_grain_speed_m_s == pytest.approx(cfg.falling_speed_m_s, rel=0.1)
    assert res.motion.celerity_m_s == pytest.approx(cfg.celerity_m_s, rel=0.05)
