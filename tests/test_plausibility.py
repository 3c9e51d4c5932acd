"""Numbers that cannot be right are said so (issue 16, item 5): absurd speeds, saturated tubes."""

from __future__ import annotations

import numpy as np
import pytest
from warned import codes, of_code

import grainplug as gp
from grainplug.synthetic import SynthConfig
from grainplug.synthetic.render import Renderer


@pytest.fixture(scope="module")
def frames() -> np.ndarray:
    cfg = SynthConfig(n_frames=120, width_px=64, height_px=300, fps=500.0, seed=3, rgb=False, bit_depth=8)
    return np.stack(list(Renderer(cfg).frames()))


def test_a_sound_movie_has_no_plausibility_warning(frames):
    res = gp.analyze(frames, fps=500.0)
    assert not codes(res) & {"plugs.implausible_speed", "light.saturated"}, res.warnings


def test_a_wrong_frame_rate_makes_speeds_absurd_and_is_said(frames):
    res = gp.analyze(frames, fps=500_000.0)  # a thousand times too fast
    said = of_code(res, "plugs.implausible_speed")
    assert said and all("check the frame rate (fps=)" in w for w in said), res.warnings
    assert any(f"the plugs move at {res.celerity_m_s:.3g} m/s" in w for w in said), res.warnings  # not the grains' only


def test_a_scale_from_the_tube_is_flagged_and_its_doubts_named(frames):
    res = gp.analyze(frames, fps=500.0)
    # the synthetic tube's walls are not a real tube's optics: the model's estimate is not cross-checked
    [said] = of_code(res, "scale.model_alone")
    assert "tube_outer_diameter_mm=" in said and "mm_per_px=" in said, res.warnings
    given = gp.analyze(frames, fps=500.0, mm_per_px=0.185)
    assert not [c for c in codes(given) if c.startswith("scale.")], given.warnings


@pytest.mark.parametrize("width", [64, 44, 36, 30])
def test_a_strip_cropped_close_to_the_tube_is_measured_lengthwise(frames, width):
    # the bore (16.2 px) fills up to 54 % of the strip: still found along the strip, and its width right
    lo = 32 - width // 2
    strip = gp.analyze(np.ascontiguousarray(frames[:, :, lo: lo + width]), fps=500.0)
    assert strip.tube.orientation == "vertical"
    assert strip.bore.diameter_px == pytest.approx(3.0 / 0.185, rel=0.03)


def test_a_tube_that_fills_the_frame_is_said(frames):
    strip = gp.analyze(np.ascontiguousarray(frames[:, :, 24:42]), fps=500.0)  # the bore fills 90 % of 18 px
    [said] = of_code(strip, "scale.tube_wide")
    assert f"fills {100 * strip.bore.diameter_px / 18:.0f} % of the frame's width" in said, strip.warnings


def test_a_saturated_tube_is_said(frames):
    bright = np.clip(frames.astype(np.int32) * 3, 0, 255).astype(np.uint8)
    res = gp.analyze(bright, fps=500.0)
    assert of_code(res, "light.saturated"), res.warnings


@pytest.mark.parametrize(("mm_per_px", "doubted"), [(0.185, False), (0.19, False), (0.06, True), (0.5, True)])
def test_a_given_scale_far_from_the_tube_seen_is_said(frames, mm_per_px, doubted):
    """Given --mm-per-px, the tube found (16 px) is checked against the bore it makes: 0.06 mm/px (a 50 px bore)
    and 0.5 mm/px (6 px) are doubted, the true 0.185 and a 3 % error are not (the tube model's own job)."""
    res = gp.analyze(frames, fps=500.0, mm_per_px=mm_per_px)
    said = of_code(res, "scale.given_vs_tube")
    assert bool(said) == doubted, res.warnings
    assert all("the given scale makes its 3 mm bore" in w for w in said)
    assert all("mm_per_px=" in w for w in said)


@pytest.mark.parametrize("mm_per_px", [0.0185, 0.000185])
def test_a_scale_so_fine_that_no_plug_is_left_is_doubted(frames, mm_per_px):
    """A scale 10 (or 1000, metres for mm) times too fine makes every plug shorter than min_plug_mm: "no plugs",
    which used to come without a warning because the check of the given scale was off whenever no plug was found."""
    res = gp.analyze(frames, fps=500.0, mm_per_px=mm_per_px)
    assert not res.has_plugs
    said = of_code(res, "scale.given_vs_tube")
    assert len(said) == 1 and "check mm_per_px=" in said[0], res.warnings
    assert "check the scale" in res.statement


def test_the_command_line_names_its_flags_and_the_library_its_keywords(frames, tmp_path, capsys):
    """One warning, two audiences: a Python user reads ``fps=`` and ``mm_per_px=``, the command line's user reads
    ``--fps`` and ``--mm-per-px``; the saved summary keeps the library's words."""
    import json

    import tifffile

    from grainplug.cli import main

    res = gp.analyze(frames, fps=500_000.0)
    said = of_code(res, "plugs.implausible_speed")
    assert said and all("(fps=)" in w for w in said), res.warnings
    assert not any("--" in w for w in res.warnings)
    path = tmp_path / "m.tif"
    tifffile.imwrite(path, frames)
    assert main(["analyze", str(path), "--fps", "500000", "--out", str(tmp_path / "o"), "--no-figures"]) == 0
    err = capsys.readouterr().err
    assert "check the frame rate (--fps)" in err and "give --tube-outer-diameter-mm" in err
    assert "fps=" not in err and "mm_per_px=" not in err
    saved = of_code(json.loads((tmp_path / "o" / "summary.json").read_text()), "plugs.implausible_speed")
    assert saved and all("check the frame rate (fps=)" in w for w in saved)


def test_a_tube_without_plugs_does_not_doubt_a_right_scale():
    """With no plugs the tube is seen where falling grains show it (4 px of a 16 px bore): no reason to doubt
    the given scale; only a tube seen wider than the bore it makes would be."""
    cfg = SynthConfig(n_frames=60, width_px=64, height_px=300, fps=500.0, seed=4, rgb=False, regime="none")
    frames = np.stack(list(Renderer(cfg).frames()))
    res = gp.analyze(frames, fps=500.0, mm_per_px=0.185)
    assert not res.has_plugs
    assert "scale.given_vs_tube" not in codes(res), res.warnings


@pytest.mark.parametrize("camera", ["up", "down"])
def test_a_flow_direction_only_assumed_is_said_with_the_celerity(camera):
    """Without grains falling through the bubbles a vertical flow is taken down the image: a camera mounted upside
    down then reads climbing plugs (-0.03 m/s) as +0.03 m/s. That sign is a guess, and is said so; with falling
    grains the direction is read from them and nothing is said."""
    cfg = SynthConfig(n_frames=150, seed=2, flow_direction=camera, falling_grains_per_mm=0.0, celerity_m_s=-0.03)
    frames = np.stack(list(Renderer(cfg).frames()))
    res = gp.analyze(frames, fps=cfg.fps, mm_per_px=cfg.mm_per_px)
    assert res.flow_direction == "down" and res.celerity_m_s == pytest.approx(0.03 if camera == "up" else -0.03,
                                                                             rel=0.01)
    [said] = of_code(res, "flow.sign_assumed")
    assert "flow_direction=" in said, res.warnings
    seen = SynthConfig(n_frames=150, seed=2, flow_direction=camera, celerity_m_s=-0.03)
    res = gp.analyze(np.stack(list(Renderer(seen).frames())), fps=seen.fps, mm_per_px=seen.mm_per_px)
    assert res.celerity_m_s == pytest.approx(-0.03, rel=0.01) and not res.warnings


def test_plugs_under_heavy_noise_are_confirmed_by_averaging_along_the_tube():
    """Pixel noise pulls the plug/bubble separation (0.77) under the 0.8 that two materials need pixel by pixel, and
    the movie was called "no plugs: compact flow". Plugs are long and noise is not: averaged along the tube over a
    third of the shortest plug the two levels separate (0.92), and the plugs are measured as without the noise."""
    clean = SynthConfig(n_frames=150, seed=4, rgb=False, bit_depth=16)
    noisy = SynthConfig(n_frames=150, seed=4, rgb=False, bit_depth=16, noise_sigma=90.0)
    ref = gp.analyze(np.stack(list(Renderer(clean).frames())), fps=clean.fps, mm_per_px=clean.mm_per_px)
    res = gp.analyze(np.stack(list(Renderer(noisy).frames())), fps=noisy.fps, mm_per_px=noisy.mm_per_px)
    n = res.normalized
    assert n.separation_eta < 0.8 and n.averaged_eta > 0.85 and res.has_plugs, (n.separation_eta, n.averaged_eta)
    assert res.celerity_m_s == pytest.approx(-0.05, rel=0.01)
    assert res.plug_length_mm == pytest.approx(ref.plug_length_mm, rel=0.01)
    assert res.bubble_length_mm == pytest.approx(ref.bubble_length_mm, rel=0.01)


@pytest.mark.parametrize("fill", ["empty", "compact"])
@pytest.mark.parametrize("polarity", ["dark", "bright"])
def test_noise_alone_makes_no_plugs(fill, polarity):
    """The averaged second look does not turn noise, falling grains or a compact column into plugs."""
    cfg = SynthConfig(n_frames=150, seed=4, rgb=False, bit_depth=16, noise_sigma=90.0, regime="none",
                      no_plug_fill=fill, polarity=polarity)
    res = gp.analyze(np.stack(list(Renderer(cfg).frames())), fps=cfg.fps, mm_per_px=cfg.mm_per_px)
    assert not res.has_plugs and res.statement.startswith("no plugs")


def test_two_grey_levels_too_close_to_tell_apart_are_not_called_one_phase():
    """Plugs under a noise that averaging does not cut (blocks of 16 positions, like a codec's): separation 0.73,
    still 0.71 averaged. No plug is measured, but the statement no longer asserts a compact flow as if it were
    known: it says two levels are hinted at and what would separate them."""
    from grainplug.diagram import Diagram
    from grainplug.measures.diagram import measure_diagram

    rng = np.random.default_rng(0)
    s, t = np.arange(400) * 0.2, np.arange(300) / 250
    plug = ((s[None, :] - 50 * t[:, None]) % 8.0) < 4.0
    blocks = rng.normal(0, 1, size=(300, 26)).repeat(16, axis=1)[:, :400]
    values = (np.where(plug, 80.0, 120.0) * np.exp(0.15 * blocks)).astype(np.float32)
    m = measure_diagram(Diagram(values, t, s, 0.2), fps=250.0, background_level=200.0)
    assert 0.7 <= m.normalized.separation_eta < 0.8 and m.normalized.averaged_eta < 0.85
    assert m.motion is None and "hint at two, too close to tell apart" in m.statement
    assert "raise the contrast" in m.statement


@pytest.fixture(scope="module")
def train():
    """A plug train (10 mm plugs, 8 mm bubbles, +0.05 m/s) and its clean measures."""
    cfg = SynthConfig(n_frames=200, seed=5, celerity_m_s=0.05, plug_length_mm=10, bubble_length_mm=8,
                      plug_length_sd_mm=1, bubble_length_sd_mm=1)
    frames = np.stack(list(Renderer(cfg).frames()))
    return cfg, frames, gp.analyze(frames, fps=cfg.fps, mm_per_px=cfg.mm_per_px)


def test_an_opaque_object_over_the_tube_is_measured_around(train):
    """A clamp over the tube (rows 300-329: 55.5-61.1 mm) is a still dark stretch: it was measured as a plug that
    never moves, and the plugs crossing it cut there (plugs -9 %, bubbles -20 %). It is now found as a blind
    stretch: plugs touching it are cut there, bubbles across it not measured, no plug made of it; the stretch is
    said, with where it is, and listed in summary.json."""
    cfg, frames, clean = train
    assert not clean.warnings
    clamped = frames.copy()
    clamped[:, 300:330] = np.clip(30 + np.random.default_rng(1).normal(0, 3, clamped[:, 300:330].shape), 0, 255)
    res = gp.analyze(clamped, fps=cfg.fps, mm_per_px=cfg.mm_per_px)
    [said] = of_code(res, "still.region")
    assert said.startswith("nothing changes at 55.5-61.1 mm "), res.warnings  # where it is
    assert "still.track" not in codes(res), res.warnings  # the clamp is no plug any more
    [blind] = res.summary["blind_stretches"]
    assert blind["found_by"] == "still contents" and blind["from_mm"] == pytest.approx(55.5, abs=0.2)
    assert blind["to_mm"] == pytest.approx(61.1, abs=0.2)
    assert res.celerity_m_s == pytest.approx(clean.celerity_m_s, rel=0.01)
    assert res.plug_length_mm == pytest.approx(clean.plug_length_mm, rel=0.03)
    assert res.bubble_length_mm == pytest.approx(clean.bubble_length_mm, rel=0.03)
    # given by hand, the same stretch is taken as given, and not said again
    given = gp.analyze(clamped, fps=cfg.fps, mm_per_px=cfg.mm_per_px, mask_mm=[(55.0, 62.0)])
    assert [b["found_by"] for b in given.summary["blind_stretches"]] == ["mask_mm"]
    assert not given.warnings and given.plug_length_mm == pytest.approx(clean.plug_length_mm, rel=0.03)


def test_plugs_about_the_length_threshold_are_said():
    """Plugs of 3.3 +- 0.5 mm against the 3 mm threshold: the shorter ones are dropped, the bubbles about them
    measured as one (bubbles 7.6 mm for 4) and the plugs at the threshold split into tracks, without a word."""
    cfg = SynthConfig(n_frames=200, seed=5, celerity_m_s=0.05, plug_length_mm=3.3, plug_length_sd_mm=0.5,
                      bubble_length_mm=4.0, bubble_length_sd_mm=0.5)
    res = gp.analyze(np.stack(list(Renderer(cfg).frames())), fps=cfg.fps, mm_per_px=cfg.mm_per_px)
    [said] = of_code(res, "plugs.near_min_length")
    assert "within 20 % of min_plug_mm = 3 mm" in said and "lower min_plug_mm=" in said, res.warnings
    lowered = gp.analyze(np.stack(list(Renderer(cfg).frames())), fps=cfg.fps, mm_per_px=cfg.mm_per_px,
                         min_plug_mm=1.5)
    assert "plugs.near_min_length" not in codes(lowered), lowered.warnings
    assert lowered.bubble_length_mm == pytest.approx(4.0, rel=0.1)


@pytest.mark.parametrize("grains_per_mm", [1.0, 3.0])
def test_falling_grains_alone_are_neither_plugs_about_the_threshold_nor_two_close_levels(grains_per_mm):
    """Clumps of falling grains cut at min_plug_mm pile up near it: without a plug train that says nothing of
    plugs (lowering the threshold would make plugs of the clumps). Their grey levels part less once averaged along
    the tube: short things, not plugs, so the tube is said to hold one phase, not two close levels."""
    cfg = SynthConfig(n_frames=150, seed=6, regime="none", falling_grains_per_mm=grains_per_mm)
    res = gp.analyze(np.stack(list(Renderer(cfg).frames())), fps=cfg.fps, mm_per_px=cfg.mm_per_px)
    assert not res.has_plugs and "plugs.near_min_length" not in codes(res), res.warnings
    assert "hint at two" not in res.statement, res.statement


@pytest.mark.parametrize("width", [3, 6])
def test_rain_with_a_speck_of_dense_grains_is_not_called_a_compact_flow(width):
    """A diagram that is rain (c = 0.02) but for a thin dense streak (0.5-1 % of it: too little for two phases) was
    called "compact flow by its grey level" (the mean of its two classes' levels); it is dilute."""
    from grainplug.diagram import Diagram
    from grainplug.measures.diagram import measure_diagram

    rng = np.random.default_rng(0)
    n_t, n_x = 400, 600
    c = 0.02 + 0.003 * rng.standard_normal((n_t, n_x))
    for t in range(n_t):
        a = int(400 - 0.3 * t)
        c[t, a: a + width] = 0.58
    values = np.clip(200 - 250 * c, 1, 200).astype(np.float32)
    found = measure_diagram(Diagram(values, np.arange(n_t) / 100.0, np.arange(n_x) * 0.1875, 0.1875), fps=100.0,
                            background_level=200.0)
    assert "single phase" in found.statement and "dilute" in found.statement, found.statement
    assert "compact" not in found.statement
