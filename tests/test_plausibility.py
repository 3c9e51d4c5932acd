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
    # the synthetic tube's walls are not a real tube's optics: the model's estimate is not cross-checked
    assert any("the scale comes from the tube model alone" in w and "--tube-outer-diameter-mm" in w
               and "--mm-per-px" in w for w in res.warnings), res.warnings
    assert not any("the scale comes from" in w for w in gp.analyze(frames, fps=500.0, mm_per_px=0.185).warnings)


@pytest.mark.parametrize("width", [64, 44, 36, 30])
def test_a_strip_cropped_close_to_the_tube_is_measured_lengthwise(frames, width):
    # the bore (16.2 px) fills up to 54 % of the strip: still found along the strip, and its width right
    lo = 32 - width // 2
    strip = gp.analyze(np.ascontiguousarray(frames[:, :, lo: lo + width]), fps=500.0)
    assert strip.tube.orientation == "vertical"
    assert strip.bore.diameter_px == pytest.approx(3.0 / 0.185, rel=0.03)


def test_a_tube_that_fills_the_frame_is_said(frames):
    strip = gp.analyze(np.ascontiguousarray(frames[:, :, 24:42]), fps=500.0)  # the bore fills 90 % of 18 px
    assert any("of the frame's width" in w for w in strip.warnings), strip.warnings


def test_a_saturated_tube_is_said(frames):
    bright = np.clip(frames.astype(np.int32) * 3, 0, 255).astype(np.uint8)
    res = gp.analyze(bright, fps=500.0)
    assert any("of the tube's pixels are at the camera's top value (saturated)" in w for w in res.warnings)


@pytest.mark.parametrize(("mm_per_px", "doubted"), [(0.185, False), (0.19, False), (0.06, True), (0.5, True)])
def test_a_given_scale_far_from_the_tube_seen_is_said(frames, mm_per_px, doubted):
    """Given --mm-per-px, the tube found (16 px) is checked against the bore it makes: 0.06 mm/px (a 50 px bore)
    and 0.5 mm/px (6 px) are doubted, the true 0.185 and a 3 % error are not (the tube model's own job)."""
    res = gp.analyze(frames, fps=500.0, mm_per_px=mm_per_px)
    said = [w for w in res.warnings if "the given scale makes its 3 mm bore" in w]
    assert bool(said) == doubted, res.warnings
    assert all("--mm-per-px" in w for w in said)


def test_a_tube_without_plugs_does_not_doubt_a_right_scale():
    """With no plugs the tube is seen where falling grains show it (4 px of a 16 px bore): no reason to doubt
    the given scale; only a tube seen wider than the bore it makes would be."""
    cfg = SynthConfig(n_frames=60, width_px=64, height_px=300, fps=500.0, seed=4, rgb=False, regime="none")
    frames = np.stack(list(Renderer(cfg).frames()))
    res = gp.analyze(frames, fps=500.0, mm_per_px=0.185)
    assert not res.has_plugs
    assert not [w for w in res.warnings if "the given scale makes" in w], res.warnings
