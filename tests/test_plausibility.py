"""Numbers that cannot be right are said so (issue 16, item 5): absurd speeds, saturated tubes."""

from __future__ import annotations

import numpy as np
import pytest

import grainplug as gp
from grainplug.synthetic import SynthConfig
from grainplug.synthetic.render import Renderer


@pytest.fixture(scope="module")
def frames() -> np.ndarray:
    cfg = SynthConfig(n_frames=120, width_px=64, height_px=300, fps=500.0, seed=3, rgb=False, bit_depth=8)
    return np.stack(list(Renderer(cfg).frames()))


def test_a_sound_movie_has_no_plausibility_warning(frames):
    res = gp.analyze(frames, fps=500.0)
    assert not any("faster than" in w or "saturated" in w for w in res.warnings), res.warnings


def test_a_wrong_frame_rate_makes_speeds_absurd_and_is_said(frames):
    res = gp.analyze(frames, fps=500_000.0)  # a thousand times too fast
    text = " ".join(res.warnings)
    assert "faster than grains can fall in a pipe: check the frame rate (--fps)" in text, res.warnings


def test_a_saturated_tube_is_said(frames):
    bright = np.clip(frames.astype(np.int32) * 3, 0, 255).astype(np.uint8)
    res = gp.analyze(bright, fps=500.0)
    assert any("of the tube's pixels are at the camera's top value (saturated)" in w for w in res.warnings)
