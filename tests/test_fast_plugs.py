"""The plug stage's vectorised paths agree with plain loops.

Runs and their sub-sample edges against a row-by-row loop; the row closing
against ``ndimage.binary_closing``; linking every frame at once against the
frame-by-frame linking it replaced.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from grainplug._filters import gaussian_filter1d
from grainplug.plugs.segment import Runs, close_rows, find_runs, plug_mask
from grainplug.plugs.tracking import Tracks, link


def _runs_by_loop(z, mask, pos):
    """One row at a time, one run at a time (the same smoothing: the filter itself is held to
    scipy's by test_filters.py)."""
    zs = gaussian_filter1d(z.astype(np.float32), 0.7, axis=1, mode="nearest")
    ds, out = pos[1] - pos[0], []
    for k in range(mask.shape[0]):
        row = np.concatenate(([False], mask[k], [False]))
        d = np.diff(row.astype(int))
        for a, b in zip(np.nonzero(d == 1)[0], np.nonzero(d == -1)[0], strict=True):
            def cross(i_out, i_in, p=zs[k]):
                lo, hi = float(p[i_out]), float(p[i_in])
                f = 0.5 if lo == hi else min(max((0.5 - lo) / (hi - lo), 0.0), 1.0)
                return pos[0] + ds * (i_out + f * (i_in - i_out))
            top = np.nan if a == 0 else cross(a - 1, a)
            bot = np.nan if b == mask.shape[1] else cross(b, b - 1)
            out.append((k, a, b, top, bot))
    return out


def test_runs_vectorised_equal_loop(rng):
    z = ndimage.uniform_filter((rng.random((120, 300)) < 0.5).astype(np.float32), (1, 25))
    z = (z > 0.5) * 0.9 + rng.normal(0, 0.12, z.shape)
    pos = np.arange(300) * 0.185
    mask = plug_mask(z, mm_per_sample=0.185)
    # the mask keeps only runs that are long enough
    for k in range(0, 120, 17):
        row = np.concatenate(([False], mask[k], [False]))
        d = np.diff(row.astype(int))
        assert (np.nonzero(d == -1)[0] - np.nonzero(d == 1)[0]).min() >= round(3.0 / 0.185)
    runs = find_runs(z, mask, pos)
    ref = _runs_by_loop(z, mask, pos)
    assert len(runs) == len(ref) > 100
    got = list(zip(runs.frame, runs.start, runs.stop, runs.top_mm, runs.bottom_mm, strict=True))
    np.testing.assert_allclose(np.array(got, float), np.array(ref, float), rtol=0, atol=1e-9)


@pytest.mark.parametrize("length", [2, 3, 4, 5, 6, 7, 8])
def test_row_closing_equals_binary_closing(length):
    rng = np.random.default_rng(length)
    changed = 0
    for p in (0.2, 0.5, 0.8, 0.95):
        mask = rng.random((60, 97)) < p
        expected = ndimage.binary_closing(mask, structure=np.ones((1, length), bool), border_value=0)
        np.testing.assert_array_equal(close_rows(mask, length), expected)
        changed += int((expected != mask).sum())
    assert changed > 0  # holes were filled (and border runs cut)


def _link_frame_by_frame(runs, n_frames):
    """The former frame-by-frame linking: the reference for the vectorised one."""
    n = len(runs)
    track = -np.ones(n, int)
    first: list[int] = []
    last: list[int] = []
    started: list[str] = []
    ended: list[str] = []

    def new_track(i: int, how: str) -> None:
        track[i] = len(first)
        first.append(int(runs.frame[i]))
        last.append(int(runs.frame[i]))
        started.append(how)
        ended.append("end")

    prev = runs.in_frame(0)
    for i in prev:
        new_track(i, "start")
    for k in range(1, n_frames):
        cur = runs.in_frame(k)
        if len(prev) == 0:
            for i in cur:
                new_track(i, "entered")
            prev = cur
            continue
        # overlap matrix of the runs of the two frames
        ps, pe = runs.start[prev], runs.stop[prev]
        cs, ce = runs.start[cur], runs.stop[cur]
        ov = (np.minimum(pe[:, None], ce[None, :]) - np.maximum(ps[:, None], cs[None, :])) > 0
        n_succ = ov.sum(axis=1)
        n_pred = ov.sum(axis=0)
        for j, i in enumerate(cur):
            preds = np.nonzero(ov[:, j])[0]
            if len(preds) == 1 and n_succ[preds[0]] == 1:
                t = track[prev[preds[0]]]
                track[i] = t
                last[t] = k
            elif len(preds) == 0:
                new_track(i, "entered")
            elif len(preds) > 1:
                new_track(i, "merge")
            else:
                new_track(i, "split")
        for m, i in enumerate(prev):
            t = track[i]
            if last[t] == k:
                continue
            if n_succ[m] == 0:
                ended[t] = "left"
            elif n_succ[m] > 1:
                ended[t] = "split"
            else:
                j = int(np.nonzero(ov[m])[0][0])
                ended[t] = "merge" if n_pred[j] > 1 else "split"
        prev = cur
    # a track that stopped at the last frame ended with the movie; one cut earlier left the view
    for t in range(len(first)):
        if ended[t] == "end" and last[t] < n_frames - 1:
            ended[t] = "left"
    return Tracks(track, np.asarray(first, int), np.asarray(last, int), started, ended)


def _random_runs(rng, n_frames, width=200):
    """Runs that move, merge, split, appear and vanish; some frames empty."""
    frames, starts, stops = [], [], []
    for k in range(n_frames):
        if rng.random() < 0.05:
            continue  # an empty frame
        edges = np.sort(rng.choice(np.arange(1, width), size=2 * rng.integers(0, 6), replace=False))
        for a, b in edges.reshape(-1, 2):
            frames.append(k)
            starts.append(a)
            stops.append(b)
    f, a, b = (np.asarray(x, int) for x in (frames, starts, stops))
    nan = np.full(len(f), np.nan)
    return Runs(f, a, b, nan, nan)


def test_link_all_frames_at_once_equals_frame_by_frame(rng):
    cases = [_random_runs(rng, n) for n in (1, 2, 5, 40, 300)]
    # smooth motion: long tracks, the usual case
    k = np.repeat(np.arange(200), 3)
    a = (np.tile([10, 80, 150], 200) + np.repeat(np.arange(200) // 4, 3)) % 190
    order = np.lexsort((a, k))
    cases.append(Runs(k[order], a[order], a[order] + 20, np.zeros(600), np.zeros(600)))
    cases.append(Runs(*(np.zeros(0, int) for _ in range(3)), np.zeros(0), np.zeros(0)))
    seen = set()
    long_tracks = False
    for runs in cases:
        for extra in (0, 2):  # runs in the last frame end with the movie; earlier ones leave
            n_frames = (int(runs.frame.max()) + 1 if len(runs) else 1) + extra
            want, got = _link_frame_by_frame(runs, n_frames), link(runs, n_frames)
            np.testing.assert_array_equal(got.run_track, want.run_track)
            np.testing.assert_array_equal(got.first_frame, want.first_frame)
            np.testing.assert_array_equal(got.last_frame, want.last_frame)
            assert got.started_by == want.started_by
            assert got.ended_by == want.ended_by
            seen |= set(got.started_by) | set(got.ended_by)
            long_tracks |= bool(len(got) and (got.last_frame - got.first_frame).max() > 20)
    assert seen == {"start", "entered", "merge", "split", "end", "left"}  # every branch taken
    assert long_tracks
