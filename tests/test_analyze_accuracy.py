"""`analyze` against the truth of synthetic movies, over every hard case.

Targets (from the analyze issue): celerity within 2% with the scale given and
4% with the scale measured from the tube; mean plug length within 3% / 5%;
oscillation frequency within 0.2 Hz when the record holds >= 8 periods; the
regime right in every case; a movie without plugs says so and measures nothing.
"""

from __future__ import annotations

import pytest

from grainplug import AnalysisParams, analyze
from grainplug.synthetic import synthesize
from grainplug.synthetic.cases import (
    CASES,
    CELERITY_TOL_SCALE_FROM_TUBE,
    CELERITY_TOL_SCALE_GIVEN,
    FREQUENCY_TOL_HZ,
    LENGTH_TOL_SCALE_FROM_TUBE,
    LENGTH_TOL_SCALE_GIVEN,
    MIN_PERIODS_FOR_FREQUENCY,
)

PARAMS = [pytest.param(c, marks=pytest.mark.slow, id=c.name) if c.slow else pytest.param(c, id=c.name)
          for c in CASES]


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    cache: dict[str, object] = {}

    def get(case, seed=1):
        key = f"{case.name}-{seed}"
        if key not in cache:
            cfg = case.synth_config(seed)
            cache[key] = (cfg, synthesize(cfg, tmp_path_factory.mktemp(key), fmt=case.fmt))
        return cache[key]

    return get


@pytest.mark.parametrize("case", PARAMS)
@pytest.mark.parametrize("scale", ["given", "tube"])
def test_case_accuracy(rendered, case, scale):
    cfg, res = rendered(case)
    truth = res.truth
    out = analyze(res.movie, AnalysisParams(mm_per_px=cfg.mm_per_px if scale == "given" else None,
                                            flow_direction=cfg.flow_direction))
    s = out.summary
    assert s["regime"] == truth["regime"]
    if not truth["has_plugs"]:
        assert s["has_plugs"] is False
        assert s["celerity_m_s"] is None and s["plug_length_mm"] is None
        assert "no plugs" in s["statement"]
        return
    tol_c = CELERITY_TOL_SCALE_GIVEN if scale == "given" else CELERITY_TOL_SCALE_FROM_TUBE
    tol_l = LENGTH_TOL_SCALE_GIVEN if scale == "given" else LENGTH_TOL_SCALE_FROM_TUBE
    assert s["celerity_m_s"] == pytest.approx(truth["celerity_m_s"], rel=tol_c)
    assert s["plug_length_mm"] == pytest.approx(truth["plug_length_mm"], rel=tol_l)
    lo, hi = s["celerity_ci95_m_s"]
    assert lo <= s["celerity_m_s"] <= hi
    if truth["oscillation_frequency_hz"]:
        periods = truth["oscillation_frequency_hz"] * cfg.n_frames / cfg.fps
        assert periods >= MIN_PERIODS_FOR_FREQUENCY
        assert abs(s["oscillation_frequency_hz"] - truth["oscillation_frequency_hz"]) <= FREQUENCY_TOL_HZ
        assert s["oscillation_amplitude_mm"] == pytest.approx(truth["oscillation_amplitude_mm"], rel=0.15)
    else:
        assert s["oscillation_frequency_hz"] is None
    assert s["tube_axis_angle_deg"] == pytest.approx(truth["tube_axis_angle_deg"], abs=0.3)
    if scale == "tube":
        assert s["tube_diameter_px"] == pytest.approx(truth["tube_diameter_px"], rel=0.03)


def test_bubble_length_clean_case(rendered):
    from grainplug.synthetic.cases import case

    cfg, res = rendered(case("dark_plugs_climbing"), seed=2)
    s = analyze(res.movie, AnalysisParams(mm_per_px=cfg.mm_per_px)).summary
    assert s["bubble_length_mm"] == pytest.approx(res.truth["bubble_length_mm"], rel=0.05)
    assert s["plug_length_over_diameter"] == pytest.approx(s["plug_length_mm"] / 3.0, abs=1e-3)


def test_edges_follow_truth(tmp_path):
    """Per-frame upper edges match the truth: median error under 0.1 mm (0.5 px), 99% under 0.3 mm,
    with sensor noise sigma = 15."""
    import csv

    import numpy as np

    # smooth interfaces: a rough one differs over the bore's core from its full-diameter mean
    # (the truth) by up to ~0.2 mm per plug, which is not what this test is about
    from grainplug.synthetic import SynthConfig

    cfg = SynthConfig(noise_sigma=15.0, edge_roughness_mm=0.0, seed=1)
    res = synthesize(cfg, tmp_path, fmt="tiff")
    out = analyze(res.movie, AnalysisParams(mm_per_px=cfg.mm_per_px))
    truth: dict[int, list[float]] = {}
    with open(res.truth_edges_csv) as fh:
        for row in csv.DictReader(fh):
            truth.setdefault(int(row["frame"]), []).append(float(row["top_mm"]))
    errs = []
    for i in range(len(out.runs)):
        top = out.runs.top_mm[i]
        if np.isfinite(top):
            cand = np.asarray(truth[int(out.runs.frame[i])])
            errs.append(np.min(np.abs(cand - top)))
    errs = np.asarray(errs)
    assert len(errs) > 300
    assert np.median(errs) < 0.1
    assert np.percentile(errs, 99) < 0.3
