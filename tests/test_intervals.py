"""The 95 % intervals hold the truth when the scale comes from the tube (issue 33, item 5).

A handful of cases of the sweep of ``benchmarks/intervals.py`` on the independent optical renderer
(``tube_optics.py``) and the plain-band one (``test_other_renderer.py``): a 12 px bore, a 13 px noisy one, a
back-lit tube whose 15 deg lamp hides the stripes (the contents read 24 % narrow), narrow stripes through
MJPEG, a front-lit H.264 movie. The scale's error must lie within 1.96 of its claimed standard deviations,
and the celerity's and the plug length's 95 % intervals must hold the truth (to 0.5 % of it, the renderers'
own precision). The whole sweep (182 analyses) is the benchmark; docs/accuracy.md "Intervals on a sweep".
"""

from __future__ import annotations

import numpy as np
import pytest
from test_other_renderer import render as render_band
from tube_optics import SUFFIX, Lighting, render_movie

import grainplug as gp

#: a miss by less than this share of the truth is not counted
SLACK = 0.005

CASES = {
    "12 px, lamp 25 deg": (12, Lighting("back", 25.0), "tif", 0.01, 0),
    "13 px, noise 3 %": (13, Lighting("back", 25.0), "tif", 0.03, 0),
    "15 px, lamp 15 deg, noise 3 %": (15, Lighting("back", 15.0), "tif", 0.03, 0),
    "20 px, lamp 15 deg, MJPEG": (20, Lighting("back", 15.0), "mjpeg", 0.03, 0),
    "20 px, front-lit, H.264": (20, Lighting("front"), "h264", 0.01, 1),
}


def holds(ci: tuple[float, float] | None, truth: float) -> bool:
    assert ci is not None
    lo, hi = sorted(ci)
    return lo - SLACK * abs(truth) <= truth <= hi + SLACK * abs(truth)


def check(res: gp.AnalysisResult, mm_per_px: float, celerity: float, length: float) -> None:
    err = res.mm_per_px / mm_per_px - 1
    assert abs(err) <= 1.96 * res.scale_rel_sd, (err, res.scale_rel_sd, res.bore)
    assert holds(res.motion.celerity_ci95_m_s, celerity), (res.celerity_m_s, res.motion.celerity_ci95_m_s, celerity)
    assert holds(res.lengths.plug_length_ci95_mm, length), (res.plug_length_mm, res.lengths.plug_length_ci95_mm,
                                                            length)


@pytest.mark.parametrize("name", list(CASES))
def test_the_intervals_hold_the_truth_on_the_optical_renderer(tmp_path, name):
    bore, light, fmt, noise, seed = CASES[name]
    path = tmp_path / f"m{SUFFIX[fmt]}"
    mpp = 3.0 / bore
    truth = render_movie(path, rng=np.random.default_rng(1000 + seed), fmt=fmt, mm_per_px=mpp,
                         width_px=max(60, round(3.4 * bore)), height_px=600, n_frames=300, noise=noise,
                         lighting=light)
    for od in (None, 5.5):
        res = gp.analyze(path, fps=truth.fps, tube_outer_diameter_mm=od)
        check(res, mpp, truth.celerity_m_s, truth.plug_length_mm)


def test_the_intervals_hold_the_truth_on_the_plain_band_renderer(tmp_path):
    # no walls at all: a 12 px band of dark plugs, read as a back-lit tube's contents (a lower bound of its bore)
    c, length, _ = render_band(tmp_path / "m.tif", rng=np.random.default_rng(1000), tube_px=12.0, mm_per_px=0.27,
                               h=500, n_frames=150)
    res = gp.analyze(tmp_path / "m.tif", fps=250.0, tube_diameter_mm=12.0 * 0.27)
    check(res, 0.27, c, length)


def test_a_shake_across_the_tube_widens_a_scale_read_from_the_contents_only():
    from grainplug.calibration.scale import Scale, shaken_rel_sd
    from grainplug.calibration.tube_model import BoreEstimate

    contents = Scale(0.15, "tube inner width seen through its contents (bore 3 mm = 20.00 px)", 0.03,
                     bore=BoreEstimate(20.0, "contents", {"contents": 20.0}, rel_sd=0.03))
    # a 0.5 px rms shake sweeps the contents over about 2 sqrt(2) x 0.5 = 1.41 px of a 20 px bore: 7.1 %
    assert shaken_rel_sd(contents, 0.5) == pytest.approx(np.hypot(0.03, 1.4142 / 20), rel=1e-3)
    assert shaken_rel_sd(contents, 0.0) == 0.03
    stripes = Scale(0.15, "tube model: refraction stripes", 0.008,
                    bore=BoreEstimate(20.0, "stripe + outer", {"stripe + outer": 20.0}, rel_sd=0.008))
    assert shaken_rel_sd(stripes, 0.5) == 0.008  # found on the mean image, which a shake blurs symmetrically
    assert shaken_rel_sd(Scale(0.15, "user", 0.0), 0.5) == 0.0
