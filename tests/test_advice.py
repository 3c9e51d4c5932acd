"""Every piece of advice a scale warning gives, followed on a case that triggers it, must not make the number worse.

Issue 33, item 6: the tube-model warning once told the user to give the outer diameter "to check it", and on
the bundled sample doing so moved the scale from +2.2 % to -4.5 % off. Here each warning is triggered on a
movie with known truth (the bundled sample; the independent optical renderer ``tube_optics.py``), its advice
is followed, and the scale's error after is compared with the error before.
"""

from __future__ import annotations

import numpy as np
import pytest
from tube_optics import CASES, SUFFIX, render_movie
from warned import codes

import grainplug as gp
from grainplug.calibration.pattern import Calibration

#: following advice may change the error by noise; "worse" is worse by more than this (relative scale error; the
#: issue's own threshold for a miss that is not counted)
NOISE = 0.005


def scale_error(res: gp.AnalysisResult, mm_per_px: float) -> float:
    return abs(res.mm_per_px / mm_per_px - 1)


@pytest.fixture(scope="module")
def sample():
    truth = gp.datasets.sample_truth()["config"]
    res = gp.analyze(gp.datasets.sample_movie(), fps=truth["fps"])
    return truth, res


def test_outer_diameter_advised_on_the_sample_makes_the_scale_better(sample):
    truth, res = sample
    assert "scale.model_alone" in codes(res), res.warnings
    outer_mm = truth["tube_diameter_mm"] + 2 * truth["wall_mm"]
    given = gp.analyze(gp.datasets.sample_movie(), fps=truth["fps"], tube_outer_diameter_mm=outer_mm)
    before, after = scale_error(res, truth["mm_per_px"]), scale_error(given, truth["mm_per_px"])
    assert after <= before + NOISE, (before, after)
    assert after < 0.01, after  # and right: the silhouette and the stripes weighed, not one preferred
    # the two estimates disagree on this renderer (its silhouette reads wide): said, and carried in the interval
    assert given.summary["scale_rel_sd"] >= after


@pytest.mark.parametrize("name", ["back-lit, lamp 25 deg", "bore 15 px", "H.264 crf 28", "front-lit, bright plugs"])
def test_outer_diameter_advised_on_the_optical_renderer_does_not_make_the_scale_worse(tmp_path, name):
    kw = CASES[name]
    path = tmp_path / f"m{SUFFIX[str(kw.get('fmt', 'tif'))]}"
    truth = render_movie(path, rng=np.random.default_rng(1), **kw)
    res = gp.analyze(path, fps=truth.fps)
    advised = {"scale.model_alone", "scale.contents_unchecked"} & codes(res)
    assert advised, res.warnings  # the advice to give the outer diameter is there
    given = gp.analyze(path, fps=truth.fps, tube_outer_diameter_mm=float(kw.get("outer_diameter_mm", 5.5)))
    before, after = scale_error(res, truth.mm_per_px), scale_error(given, truth.mm_per_px)
    assert after <= before + NOISE, (before, after)


def uniform(mm_per_px: float, shape: tuple[int, int], pitch_mm: float) -> Calibration:
    """A calibration of a flat, square, undistorted graph paper at ``mm_per_px``, its lines ``pitch_mm`` apart."""
    return Calibration(mm_per_px=mm_per_px, mm_per_px_x=mm_per_px, mm_per_px_y=mm_per_px,
                       jacobian_mm_per_px=((mm_per_px, 0.0), (0.0, mm_per_px)), rel_sd=0.001, tilt_deg=0.0,
                       scale_variation=0.0, rms_residual_px=0.05, n_points=60, pattern="graph", pitch_mm=pitch_mm,
                       image_shape=shape, centre_px=(shape[1] / 2, shape[0] / 2),
                       homography=((1 / mm_per_px, 0, 0), (0, 1 / mm_per_px, 0), (0, 0, 1)),
                       image={"name": "paper.png"})


def test_a_doubted_calibrations_advice_gives_the_right_scale(sample):
    truth, _ = sample
    frames_shape = (truth["height_px"], truth["width_px"])
    # graph paper read at its bold 5 mm lines while its 1 mm pitch was typed: 5x too small a scale
    wrong = uniform(truth["mm_per_px"] / 5, tuple(frames_shape), 1.0)
    bad = gp.analyze(gp.datasets.sample_movie(), fps=truth["fps"], calibration=wrong)
    assert "scale.calibration_doubted" in codes(bad), bad.warnings
    # the advice: check the pitch; with the pitch the pattern really has (5 mm between the lines read), right
    fixed = gp.analyze(gp.datasets.sample_movie(), fps=truth["fps"],
                       calibration=uniform(truth["mm_per_px"], tuple(frames_shape), 5.0))
    assert "scale.calibration_doubted" not in codes(fixed)
    assert scale_error(fixed, truth["mm_per_px"]) < scale_error(bad, truth["mm_per_px"])
