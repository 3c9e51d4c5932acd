"""The lamp's ripple without a lamp beside the tube (front light), and the recording's cadence (issue 33, item 2).

Front light: a ripple of +-30 % was taken for dark and over-exposed frames, 44 % of the frames were bridged and
the falling grains read as rising (the celerity's sign flipped, silently). A heavily compressed H.264 movie
moves the plug edges in a staircase of its group of pictures (four frames), read as an oscillation at 62.6 Hz.
The movies come from the independent renderer of ``lab_nuisances.py``; the truth from its kinematics.
"""

from __future__ import annotations

import numpy as np
import pytest
from lab_nuisances import OSC, Ripple, Scene, render_movie

import grainplug as gp
from grainplug.diagram.frames import repair_frames
from grainplug.diagram.light import divide_by_lamp, frame_light
from grainplug.measures.motion import frame_locked_hz, measure_motion

C_TRUE = -0.05  # the renderer's default train: plugs climbing at 5 cm/s, grains falling at 0.35 m/s


def _analyse(tmp_path, scene: Scene, seed: int = 2) -> gp.AnalysisResult:
    movie = tmp_path / ("movie.mp4" if scene.fmt == "h264" else "movie.tif")
    render_movie(movie, scene, np.random.default_rng(seed))
    return gp.analyze(movie, fps=scene.fps, mm_per_px=scene.mm_per_px)


@pytest.mark.parametrize(("mains_hz", "fps"), [(100, 250), (120, 250), (120, 300), (120, 400), (100, 500), (100, 1000)])
def test_front_light_ripple_leaves_the_celerity_s_sign_and_the_regime(tmp_path, mains_hz, fps):
    scene = Scene(lighting="front", height_px=400, n_frames=150, fps=float(fps), ripple=Ripple(0.3, float(mains_hz)))
    res = _analyse(tmp_path, scene)
    s = res.summary
    assert s["celerity_m_s"] == pytest.approx(C_TRUE, rel=0.03), s  # the sign first of all
    assert s["regime"] == "propagative"
    assert res.flow_direction == "down" and res.flow_direction_source.startswith("inferred"), res.flow_direction_source
    assert "frames.repaired" not in s["warning_codes"], s["warnings"]  # the ripple is no doubtful frame
    light = s["light"]
    assert light["corrected"] and "front light" in light["source"] and "diagram itself" in light["source"], light
    # the ripple's rms, 0.3 / sqrt(2) of a sinusoid, read within a fifth (the chain's window takes a little)
    assert light["ripple_rms"] == pytest.approx(0.3 / np.sqrt(2), rel=0.2), light


def test_front_light_without_ripple_is_said_steady_and_left_alone(tmp_path):
    res = _analyse(tmp_path, Scene(lighting="front", height_px=400, n_frames=120))
    light = res.summary["light"]
    assert not light["corrected"] and "front light" in light["source"] and "steady" in light["source"], light
    assert light["ripple_rms"] < 0.005
    assert res.summary["celerity_m_s"] == pytest.approx(C_TRUE, rel=0.03)


def _moving_diagram(rng: np.random.Generator, n: int = 300, p: int = 500) -> np.ndarray:
    """Plugs (level 100) and bubbles (25) of a front-lit diagram moving 1.3 samples a frame, with noise."""
    s = np.arange(p)[None, :] + 1.3 * np.arange(n)[:, None]
    plug = (s % 160) < 95
    return (np.where(plug, 100.0, 25.0) + rng.normal(0, 2.5, (n, p))).astype(np.float32)


def test_the_light_read_on_the_diagram_is_the_ripple_and_spares_a_blank_frame(rng):
    clean = _moving_diagram(rng)
    k = np.arange(len(clean))
    ripple = 1 + 0.3 * np.sin(2 * np.pi * 120.0 * k / 250.0 + 0.4)  # 120 Hz at 250 fps: near the Nyquist rate
    values = clean * ripple[:, None].astype(np.float32)
    values[100:103] = 0.5  # the lamp failed for three frames
    gain, rms, noise = frame_light(values)
    lit = np.ones(len(k), bool)
    lit[100:103] = False
    # the ripple (a ripple this fast averages out over 16 frames): within 1.5 % away from the record's ends and
    # the blank frames, within 5 % next to them (where fewer frames are averaged)
    ratio = gain / ripple
    ratio /= np.median(ratio[lit])
    inner = lit.copy()
    inner[:8], inner[-8:], inner[92:111] = False, False, False
    np.testing.assert_allclose(ratio[inner], 1.0, atol=0.015)
    np.testing.assert_allclose(ratio[lit], 1.0, atol=0.05)
    assert np.all(gain[100:103] == 1.0)  # the blank frames are not lit up
    assert rms > 10 * noise
    divided, lamp = divide_by_lamp(values, np.zeros((len(k), 0)), np.zeros(0), back_lit=False)
    assert lamp.corrected
    _, repair = repair_frames(divided, top=255.0)
    assert repair.dark.tolist() == [100, 101, 102] and repair.n_bad == 3  # what is still doubtful is bridged
    _, before = repair_frames(values, top=255.0)
    assert before.n_bad > 50  # what the ripple did undivided


def test_a_steady_light_is_not_divided(rng):
    values = _moving_diagram(rng)
    out, lamp = divide_by_lamp(values, np.zeros((len(values), 0)), np.zeros(0), back_lit=False)
    assert not lamp.corrected and np.shares_memory(out, values)
    assert lamp.ripple_rms is not None and lamp.ripple_rms < 0.005


def _staircase_edges(fps: float, n: int = 250, hold: int = 4) -> tuple[np.ndarray, ...]:
    """Upper edges of four tracked plugs moving at -0.05 m/s as a codec shows them: held still in the predicted
    frames of each group of ``hold`` frames, moved at its reference frame (a staircase)."""
    t = np.arange(n) / fps
    frame = np.repeat(np.arange(n), 4)
    step_t = t[(np.arange(n) // hold) * hold]  # the time of each frame's reference
    top = (np.array([5.0, 29.0, 53.0, 77.0])[None, :] - 50.0 * step_t[:, None]).ravel()
    return t, top, np.tile(np.arange(4), n), frame


@pytest.mark.parametrize("fps", [250.0, 500.0])
def test_a_codec_s_staircase_is_no_oscillation(fps):
    t, top, track, frame = _staircase_edges(fps)
    m = measure_motion(t, top, track, frame, fps=fps, mm_per_px=0.15, frame_cadence=True)
    assert m.regime == "propagative" and m.oscillation_frequency_hz is None
    assert m.celerity_m_s == pytest.approx(-0.05, rel=0.02)
    assert m.frame_locked_hz == pytest.approx(fps / 4, abs=0.3)  # said apart, for the warning
    # uncompressed, the same edges are an oscillation (nothing tells them from one), named as frame-locked
    u = measure_motion(t, top, track, frame, fps=fps, mm_per_px=0.15)
    assert u.regime == "oscillating" and u.oscillation_frequency_hz == pytest.approx(fps / 4, abs=0.3)
    assert u.frame_locked_hz == u.oscillation_frequency_hz


def test_frame_locked_frequencies_repeat_within_eight_frames():
    f = frame_locked_hz(250.0, 112.5)
    assert f[0] == pytest.approx(250 / 8) and 62.5 in f and 100.0 in f and 50.0 in f  # 100 Hz: 2 periods in 5 frames
    assert all(f_ <= 112.5 for f_ in f) and not any(abs(x - 5.0) < 1 for x in f)


def test_h264_cadence_alone_is_no_oscillation_and_is_said(tmp_path):
    res = _analyse(tmp_path, Scene(height_px=400, n_frames=250, fmt="h264", crf=35), seed=3)
    s = res.summary
    assert s["regime"] == "propagative" and s["oscillation_frequency_hz"] is None
    assert s["celerity_m_s"] == pytest.approx(C_TRUE, rel=0.03)
    assert "plugs.frame_cadence" in s["warning_codes"], s["warnings"]


@pytest.mark.parametrize("scene", [
    Scene(lighting="front", height_px=400, n_frames=300, motion=OSC, ripple=Ripple(0.3, 120.0)),
    Scene(height_px=400, n_frames=300, motion=OSC, ripple=Ripple(0.3, 100.0), fmt="h264", crf=35),
], ids=["front light, ripple 120 Hz", "back light, ripple 100 Hz, H.264 crf 35"])
def test_a_real_oscillation_is_found_through_flicker_and_compression(tmp_path, scene):
    res = _analyse(tmp_path, scene, seed=3)
    s = res.summary
    assert s["regime"] == "oscillating"
    assert s["oscillation_frequency_hz"] == pytest.approx(OSC.frequency_hz, abs=0.3)
    assert s["celerity_m_s"] == pytest.approx(OSC.celerity_m_s, rel=0.03)
    assert "plugs.frame_cadence" not in s["warning_codes"]


def test_the_falling_grains_are_read_on_frames_seen_only(rng):
    """Bridged frames are interpolations, not observations: their pairs are left out of the grains' correlation
    (with a ripple taken for dark and bright frames, the bridged ones made the grains read as rising)."""
    from grainplug.measures.grains import falling_grains

    n, p, d = 120, 600, 9  # specks falling 9 samples a frame (0.34 m/s at 0.15 mm and 250 fps)
    falling_at = rng.uniform(0, 3 * p, 60)
    rising_at = rng.uniform(0, 3 * p, 150)
    bridged = np.flatnonzero(np.arange(n) % 4 >= 2)  # half the frames, in pairs: here a denser, rising pattern
    z = np.zeros((n, p), np.float32)
    for k in range(n):
        pos = (falling_at + d * k) if k % 4 < 2 else (rising_at - d * k)
        pos = (pos % (3 * p)).astype(int)
        z[k, pos[pos < p]] = 0.3
    everything = falling_grains(z, mm_per_sample=0.15, fps=250.0)
    assert everything.speed_m_s is not None and everything.speed_m_s < 0  # what the bridged frames say
    seen = falling_grains(z, mm_per_sample=0.15, fps=250.0, unseen=bridged)
    assert seen.speed_m_s == pytest.approx(d * 0.15 * 250 / 1000, rel=0.02)
