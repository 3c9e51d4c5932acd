"""A real lab's nuisances (camera shake, lamp ripple, passing shadows, clamps, labels), from an independent renderer.

``lab_nuisances.py`` draws them (it shares no code with ``grainplug.synthetic``); the whole bench is
``benchmarks/nuisances.py`` (docs/accuracy.md, "Real-lab nuisances"). Here: (a) the renderer does
what it says (the shake's image motion, the ripple's frame level, still clamps, the shadow's depth,
the kinematics' truth), and (b) grainplug meets the targets on the cases it gets right today; the
cases it gets wrong are strict xfails naming the nuisance, so a fix that makes one pass must remove
its mark.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from lab_nuisances import (
    CASES,
    Clamp,
    Label,
    Motion,
    Ripple,
    Scene,
    Shadow,
    Shake,
    judge,
    render_frames,
    render_movie,
    truth_record,
)
from skimage.registration import phase_cross_correlation

import grainplug as gp

#: a small, noiseless, still scene for the renderer's own checks
QUIET = Scene(height_px=300, n_frames=12, motion=Motion("static"), grains_per_mm=0.0, noise=0.0, shot=0.0,
              clamps=(Clamp(10.0, 5.0),), labels=(Label(30.0, 8.0),))


def test_the_shake_moves_the_image_by_what_was_asked_to_a_twentieth_of_a_pixel():
    # an empty tube with a clamp and a label: the frame's ends match, so the correlation needs no window
    # (the spectrum is not whitened: with 8-bit levels that amplifies the quantisation to 0.1 px)
    scene = replace(QUIET, plugs=False, shake=Shake(1.5, 35.0, wander_px=2.0))
    frames, truth = render_frames(scene, np.random.default_rng(3))
    ref = frames[0].astype(float)
    for k in range(1, len(frames)):
        measured, _, _ = phase_cross_correlation(frames[k].astype(float), ref, upsample_factor=200,
                                                 normalization=None)
        asked = truth.shake_px[k] - truth.shake_px[0]
        assert np.abs(measured - asked).max() < 0.05, (k, measured, asked)
    assert np.ptp(truth.shake_px[:, 0]) > 1.0  # it did move, by more than a pixel


def test_the_ripple_sets_the_mean_frame_level_and_is_aliased_as_sampled():
    rippled = replace(QUIET, ripple=Ripple(0.3, 100.0, drift=0.1, phase=0.2))
    frames, truth = render_frames(rippled, np.random.default_rng(4))
    still, _ = render_frames(QUIET, np.random.default_rng(4))
    t = np.arange(QUIET.n_frames) / QUIET.fps
    asked = (1 + 0.3 * np.sin(2 * np.pi * 100.0 * t + 0.2)) * (1 + 0.1 * (t / (QUIET.n_frames / QUIET.fps) - 0.5))
    level = frames.mean(axis=(1, 2)) / still.mean(axis=(1, 2))
    np.testing.assert_allclose(truth.light, asked, rtol=1e-12)
    np.testing.assert_allclose(level, asked, rtol=0.01)
    # 100 Hz at 250 fps: 0.4 cycle a frame, so the level jumps from frame to frame and repeats every 5
    assert np.abs(level[1:] / level[:-1] - 1).max() > 0.3
    assert level[5] / level[0] == pytest.approx((1 + 0.1 * (5 / 12 - 0.5)) / (1 + 0.1 * (0 - 0.5)), rel=0.01)


def test_clamp_pixels_never_change_while_plugs_move_and_a_label_lets_light_through():
    scene = replace(QUIET, motion=Motion("propagative", -0.1), grains_per_mm=0.5, n_frames=20)
    frames, _ = render_frames(scene, np.random.default_rng(5))
    px = scene.mm_per_px
    rows = slice(int(8.5 / px), int(11.5 / px))  # the clamp is 7.5-12.5 mm, blur 0.8 px
    np.testing.assert_array_equal(frames[:, rows, :], np.broadcast_to(frames[0, rows, :], frames[:, rows, :].shape))
    assert frames[0, rows, 30:70].max() <= 0.04 * 255  # dark over the tube and beyond its walls
    bore = slice(45, 55)
    label = frames[:, int(27 / px):int(33 / px), bore].astype(float)
    assert 0 < label.mean() < 0.6 * frames[:, int(40 / px):, bore].astype(float).max()


def test_a_shadow_darkens_background_and_tube_alike_by_its_depth():
    scene = replace(QUIET, clamps=(), labels=(), shadows=(Shadow(0.5, 3.0, 20.0, start_mm=20.0),))
    frames, _ = render_frames(scene, np.random.default_rng(6))
    plain, _ = render_frames(replace(scene, shadows=()), np.random.default_rng(6))
    px = scene.mm_per_px
    for k in (0, 11):
        row = int(round((20.0 + 20.0 * k / scene.fps) / px))  # the band's centre
        ratio = frames[k, row, :].astype(float) / np.maximum(plain[k, row, :], 1)
        bright = plain[k, row, :] > 60
        np.testing.assert_allclose(ratio[bright], 0.5, atol=0.02)
        far = int(40 / px)  # 6 band widths away
        np.testing.assert_array_equal(frames[k, far, :], plain[k, far, :])


def test_the_truth_follows_the_kinematics():
    stick = Motion("stick-slip", -0.03, 4.0, stick_fraction=0.6)
    t = np.arange(0, 1.0, 1 / 1000)
    x = stick.displacement_mm(t)
    assert x[0] == 0 and x[-1] == pytest.approx(-30.0 * 0.999, abs=0.05)  # the mean velocity is c
    assert np.all(np.diff(x) <= 0)  # never backwards
    assert np.ptp(x[:150]) == 0.0 and x[151] < 0  # still for 60 % of the first period, then slips
    _, truth = render_frames(replace(QUIET, motion=stick, height_px=600, n_frames=40), np.random.default_rng(7))
    assert truth.regime == "oscillating" and truth.frequency_hz == 4.0 and truth.amplitude_mm > 2
    assert truth.n_plugs_whole >= 3 and 13 < truth.plug_length_mm < 15.5 and 8.5 < truth.bubble_length_mm < 11


def _measure(case_name: str, tmp_path) -> dict[str, object]:
    case = CASES[case_name]
    movie = tmp_path / case.movie_name()
    truth = render_movie(movie, case.scene, np.random.default_rng(case.seed))
    res = gp.analyze(movie, **case.analysis_kwargs())
    return judge(case, truth_record(truth), res.summary) | {"codes": res.summary["warning_codes"]}


def _xfail(name: str, reason: str) -> pytest.param:
    return pytest.param(name, marks=pytest.mark.xfail(strict=True, reason=reason))


#: cases grainplug gets wrong today (2026-11-28, after the shake registration, lamp and blind-stretch corrections),
#: with the nuisance that breaks them
WRONG_TODAY: dict[str, str] = {}
#: cases that pass by under 0.2 % of a target and fail with other seeds: neither asserted nor expected to fail, so
#: that an unrelated change of a tenth of a per cent does not trip the suite (none today: "combined c=-0.05, H.264
#: crf 28, scale from tube" was, at +5.9 % for 6 %, and is +0.6 % since the camera's shake is registered)
MARGINAL: set[str] = set()
for _name in MARGINAL:
    WRONG_TODAY.pop(_name, None)

#: a handful of representative cases, run by default (about 1.5 s each)
FAST = ["clean c=-0.05", "shake 0.5 px 10 Hz", "shake 1.5 px 35 Hz, oscillating 5 Hz", "ripple 40 % 100 Hz",
        "shadow edge 50 % at 100 mm/s", "label 12 mm, front light", "H.264 crf 35", "stick-slip 4 Hz, shake 1 px 30 Hz",
        "shake 1.5 px 35 Hz", "shake 1.5 px 35 Hz, static plugs", "ripple 30 % 120 Hz, front light",
        "shadow band 50 % at 5 mm/s, c=-0.1", "clamp 8 mm", "label 12 mm, 55 % through", "combined c=-0.05",
        "shadow band 40 % at 40 mm/s, front light"]


def _params(names: list[str]) -> list[object]:
    return [_xfail(n, WRONG_TODAY[n]) if n in WRONG_TODAY else n for n in names]


@pytest.mark.parametrize("name", _params(FAST))
def test_targets_on_representative_cases(tmp_path, name):
    got = _measure(name, tmp_path)
    assert got["ok"], got


@pytest.mark.slow
@pytest.mark.parametrize("name", _params([n for n in CASES if n not in FAST and n not in MARGINAL]))
def test_targets_on_the_whole_bench(tmp_path, name):
    got = _measure(name, tmp_path)
    assert got["ok"], got


#: with another seed (movies the methods were not developed on), every target must still be met: the celerity's
#: interval where the camera wandered along the tube unmeasured (it missed in the first three before the wander's
#: term: issue 33, item 5; seed 2 of the whole bench: 39 of 50 cases met every target, 45 after), and the plugs
#: under a shadow passing in front light
OTHER_SEED = ["combined c=-0.05", "combined c=-0.1", "stick-slip 4 Hz, shake 1 px 30 Hz",
              # a passing shadow in front light, read on the contents (plugs -26 % without a word before)
              "shadow band 40 % at 40 mm/s, front light", "shadow band 60 % at 60 mm/s, front light",
              # a short oscillating record through a clamp and a label, the camera shaking along the tube: the
              # clamp's and the label's edges found still once the diagram is held still against the tube
              "combined oscillating 5 Hz", "combined c=-0.02", "combined c=-0.05, front light"]


@pytest.mark.slow
@pytest.mark.parametrize("name", OTHER_SEED)
def test_the_interval_holds_with_another_seed(tmp_path, name):
    import dataclasses

    case = dataclasses.replace(CASES[name], seed=2)
    movie = tmp_path / case.movie_name()
    truth = render_movie(movie, case.scene, np.random.default_rng(case.seed))
    res = gp.analyze(movie, **case.analysis_kwargs())
    got = judge(case, truth_record(truth), res.summary)
    assert got["ok"], got


def test_a_passing_shadow_in_front_light_is_read_on_the_contents_and_said(tmp_path):
    """A 40 % shadow crossing a front-lit tube (no lamp beside it to read it on) cut the plugs by 38 % without a
    word; it is now divided out and said. A 60 % one left plugs missed in some frames, and the gap across each was
    taken for one bubble (+58 %): a gap whose plugs are mostly seen with another between them is no bubble."""
    got = _measure("shadow band 40 % at 40 mm/s, front light", tmp_path)
    assert got["ok"] and "light.moving_shadow" in got["codes"], got
    deep = _measure("shadow band 60 % at 60 mm/s, front light", tmp_path)
    assert deep["ok"] and abs(deep["bubble_err"]) < 0.2, deep  # +12 % and +8 % (seeds 1, 2): the gaps beside a plug
    clean = _measure("clean c=-0.05, front light", tmp_path)
    assert "light.moving_shadow" not in clean["codes"], clean


@pytest.mark.parametrize("seed", [1, 2])
def test_a_clamp_over_a_short_oscillating_record_is_found_by_its_still_edge(tmp_path, seed):
    """The train travels less than its plugs and bubbles over the record (a place may see one phase only, so still
    places are not judged), but the clamp's edge stays put in every frame while the edges oscillate: it is made
    blind, and the plugs touching it are cut, not measured clamp and all."""
    from lab_nuisances import CLAMP, OSC

    scene = Scene(motion=OSC, n_frames=300, clamps=(CLAMP,))
    movie = tmp_path / "m.tif"
    truth = render_movie(movie, scene, np.random.default_rng(seed))
    res = gp.analyze(movie, fps=scene.fps, mm_per_px=scene.mm_per_px, tube_diameter_mm=scene.inner_diameter_mm)
    lo, hi = CLAMP.center_mm - CLAMP.length_mm / 2, CLAMP.center_mm + CLAMP.length_mm / 2
    assert any(lo - 1.0 <= b.from_mm and b.to_mm <= hi + 1.0 for b in res.blind), res.blind
    assert res.plug_length_mm == pytest.approx(truth_record(truth)["plug_length_mm"], rel=0.05)


@pytest.mark.slow
@pytest.mark.parametrize(("name", "seed"), [("shake 1 px 20 Hz + wander 3 px, c=-0.02", 2),
                                            ("shake 1 px 8 Hz, static plugs", 2),
                                            ("shake 1 px 8 Hz, static plugs", 3)])
def test_a_wander_along_plain_glass_is_said_not_measured(tmp_path, name, seed):
    """With nothing fixed to the tube in view (plain walls before a flat lamp), the camera's motion along the tube
    cannot be told from the plugs'. With seed 2 these two cases miss their targets (a 4.5-6 px wander along, little
    across: celerity +4.7 % outside its interval; still plugs drifting 0.7 mm/s, called propagative): what is
    asked of them is that the result says so, in the warning that tells the fix (a mark beside the tube). With
    seed 3 the still plugs' tube is found 1.3 times wide and tilted: its wall profiles step where they jump a pixel
    column, and the motion along registered on those steps as none, without the warning."""
    import dataclasses

    case = dataclasses.replace(CASES[name], seed=seed)
    movie = tmp_path / case.movie_name()
    render_movie(movie, case.scene, np.random.default_rng(case.seed))
    res = gp.analyze(movie, **case.analysis_kwargs())
    assert "shake.along_unmeasured" in res.summary["warning_codes"]
    assert not res.summary["shake"]["along_measured"]
