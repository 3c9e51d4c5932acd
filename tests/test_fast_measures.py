"""The measures' fast paths agree with plain computations.

The drift fit without the one-hot block of track offsets against ``lstsq`` of the
full design; the falling grains correlated on spread frame pairs against all
pairs; the vectorised bubble lengths against a loop over frames.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy import ndimage

from grainplug.measures import motion
from grainplug.measures.grains import falling_grains
from grainplug.measures.lengths import measure_lengths
from grainplug.plugs.segment import find_runs, plug_mask
from grainplug.plugs.tracking import link


def test_fit_without_one_hot_equals_full_design(rng):
    n_tracks, n = 9, 700
    tix = np.sort(rng.integers(0, n_tracks, n))
    t = rng.uniform(0, 3, n)
    y = -40 * t + rng.normal(0, 5, n_tracks)[tix] + 0.7 * np.sin(2 * np.pi * 6.3 * t) + rng.normal(0, 0.2, n)
    w = rng.uniform(0, 1, n)
    w[tix == 3] = 0.0  # a track with no weight at all: offset 0, as the minimum-norm solution
    for f, nh, weights in ((None, 0, None), (6.3, 3, None), (6.3, 3, w), (None, 0, w)):
        coef, rss, res = motion.fit_edges(t, y, tix, n_tracks, f, nh, weights)
        A = motion.edge_design(t, tix, n_tracks, f, nh)
        sw = np.ones(n) if weights is None else np.sqrt(weights)
        ref, *_ = np.linalg.lstsq(A * sw[:, None], y * sw, rcond=None)
        np.testing.assert_allclose(coef, ref, rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(res, y - A @ ref, rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(rss, float(np.sum(sw**2 * (y - A @ ref) ** 2)), rtol=1e-9)


def test_fit_of_a_rank_deficient_design(rng):
    """Edges seen only at whole periods: the harmonic columns vanish once the track offsets
    are projected out, the normal equations are singular, and the fit falls back to lstsq:
    the same fitted values and drift as the full design, no weight on the dead columns."""
    n_tracks, f = 4, 5.0
    t = np.repeat(np.arange(40) / f, 3)
    tix = np.tile(np.arange(3), 40) + (np.arange(120) >= 60)
    y = -30 * t + rng.normal(0, 0.3, t.size)
    coef, rss, res = motion.fit_edges(t, y, tix, n_tracks, f, 2)
    A = motion.edge_design(t, tix, n_tracks, f, 2)
    assert np.linalg.matrix_rank(A) < A.shape[1]
    ref, *_ = np.linalg.lstsq(A, y, rcond=None)
    np.testing.assert_allclose(res, y - A @ ref, rtol=0, atol=1e-8)
    np.testing.assert_allclose(rss, float(np.sum((y - A @ ref) ** 2)), rtol=1e-9)
    np.testing.assert_allclose(A @ coef, A @ ref, rtol=0, atol=1e-8)
    np.testing.assert_allclose(coef[0], ref[0], rtol=1e-8)
    np.testing.assert_allclose(coef[-4:], 0.0, atol=1e-9)


def test_falling_grains_on_spread_pairs_agrees_with_all_pairs(rng):
    n_t, n_s, shift = 1500, 400, 8  # specks moving 8 samples per frame through a bubble
    z = np.full((n_t, n_s), 0.1, np.float32)
    specks = rng.integers(0, n_s + shift * n_t, 4000)
    for k in range(n_t):
        s = specks - shift * (n_t - k)
        s = s[(s >= 0) & (s < n_s)]
        z[k, s] += 0.25
    z += rng.normal(0, 0.01, z.shape).astype(np.float32)
    all_pairs = falling_grains(z, mm_per_sample=0.2, fps=250.0, max_pairs=n_t)
    spread = falling_grains(z, mm_per_sample=0.2, fps=250.0, max_pairs=300)
    expected = shift * 0.2 * 250.0 / 1000.0
    assert all_pairs.speed_m_s == pytest.approx(expected, abs=0.01)
    assert spread.speed_m_s == pytest.approx(expected, abs=0.01)
    # the specks moving the other way are found moving the other way
    back = falling_grains(z[::-1], mm_per_sample=0.2, fps=250.0, max_pairs=300)
    assert back.speed_m_s == pytest.approx(-expected, abs=0.01)


def _plug_diagram(rng, n_t=240, n_s=500):
    """Contrast diagram of a plug train drifting down and oscillating, with noise: plugs
    and bubbles of random lengths enter at the top and leave at the bottom; cracks split
    plugs for a few frames."""
    lengths = rng.uniform(25, 90, 80)  # plug, bubble, plug, ... in samples
    edges = np.concatenate(([0.0], np.cumsum(lengths))) - lengths.sum() + n_s + 60
    z = np.zeros((n_t, n_s), np.float32)
    s = np.arange(n_s)
    for k in range(n_t):
        shift = 3.0 * k + 6 * np.sin(2 * np.pi * k / 37)
        idx = np.searchsorted(edges + shift, s, side="right")
        z[k] = (idx % 2 == 1) & (idx > 0) & (idx < len(edges))
    # now and then a crack splits a plug for a few frames: short tracks, merges and splits
    for k in rng.choice(n_t - 4, 12, replace=False):
        at = int(rng.integers(20, n_s - 20))
        z[k: k + int(rng.integers(1, 5)), at: at + 12] = 0.0
    z = ndimage.uniform_filter1d(z, 3, axis=1)
    return z + rng.normal(0, 0.15, z.shape).astype(np.float32)


def _bubbles_by_loop(runs, tracks, min_frames):
    """Frame by frame, neighbour by neighbour: the gap between each pair of tracks seen one
    after the other, its median over the frames, kept if seen in >= min_frames frames."""
    gaps: dict[tuple[int, int], list[float]] = {}
    for k in np.unique(runs.frame):
        idx = runs.in_frame(int(k))
        for u, d in itertools.pairwise(idx):
            if np.isfinite(runs.bottom_mm[u]) and np.isfinite(runs.top_mm[d]):
                key = (int(tracks.run_track[u]), int(tracks.run_track[d]))
                gaps.setdefault(key, []).append(float(runs.top_mm[d] - runs.bottom_mm[u]))
    return {key: float(np.median(v)) for key, v in gaps.items() if len(v) >= min_frames}


def test_bubble_lengths_vectorised_equal_the_loop(rng):
    z = _plug_diagram(rng)
    pos = np.arange(z.shape[1]) * 0.2
    mask = plug_mask(z, mm_per_sample=0.2)
    runs = find_runs(z, mask, pos)
    tracks = link(runs, z.shape[0])
    assert len(runs) > 300 and len(tracks) > 10
    sizes = []
    for min_frames in (1, 3, 10, 60):
        got = measure_lengths(runs, tracks, min_frames=min_frames)
        ref = _bubbles_by_loop(runs, tracks, min_frames)
        pairs = [tuple(int(x) for x in p) for p in got.bubble_tracks]
        assert got.bubble_tracks.shape == (len(ref), 2)
        assert got.per_bubble_mm.shape == (len(ref),)
        assert len(set(pairs)) == len(pairs)
        assert dict(zip(pairs, got.per_bubble_mm.tolist(), strict=True)) == pytest.approx(ref, abs=1e-12)
        assert got.n_bubbles_measured == len(ref)
        if ref:
            assert got.bubble_length_mm == pytest.approx(np.mean(list(ref.values())), rel=1e-12)
        else:
            assert got.bubble_length_mm is None
        sizes.append(len(ref))
    assert sizes[0] > sizes[-1] > 0  # the threshold on frames seen does filter


def test_a_length_interval_from_few_values_is_clipped_at_zero_and_shown_as_such():
    """Two bubbles, 5 and 35 mm: the t-interval of their mean reaches below zero; a length cannot, so the
    interval starts at 0, and the report shows it as an interval, not as a symmetric ±."""
    from grainplug.reports.html import with_uncertainty

    pos = np.arange(400) * 0.5
    z = np.zeros((20, pos.size), np.float32)
    for a, b in ((10, 40), (45, 75), (110, 140)):
        z[:, (pos >= a) & (pos < b)] = 1.0
    runs = find_runs(z, plug_mask(z, mm_per_sample=0.5), pos)
    got = measure_lengths(runs, link(runs, z.shape[0]), min_frames=3)
    assert got.n_bubbles_measured == 2 and got.bubble_length_mm == pytest.approx(20.0, abs=0.6)
    lo, hi = got.bubble_length_ci95_mm
    assert lo == 0.0 and hi > 150
    assert with_uncertainty(got.bubble_length_mm, lo, hi) == f"20 (0 to {round(hi, -1):.0f})"  # to 2 digits of ±105
    assert with_uncertainty(30.6, 29.9, 31.3) == "30.6 ± 0.7"  # a centred interval keeps its ±


@pytest.mark.parametrize(("speed_px_per_record", "regime"), [(0.0, "static"), (0.3, "static"), (4.0, "propagative"),
                                                              (-4.0, "propagative")])
def test_plugs_that_do_not_move_by_a_pixel_are_static(rng, speed_px_per_record, regime):
    """Three plugs' upper edges over 200 frames, with 0.05 px of noise: a drift of under a pixel over the record
    (every celerity of the interval too) is static, one of a few pixels is propagative, either way."""
    from grainplug.measures.motion import measure_motion

    fps, mm_per_px, n = 1000.0, 0.2, 200
    t = np.arange(n) / fps
    frames = np.repeat(np.arange(n), 3)
    track = np.tile(np.arange(3), n)
    start_mm = np.array([10.0, 40.0, 70.0])[track]
    top = start_mm + speed_px_per_record * mm_per_px * frames / (n - 1) + rng.normal(0, 0.05 * mm_per_px, 3 * n)
    m = measure_motion(t, top, track, frames, fps=fps, mm_per_px=mm_per_px)
    assert m.regime == regime
    expected = speed_px_per_record * mm_per_px / ((n - 1) / fps) / 1000.0
    lo, hi = m.celerity_ci95_m_s
    assert lo <= expected <= hi


@pytest.mark.parametrize("fps", [5000.0, 2000.0, 250.0])
def test_falling_grains_found_at_any_frame_rate(rng, fps):
    """At thousands of frames per second the grains move under two samples between frames, as slowly as
    plug edges do between consecutive frames: they are followed over the frames they need."""
    n_t, n_s = 600, 400
    shift_per_frame = 0.8 * 1000.0 / (0.1 * fps)  # 0.8 m/s at 0.1 mm per sample
    z = np.full((n_t, n_s), 0.1, np.float32)
    track = n_s + shift_per_frame * n_t
    specks = rng.uniform(0, track, int(0.3 * track))  # as dense at every frame rate
    for k in range(n_t):
        s = np.round(specks - shift_per_frame * (n_t - k)).astype(int)
        s = s[(s >= 0) & (s < n_s)]
        z[k, s] += 0.25
    z += rng.normal(0, 0.01, z.shape).astype(np.float32)
    expected = shift_per_frame * 0.1 * fps / 1000.0
    down = falling_grains(z, mm_per_sample=0.1, fps=fps)
    up = falling_grains(z[::-1], mm_per_sample=0.1, fps=fps)
    assert down.speed_m_s == pytest.approx(expected, rel=0.05)
    assert up.speed_m_s == pytest.approx(-expected, rel=0.05)
    # nothing falling through the bubbles: no speed, and the words say the bubbles were there
    still = falling_grains(z[:1].repeat(n_t, axis=0), mm_per_sample=0.1, fps=fps)
    assert still.speed_m_s is None and still.seen and still.seen != falling_grains(
        np.full((n_t, n_s), 0.9, np.float32), mm_per_sample=0.1, fps=fps).seen
