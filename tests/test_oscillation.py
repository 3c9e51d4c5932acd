"""The oscillation's 95 % intervals, its kind and stick fraction, and the tracks' celerities on oscillating runs
(issue 34, item 3), on movies of the independent renderer ``lab_nuisances.py`` with known truth.

The intervals' method was calibrated on ``benchmarks/oscillation_intervals.py``'s random draws (seeds 1000 and up);
the cases here are the bench's named ones at seed 1, or scenes none of those draws is: held out.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from lab_nuisances import CASES, Motion, Scene, Shake, render_frames, write_movie
from test_cli_basics import run

import grainplug as gp

#: held out from the calibration: the bench's cases at seed 1, and two stick-slip scenes of other fractions
HELD_OUT = {
    "oscillating 3 Hz 3 mm": CASES["oscillating 3 Hz 3 mm"].scene,
    "stick-slip 4 Hz": CASES["stick-slip 4 Hz"].scene,
    "stick-slip 3 Hz, still 35 %": Scene(motion=Motion("stick-slip", -0.04, 3.0, stick_fraction=0.35), n_frames=240),
    "stick-slip 5 Hz, still 70 %, shake": Scene(motion=Motion("stick-slip", -0.02, 5.0, stick_fraction=0.7),
                                                n_frames=200, shake=Shake(1.0, 27.0, 1.0)),
}


def _kwargs(scene: Scene) -> dict[str, float]:
    return {"fps": scene.fps, "mm_per_px": scene.mm_per_px, "tube_diameter_mm": scene.inner_diameter_mm}


@pytest.fixture(scope="module")
def analysed() -> dict[str, tuple[object, object]]:
    out = {}
    for name, scene in HELD_OUT.items():
        frames, truth = render_frames(scene, np.random.default_rng(1))
        out[name] = (gp.analyze(frames, **_kwargs(scene)), truth)
    return out


@pytest.mark.parametrize("name", list(HELD_OUT))
def test_the_frequency_and_amplitude_intervals_hold_the_truth_on_held_out_movies(analysed, name):
    res, truth = analysed[name]
    s = res.summary
    assert s["regime"] == "oscillating"
    lo, hi = s["oscillation_frequency_ci95_hz"]
    assert lo <= truth.frequency_hz <= hi, (lo, truth.frequency_hz, hi)
    assert lo <= s["oscillation_frequency_hz"] <= hi
    assert hi - lo < 0.05 * truth.frequency_hz  # an interval, not a shrug
    a_lo, a_hi = s["oscillation_amplitude_ci95_mm"]
    assert a_lo <= truth.amplitude_mm <= a_hi, (a_lo, truth.amplitude_mm, a_hi)
    assert a_hi - a_lo < 0.2 * truth.amplitude_mm


@pytest.mark.parametrize("name", list(HELD_OUT))
def test_the_kind_and_the_stick_fraction_match_the_render(analysed, name):
    res, _ = analysed[name]
    motion = HELD_OUT[name].motion
    s = res.summary
    if motion.regime == "stick-slip":
        assert s["oscillation_kind"] == "stick-slip"
        assert s["oscillation_stick_fraction"] == pytest.approx(motion.stick_fraction, abs=0.05)
    else:
        assert s["oscillation_kind"] == "sinusoidal"
        assert s["oscillation_stick_fraction"] < 0.15
    assert s["regime"] == "oscillating"  # the regime keeps the paper's two names


def test_the_amplitude_is_half_the_peak_to_peak_of_the_period_averaged_motion_not_the_spectrum_peak(analysed):
    # a stick-slip's harmonics carry part of its swing: the spectrum's peak (the fundamental's amplitude) is lower
    res, truth = analysed["stick-slip 4 Hz"]
    m = res.motion
    assert m.oscillation_amplitude_mm == pytest.approx(truth.amplitude_mm, rel=0.01)
    f = m.oscillation_frequency_hz
    peak = m.spectrum_mm[np.argmin(np.abs(m.spectrum_hz - f))]
    assert peak < 0.95 * m.oscillation_amplitude_mm
    assert res.summary["oscillation_amplitude_mm"] == pytest.approx(m.oscillation_amplitude_mm, abs=1e-4)


@pytest.mark.parametrize("name", ["oscillating 3 Hz 3 mm", "stick-slip 4 Hz"])
def test_track_celerities_agree_with_the_headline_on_oscillating_runs(analysed, name):
    # a track is seen over a non-whole number of periods: a straight line through its raw edge is tilted by the swing
    # (3-6 % here before); with the common oscillation taken out, as the headline's fit does, they agree
    res, truth = analysed[name]
    tracks = res.tracks
    long = tracks[tracks["n_frames"] >= 20]
    assert len(long) >= 3
    np.testing.assert_allclose(long["celerity_m_s"], truth.celerity_m_s, rtol=0.005)
    assert res.summary["celerity_m_s"] == pytest.approx(truth.celerity_m_s, rel=0.005)


def test_no_oscillation_no_interval_no_kind(tmp_path):
    scene = CASES["clean c=-0.05"].scene
    frames, _ = render_frames(replace(scene, n_frames=120), np.random.default_rng(1))
    s = gp.analyze(frames, **_kwargs(scene)).summary
    assert s["regime"] == "propagative"
    for key in ("oscillation_frequency_hz", "oscillation_amplitude_mm", "oscillation_frequency_ci95_hz",
                "oscillation_amplitude_ci95_mm", "oscillation_kind", "oscillation_stick_fraction"):
        assert s[key] is None, key


def test_the_cli_line_the_report_and_the_jupyter_table_give_the_intervals_and_the_kind(tmp_path, capsys, analysed):
    scene = HELD_OUT["stick-slip 4 Hz"]
    frames, _ = render_frames(scene, np.random.default_rng(1))
    movie = tmp_path / "stick.tif"
    write_movie(movie, frames, fps=scene.fps)
    code, stdout, err = run(capsys, "analyze", movie, "--out", tmp_path / "o", "--fps", scene.fps,
                            "--mm-per-px", scene.mm_per_px)
    assert code == 0, err
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    lo, hi = s["oscillation_frequency_ci95_hz"]
    line = next(row for row in stdout.splitlines() if row.startswith("oscillation"))
    assert "95% CI" in line and "stick-slip" in line and "half peak-to-peak" in line
    assert f"{lo:.3f}" in line and f"{hi:.3f}" in line
    page = (tmp_path / "o" / "report.html").read_text()
    assert "stick-slip" in page and "half peak-to-peak" in page
    res, _ = analysed["stick-slip 4 Hz"]
    assert "stick-slip" in res._repr_html_()


def test_a_saved_oscillating_result_reads_back_with_its_intervals(tmp_path, analysed):
    res, _ = analysed["stick-slip 4 Hz"]
    res.save(tmp_path / "run", figures=False, report=False)
    back = gp.load_result(tmp_path / "run")
    assert back.motion.oscillation == res.motion.oscillation
    np.testing.assert_array_equal(back.motion.oscillation.shape_mm, res.motion.oscillation.shape_mm)
    assert back.summary["oscillation_kind"] == "stick-slip"
    np.testing.assert_allclose(back.tracks["celerity_m_s"], res.tracks["celerity_m_s"])


def test_the_review_page_shows_the_intervals_the_kind_and_the_tracks_celerities(tmp_path, analysed):
    sync_api = pytest.importorskip("playwright.sync_api")
    from test_review import chromium_page, get_json

    from grainplug.review import ReviewServer

    res, truth = analysed["stick-slip 4 Hz"]
    res.save(tmp_path / "stick", figures=False, report=False)
    with ReviewServer(tmp_path / "stick") as srv, sync_api.sync_playwright() as p, chromium_page(p) as page:
        page.goto(srv.url)
        page.wait_for_selector("#tracks tbody tr", timeout=20_000)
        st = get_json(srv, "api/run/stick/state")
        lo, hi = st["measures"]["oscillation_frequency_ci95_hz"]
        assert lo <= truth.frequency_hz <= hi
        text = page.inner_text("#measures")
        assert f"95% CI {lo:.3f} to {hi:.3f}" in text and "half peak-to-peak" in text
        assert page.inner_text("#oscillation-kind") == "stick-slip"
        long = [t["celerity_m_s"] for t in st["tracks"] if t["n_frames"] >= 20]
        np.testing.assert_allclose(long, truth.celerity_m_s, rtol=0.005)


def test_an_oscillation_given_without_its_intervals_says_so(analysed):
    """When the fitted frequency leaves the spectrum's peak the oscillation is still given, without intervals and
    kind: a warning says so (nothing is left null without a word); with its intervals, none."""
    from grainplug.checks import no_interval
    from grainplug.warning_codes import codes_of

    res, _ = next(iter(analysed.values()))
    assert res.motion.oscillation is not None and codes_of(no_interval(res.motion)) == []
    bare = replace(res.motion, oscillation=None)
    assert codes_of(no_interval(bare)) == ["plugs.oscillation_no_interval"]
