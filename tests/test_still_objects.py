"""Still objects over the tube (issue 33, item 3): translucent labels measured through, clamps in front light found
blind, a plug passing under a clamp kept as one track, no edge inside a blind stretch in the celerity.

The movies come from the independent nuisance renderer (``tests/lab_nuisances.py``), whose truth is the kinematics.
"""

from __future__ import annotations

import numpy as np
import pytest
from lab_nuisances import Clamp, Label, Scene, render_frames

import grainplug as gp
from grainplug.diagram import Diagram
from grainplug.measures.still import column_levels, seen_through
from grainplug.plugs import Runs
from grainplug.plugs.tracking import link


def _analyze(scene: Scene, seed: int):
    frames, truth = render_frames(scene, np.random.default_rng(seed))
    return gp.analyze(frames, fps=scene.fps, mm_per_px=scene.mm_per_px), truth


@pytest.mark.parametrize("label", [Label(45.0, 20.0, transmission=0.3), Label(62.0, 12.0)])
def test_plugs_and_bubbles_under_a_translucent_label_are_measured_through_it(label):
    res, truth = _analyze(Scene(labels=(label,)), 11)
    assert res.plug_length_mm == pytest.approx(truth.plug_length_mm, rel=0.05)  # +10 to +14 % before
    assert res.bubble_length_mm == pytest.approx(truth.bubble_length_mm, rel=0.05)
    assert res.celerity_m_s == pytest.approx(truth.celerity_m_s, rel=0.03)
    [seen] = [b for b in res.summary["blind_stretches"] if b["treated"] == "seen through"]
    assert seen["to_mm"] - seen["from_mm"] == pytest.approx(label.length_mm, abs=2.0)
    assert 0 < seen["contrast_left"] < label.transmission + 0.1  # the paper and its marks pass less than it
    assert "still.track" not in res.summary["warning_codes"]


def test_clamps_in_front_light_are_found_as_still():
    clamps = (Clamp(20.0, 6.0), Clamp(70.0, 6.0))
    res, truth = _analyze(Scene(lighting="front", clamps=clamps), 12)
    blind = [b for b in res.summary["blind_stretches"] if b["treated"] == "blind"]
    assert len(blind) == 2
    for b in blind:
        assert b["found_by"] == "still contents" and b["to_mm"] - b["from_mm"] == pytest.approx(6.0, abs=1.0)
    assert res.regime == truth.regime == "propagative"  # "oscillating" before: the clamps cut the plugs
    assert res.plug_length_mm == pytest.approx(truth.plug_length_mm, rel=0.05)  # -37 % before
    assert res.celerity_m_s == pytest.approx(truth.celerity_m_s, rel=0.03)


def _plug_under_a_clamp() -> tuple[Runs, np.ndarray]:
    """One 30-sample plug moving down by a sample a frame over 60 frames across a clamp at samples 40-49."""
    blind = np.zeros(120, bool)
    blind[40:50] = True
    frame, start, stop = [], [], []
    for k in range(60):
        a, b = 10 + k, 40 + k
        for lo, hi in ((a, min(b, 40)), (max(a, 50), b)):  # the plug's pieces either side of the clamp
            if hi - lo >= 3:
                frame.append(k)
                start.append(lo)
                stop.append(hi)
    start_a, stop_a = np.asarray(start), np.asarray(stop)
    top = np.where(blind[np.maximum(start_a - 1, 0)], np.nan, start_a.astype(float))
    bottom = np.where(blind[np.minimum(stop_a, 119)], np.nan, stop_a.astype(float))
    return Runs(np.asarray(frame), start_a, stop_a, top, bottom), blind


def test_a_plug_passing_under_a_clamp_keeps_its_track():
    runs, blind = _plug_under_a_clamp()
    tracks = link(runs, 60, blind=blind)
    assert len(tracks) == 1 and set(tracks.run_track.tolist()) == {0}
    assert tracks.first_frame[0] == 0 and tracks.last_frame[0] == 59
    assert len(link(runs, 60)) > 1  # without the clamp known, the pieces are a split and a merge


def test_edges_inside_a_blind_stretch_are_not_used_for_the_celerity():
    scene = Scene(clamps=(Clamp(30.0, 8.0),))
    res, truth = _analyze(scene, 13)
    [b] = [b for b in res.blind if b.blind]
    assert b.to_mm - b.from_mm == pytest.approx(8.0, abs=1.0)
    edges = res.edges
    for col in ("top_mm", "bottom_mm"):  # nothing measured inside the clamp or against it
        v = edges[col].dropna()
        assert not ((v > b.from_mm - 0.2) & (v < b.to_mm + 0.2)).any()
    assert res.celerity_m_s == pytest.approx(truth.celerity_m_s, rel=0.01)
    assert res.motion.n_edges == np.count_nonzero(np.isfinite(res.runs.top_mm))  # every edge outside is used


def test_a_still_objects_constant_change_of_the_light_is_divided_out():
    rng = np.random.default_rng(5)
    n_t, n_s = 400, 200
    truth = ((np.arange(n_s)[None, :] + 0.7 * np.arange(n_t)[:, None]) % 40 < 24).astype(np.float32)
    z = truth + rng.normal(0, 0.02, truth.shape).astype(np.float32)
    z[:, 80:120] = 0.35 * z[:, 80:120] + 0.3  # seen through a label: a third of the contrast, its own light
    diagram = Diagram(np.ones_like(z), np.arange(n_t) / 250.0, 0.15 * np.arange(n_s), 0.15)
    levels = column_levels(z)
    fixed, through, hidden = seen_through(z, diagram, levels)
    assert np.abs(fixed[:, 80:120] - truth[:, 80:120]).mean() < 0.05
    assert np.array_equal(fixed[:, :75], z[:, :75])  # the open tube is left as it is
    [(lo, hi, left)] = through
    assert (lo, hi) == pytest.approx((12.0, 18.0), abs=0.5)
    assert left == pytest.approx(0.35, abs=0.03)
    assert hidden == []
