"""summary.json's ``uncertainty``: the celerity's and plug length's standard errors split into the tracks' scatter
and the scale's share, the split adding up to the stated intervals, and which one dominates (issue 33, item 5)."""

from __future__ import annotations

import math

import pytest

import grainplug as gp


@pytest.fixture(scope="module")
def runs():
    truth = gp.datasets.sample_truth()["config"]
    movie = gp.datasets.sample_movie()
    return (gp.analyze(movie, fps=truth["fps"]).summary,
            gp.analyze(movie, fps=truth["fps"], mm_per_px=truth["mm_per_px"]).summary)


def test_the_split_adds_up_to_the_interval(runs):
    for s in runs:
        u = s["uncertainty"]["celerity"]
        half = (s["celerity_ci95_m_s"][1] - s["celerity_ci95_m_s"][0]) / 2
        se = math.hypot(u["tracks_se_m_s"], u["scale_se_m_s"])
        # a t quantile of many degrees of freedom; the interval is written to 1e-6 m/s
        assert 1.9 * se - 1e-6 <= half <= 2.1 * se + 1e-6
        assert u["scale_se_m_s"] == pytest.approx(abs(s["celerity_m_s"]) * s["scale_rel_sd"], rel=1e-3, abs=1e-8)
        p = s["uncertainty"]["plug_length"]
        assert p["scale_se_mm"] == pytest.approx(s["plug_length_mm"] * s["scale_rel_sd"], rel=1e-3, abs=1e-4)
        assert p["tracks_se_mm"] == pytest.approx(s["plug_length_sd_mm"] / math.sqrt(s["n_plugs"]), rel=1e-3)


def test_the_dominant_term_is_named(runs):
    from_tube, given = runs
    # the scale from a 16 px tube (about 1 % uncertain) outweighs a drift fit over 400 frames
    assert from_tube["uncertainty"]["celerity"]["dominant"] == "scale"
    # a scale typed by hand carries no uncertainty here: the tracks are all there is
    assert given["uncertainty"]["celerity"] == {"tracks_se_m_s": given["uncertainty"]["celerity"]["tracks_se_m_s"],
                                                "scale_se_m_s": 0.0, "dominant": "tracks"}
