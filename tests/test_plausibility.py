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


def test_a_scale_from_the_tube_is_flagged_and_its_doubts_named(frames):
    res = gp.analyze(frames, fps=500.0)
    assert any("the scale comes from the tube's apparent inner width" in w for w in res.warnings)
    assert not any("apparent inner width" in w for w in gp.analyze(frames, fps=500.0, mm_per_px=0.185).warnings)
    # cropped close to the tube, its width reads 12.6 px instead of 16.2: flagged as too few pixels
    strip = gp.analyze(np.ascontiguousarray(frames[:, :, 10:54]), fps=500.0)
    assert any("the tube is only 12." in w and "px wide" in w for w in strip.warnings), strip.warnings


def test_a_saturated_tube_is_said(frames):
    bright = np.clip(frames.astype(np.int32) * 3, 0, 255).astype(np.uint8)
    res = gp.analyze(bright, fps=500.0)
    assert any("of the tube's pixels are at the camera's top value (saturated)" in w for w in res.warnings)
