"""The fast paths of the analysis agree with slower, independent computations.

Each optimisation of the performance work (issue 6) is checked here against a
straightforward method: scipy's interpolation for the sheared profiles, the full
least-squares design for the drift fits, per-row loops for the runs, all frame
pairs for the falling grains, in-process drawing for the figure helper.
"""

from __future__ import annotations

import os
import pickle

import numpy as np
import pytest
from scipy import ndimage

from grainplug.analysis import analyze
from grainplug.calibration.tube import _bin, _grey_binned, sheared_profile, to_grey
from grainplug.measures import motion
from grainplug.measures.grains import falling_grains
from grainplug.outputs import FigureWorker, draw_figures, figure_payload
from grainplug.plugs.segment import find_runs, plug_mask
from grainplug.synthetic import SynthConfig, synthesize


def _profile_by_map_coordinates(img, tan_b, x_grid, rows=None):
    """The definition: linear interpolation along every line, with scipy."""
    h, w = img.shape
    ys = np.arange(h, dtype=float)[rows if rows is not None else slice(None)]
    yy = np.repeat(ys[:, None], len(x_grid), axis=1)
    xx = x_grid[None, :] + (ys[:, None] + 0.5) * tan_b
    vals = ndimage.map_coordinates(img.astype(float), [yy, xx], order=1, mode="constant", cval=np.nan)
    vals[(xx < 0) | (xx > w - 1)] = np.nan
    count = np.isfinite(vals).sum(axis=0)
    out = np.full(len(x_grid), np.nan)
    ok = count >= max(1, 0.3 * len(ys))
    out[ok] = np.nansum(vals, axis=0)[ok] / count[ok]
    return out, xx


@pytest.mark.parametrize("step", [1.0, 0.5, 0.25, 0.1, 0.05, 0.3])
@pytest.mark.parametrize("tan_b", [0.0, 0.037, -0.105])
def test_sheared_profile_equals_interpolation(rng, step, tan_b):
    img = rng.random((90, 70)).astype(np.float32)
    grid = np.arange(-8.3, 78.0, step)
    ref, xx = _profile_by_map_coordinates(img, tan_b, grid)
    got = sheared_profile(img, tan_b, grid)
    # away from the image's sides (where the splatted weights are partial by design)
    far = (np.abs(xx) > 1.01).all(axis=0) & (np.abs(xx - 69) > 1.01).all(axis=0)
    both = far & np.isfinite(ref)
    assert both.sum() > 20
    np.testing.assert_allclose(got[both], ref[both], rtol=0, atol=2e-6)
    assert np.array_equal(np.isnan(got[far]), np.isnan(ref[far]))
    block = slice(30, 50)
    ref_b, _ = _profile_by_map_coordinates(img, tan_b, grid, block)
    got_b = sheared_profile(img, tan_b, grid, block)
    ok = far & np.isfinite(ref_b)
    np.testing.assert_allclose(got_b[ok], ref_b[ok], rtol=0, atol=2e-6)


@pytest.mark.parametrize("b", [1, 2, 4, 8])
@pytest.mark.parametrize("shape", [(64, 48, 3), (66, 50), (37, 41, 3)])
def test_grey_binned_is_exact(rng, b, shape):
    frame = rng.integers(0, 256, shape, dtype=np.uint8)
    np.testing.assert_allclose(_grey_binned(frame, b), _bin(to_grey(frame), b), rtol=0, atol=1e-4)


def test_fit_without_one_hot_equals_full_design(rng):
    n_tracks, n = 9, 700
    tix = np.sort(rng.integers(0, n_tracks, n))
    t = rng.uniform(0, 3, n)
    y = -40 * t + rng.normal(0, 5, n_tracks)[tix] + 0.7 * np.sin(2 * np.pi * 6.3 * t) + rng.normal(0, 0.2, n)
    w = rng.uniform(0, 1, n)
    w[tix == 3] = 0.0  # a track with no weight at all: offset 0, as the minimum-norm solution
    for f, nh, weights in ((None, 0, None), (6.3, 3, None), (6.3, 3, w), (None, 0, w)):
        coef, rss, res = motion._fit_res(t, y, tix, n_tracks, f, nh, weights)
        A = motion._design(t, tix, n_tracks, f, nh)
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
    coef, rss, res = motion._fit_res(t, y, tix, n_tracks, f, 2)
    A = motion._design(t, tix, n_tracks, f, 2)
    ref, *_ = np.linalg.lstsq(A, y, rcond=None)
    np.testing.assert_allclose(res, y - A @ ref, rtol=0, atol=1e-8)
    np.testing.assert_allclose(rss, float(np.sum((y - A @ ref) ** 2)), rtol=1e-9)
    np.testing.assert_allclose(A @ coef, A @ ref, rtol=0, atol=1e-8)
    np.testing.assert_allclose(coef[0], ref[0], rtol=1e-8)
    np.testing.assert_allclose(coef[-4:], 0.0, atol=1e-9)


def _runs_by_loop(z, mask, pos):
    """One row at a time, one run at a time."""
    zs = ndimage.gaussian_filter1d(z.astype(np.float32), 0.7, axis=1, mode="nearest")
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
    # the mask keeps exactly the runs of the smoothed, closed mask that are long enough
    for k in range(0, 120, 17):
        row = np.concatenate(([False], mask[k], [False]))
        d = np.diff(row.astype(int))
        assert (np.nonzero(d == -1)[0] - np.nonzero(d == 1)[0]).min() >= round(3.0 / 0.185)
    runs = find_runs(z, mask, pos)
    ref = _runs_by_loop(z, mask, pos)
    assert len(runs) == len(ref) > 100
    got = list(zip(runs.frame, runs.start, runs.stop, runs.top_mm, runs.bottom_mm, strict=True))
    np.testing.assert_allclose(np.array(got, float), np.array(ref, float), rtol=0, atol=1e-9)


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


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    d = tmp_path_factory.mktemp("fw")
    movie = synthesize(SynthConfig(n_frames=120, seed=2, regime="oscillating", celerity_m_s=0.03,
                                   frequency_hz=8.0), d, fmt="tiff").movie
    return analyze(movie)


def test_figure_payload_is_small_and_drawable(result, tmp_path):
    small = figure_payload(result)
    assert small.normalized is None
    assert small.diagram.values.shape[0] <= 1200 and small.diagram.values.shape[1] <= 1200
    assert len(pickle.dumps(small)) < len(pickle.dumps(result))
    assert {p.name for p in draw_figures(small, tmp_path)} == {"diagram.png", "frame.png", "spectrum.png"}


def test_figure_worker_draws_in_a_helper_and_falls_back(result, tmp_path, monkeypatch):
    here, there = tmp_path / "here", tmp_path / "there"
    here.mkdir()
    there.mkdir()
    draw_figures(result, here)
    with FigureWorker() as fw:
        assert fw.running
        names = {p.name for p in fw.draw(result, there)}
    assert names == {"diagram.png", "frame.png", "spectrum.png"}
    for name in names:
        assert (there / name).stat().st_size > 0.5 * (here / name).stat().st_size
    # a result that cannot be sent to the helper: drawn here instead, with a warning logged
    fallback = tmp_path / "fallback"
    fallback.mkdir()
    monkeypatch.setattr("grainplug.outputs.figure_payload", lambda res: (lambda: None))
    with FigureWorker() as fw:
        names = {p.name for p in fw.draw(result, fallback)}
        assert not fw.running
    assert names == {"diagram.png", "frame.png", "spectrum.png"}


def test_figures_drawn_side_by_side_match_and_report_a_failure(result, tmp_path):
    """The helper draws the figures in forked children (a process of its own: pytest's
    may hold threads). Same files as drawn one by one; a child's failure is raised."""
    import subprocess
    import sys

    job = tmp_path / "job.pkl"
    job.write_bytes(pickle.dumps(figure_payload(result)))
    serial, forked = tmp_path / "serial", tmp_path / "forked"
    serial.mkdir()
    forked.mkdir()
    draw_figures(pickle.loads(job.read_bytes()), serial)
    code = (
        "import pickle, sys\n"
        "import grainplug.plotting.figures as figures\n"
        "from grainplug.outputs import draw_figures\n"
        f"res = pickle.loads(open({str(job)!r}, 'rb').read())\n"
        "if sys.argv[2] == 'fail':\n"
        "    def boom(res):\n"
        "        raise ValueError('no frame')\n"
        "    figures.plot_annotated_frame = boom\n"
        "    import grainplug.plotting as plotting\n"
        "    plotting.plot_annotated_frame = boom\n"
        "try:\n"
        "    print(sorted(p.name for p in draw_figures(res, sys.argv[1], fork=True)))\n"
        "except RuntimeError as exc:\n"
        "    print('failed:', exc)\n"
    )
    env = {**os.environ, "MPLBACKEND": "Agg"}
    ok = subprocess.run([sys.executable, "-c", code, str(forked), "ok"], capture_output=True, text=True,
                        env=env, check=True)
    assert ok.stdout.strip() == "['diagram.png', 'frame.png', 'spectrum.png']"
    for name in ("diagram.png", "frame.png", "spectrum.png"):
        assert (forked / name).read_bytes() == (serial / name).read_bytes()
    broken = tmp_path / "broken"
    broken.mkdir()
    bad = subprocess.run([sys.executable, "-c", code, str(broken), "fail"], capture_output=True, text=True,
                         env=env, check=True)
    assert bad.stdout.strip() == "failed: drawing frame.png failed"


def _wait(cond, timeout=5.0):
    import time

    t0 = time.monotonic()
    while not cond():
        if time.monotonic() - t0 > timeout:
            return False
        time.sleep(0.002)
    return True


def test_prefetch_window_follows_the_stream(tmp_path, monkeypatch):
    """A movie larger than the read-ahead budget is requested chunk by chunk from a
    background thread, never more than the budget ahead of the frame being read,
    contiguously, to its end; closing the movie stops the thread."""
    import os
    import threading

    from grainplug import _system
    from grainplug.readers import base, open_movie

    movie = synthesize(SynthConfig(n_frames=64, seed=1), tmp_path, fmt="tiff").movie
    size = movie.stat().st_size
    calls: list[tuple[int, int]] = []
    lock = threading.Lock()

    def record(fd, off, n, advice):
        with lock:
            calls.append((off, n))

    monkeypatch.setattr(os, "posix_fadvise", record, raising=False)
    monkeypatch.setattr(_system, "read_to_cache", lambda fd, null, off, n: record(fd, off, n, None))
    monkeypatch.setattr(_system, "readahead_chunk_bytes", lambda path: 64 * 1024)
    monkeypatch.setattr(base, "free_memory_bytes", lambda: size / 2)  # budget: a quarter of the file
    budget = int(size / 4)
    with open_movie(movie) as m:
        m.prefetch()
        ra = m._readahead
        assert _wait(lambda: ra.requested_to >= budget)
        assert ra.requested_to == budget
        offset, dt = m._contiguous
        frame_bytes = m.info.width * m.info.height * m.info.channels * dt.itemsize
        for k, _ in enumerate(m.analysis_frames()):
            assert ra.requested_to <= offset + k * frame_bytes + budget + 1
        end = offset + m.info.n_frames * frame_bytes
        assert _wait(lambda: ra.requested_to >= min(size, offset + 48 * frame_bytes + budget))
        assert ra.requested_to >= end  # every frame asked for
        thread = ra._thread
    assert _wait(lambda: not thread.is_alive())
    ends = [off + n for off, n in calls]
    assert all(n <= 64 * 1024 for _, n in calls) and len(calls) > 20
    assert all(calls[i + 1][0] == ends[i] for i in range(len(calls) - 1))  # contiguous, no re-request


@pytest.mark.parametrize("fmt", ["tiff", "avi"])
def test_readahead_asks_only_for_the_band_of_a_horizontal_tube(tmp_path, monkeypatch, fmt):
    """A horizontal tube crosses a landscape frame: once the tube is found, the
    read-ahead asks only for the rows its band touches, for every frame, and the
    analysis is the same as with the whole file read."""
    import os
    import threading

    from grainplug import _system
    from grainplug.readers import base

    movie = synthesize(SynthConfig(n_frames=60, seed=3, flow_direction="right", width_px=96,
                                   celerity_m_s=-0.05), tmp_path, fmt=fmt).movie
    size = movie.stat().st_size
    calls: list[tuple[int, int]] = []
    lock = threading.Lock()

    def record(fd, off, n, advice):
        with lock:
            calls.append((off, off + n))

    seen: list[tuple] = []
    original = base.Movie.prefetch_only

    def spy(self, lo, hi):
        with lock:
            taken = original(self, lo, hi)
            calls.append(None)  # what follows was asked for under the restriction
        seen.append((lo, hi, self.frame_offsets(), taken))
        return taken

    monkeypatch.setattr(os, "posix_fadvise", record, raising=False)
    monkeypatch.setattr(_system, "read_to_cache", lambda fd, null, off, n: record(fd, off, n, None))
    monkeypatch.setattr(_system, "readahead_chunk_bytes", lambda path: 16 * 1024)
    monkeypatch.setattr(base, "free_memory_bytes", lambda: size / 10)  # window: a fifth of the file
    monkeypatch.setattr(base.Movie, "prefetch_only", spy)
    monkeypatch.setattr(_system.ReadAhead, "MIN_SKIP_BYTES", 0)  # the test's frames are small
    res = analyze(movie)
    assert res.tube.orientation == "horizontal"
    (lo, hi, offsets, taken), = seen
    assert taken
    frame_bytes = int(offsets[1] - offsets[0])
    assert hi - lo < frame_bytes / 3  # the band is a small part of the frame
    after = calls[calls.index(None) + 1:]
    assert after  # the stream went on under the restriction
    page = _system.ReadAhead.PAGE
    lo_p, hi_p = lo // page * page, -(-hi // page) * page
    for a, b in after:  # nothing but bands (or their part not asked for yet)
        assert any(off + lo_p <= a < b <= off + hi_p for off in offsets), (a, b)

    monkeypatch.setattr(_system.ReadAhead, "MIN_SKIP_BYTES", 1 << 40)  # never restrict
    seen.clear()
    whole = analyze(movie)
    assert seen[0][3] is False
    np.testing.assert_array_equal(whole.diagram.values, res.diagram.values)
    assert whole.summary["celerity_m_s"] == res.summary["celerity_m_s"]


@pytest.mark.parametrize("direction", ["down", "right"])
def test_coarse_stage_band_holds_the_tube(direction):
    """The band the tube search's first stage hands out holds the whole bore the second
    stage measures, over every row, tilted or not."""
    from grainplug.calibration import find_tube
    from grainplug.synthetic.render import Renderer

    cfg = SynthConfig(n_frames=16, seed=4, flow_direction=direction, width_px=600, height_px=760, tilt_deg=2.0)
    r = Renderer(cfg)
    frames = [r.frame(k) for k in range(0, 16, 2)]
    seen = []
    tube = find_tube(frames, on_coarse=lambda *a: seen.append(a))
    (orientation, lo, hi), = seen
    assert orientation == tube.orientation == ("vertical" if direction == "down" else "horizontal")
    axis = tube.axis_x(np.array([0.0, tube.canonical_shape[0] - 1.0]))
    half = 0.5 * tube.inner_diameter_px / np.cos(np.radians(tube.tilt_deg))
    assert lo <= axis.min() - half and axis.max() + half <= hi
    assert hi - lo < 0.5 * tube.canonical_shape[1]  # and it is a band, not the frame


def test_readahead_narrows_at_the_coarse_stage_then_to_the_band(tmp_path, monkeypatch):
    """Large landscape frames with a horizontal tube: the read-ahead is restricted as
    soon as the first stage of the tube search knows where the tube lies (not after
    the fine stage), then narrowed to the band the analysis reads, which lies within."""
    from grainplug import _system
    from grainplug.readers import base

    movie = synthesize(SynthConfig(n_frames=24, seed=5, flow_direction="right", width_px=400, height_px=800,
                                   celerity_m_s=-0.05), tmp_path, fmt="tiff").movie
    seen: list[tuple] = []
    original = base.Movie.prefetch_only

    def spy(self, lo, hi):
        taken = original(self, lo, hi)
        seen.append((lo, hi, taken))
        return taken

    monkeypatch.setattr(base.Movie, "prefetch_only", spy)
    monkeypatch.setattr(_system.ReadAhead, "MIN_SKIP_BYTES", 0)  # the test's frames are small
    res = analyze(movie)
    assert res.tube.orientation == "horizontal"
    (lo1, hi1, taken1), (lo2, hi2, taken2) = seen
    assert taken1 and taken2
    assert lo1 <= lo2 < hi2 <= hi1
    assert hi1 - lo1 < 0.5 * 800 * 400 * 3  # the first restriction already skips most of a frame


def test_readahead_restricts_only_when_it_skips_enough(tmp_path, monkeypatch):
    import os

    from grainplug._system import ReadAhead

    path = tmp_path / "f.bin"
    path.write_bytes(b"\0" * 100)
    monkeypatch.setattr(os, "posix_fadvise", lambda *a: None, raising=False)
    ra = ReadAhead(path, 10)
    mib = 1 << 20
    frames = [k * 4 * mib for k in range(10)]
    assert not ra.restrict(frames, 0, 3 * mib + 1)  # skips less than 1 MiB
    assert not ra.restrict(frames, 0, 2 * mib + 1)  # skips less than it keeps
    assert not ra.restrict(frames[:1], 0, 10)
    assert not ra.restricted
    assert ra.restrict(frames, mib, 2 * mib)
    assert ra.restricted
    ra.close()


def test_restricted_readahead_asks_for_every_band_once(tmp_path, monkeypatch):
    """Under a restriction the read-ahead asks, in file order, for exactly the band
    of every frame (page-aligned), within its window, and for nothing else."""
    import os
    import threading

    from grainplug import _system

    frame, n = 64 * 1024, 40
    path = tmp_path / "frames.raw"
    path.write_bytes(b"\0" * (512 + frame * n))
    offsets = [512 + k * frame for k in range(n)]
    calls: list[tuple[int, int]] = []
    lock = threading.Lock()

    def record(fd, off, size, advice):
        with lock:
            calls.append((off, off + size))

    monkeypatch.setattr(os, "posix_fadvise", record, raising=False)
    monkeypatch.setattr(_system, "readahead_chunk_bytes", lambda p: 8192)
    monkeypatch.setattr(_system.ReadAhead, "MIN_SKIP_BYTES", 0)
    ra = _system.ReadAhead(path, 5 * frame, paused=True)
    assert ra.restrict(offsets, 10_000, 20_000)
    ra.resume()
    assert _wait(lambda: ra.requested_to >= offsets[4] + 20_480)
    assert all(b <= 512 + 5 * frame for _, b in calls)  # within the window
    ra.advance(path.stat().st_size)
    assert _wait(lambda: not ra._thread.is_alive())
    assert calls == [(off + 8192, off + 20_480) for off in offsets]


def test_figure_worker_survives_a_dead_helper(result, tmp_path):
    with FigureWorker() as fw:  # dead before the job
        fw._proc.kill()
        fw._proc.wait()
        assert {p.name for p in fw.draw(result, tmp_path)} == {"diagram.png", "frame.png", "spectrum.png"}
    for k in range(2):  # dead while the job is on its way
        folder = tmp_path / f"mid{k}"
        folder.mkdir()
        with FigureWorker() as fw:
            proc = fw._proc
            pending = fw.submit(result, folder)
            proc.kill()
            assert {p.name for p in pending()} == {"diagram.png", "frame.png", "spectrum.png"}
            assert not fw.running


def test_cli_asks_for_the_movie_before_importing(tmp_path, monkeypatch):
    import os

    from grainplug import _system
    from grainplug.cli import _early_readahead

    movie = tmp_path / "run.tif"
    movie.write_bytes(b"\0" * 10_000)
    (tmp_path / "out").mkdir()
    calls: list[tuple[int, int]] = []
    monkeypatch.setattr(os, "posix_fadvise", lambda fd, off, n, adv: calls.append((off, n)), raising=False)
    monkeypatch.setattr(_system, "read_to_cache", lambda fd, null, off, n: calls.append((off, n)))
    started = _early_readahead(["--debug", "analyze", str(movie), "--out", str(tmp_path / "out"), "--fps", "250"])
    assert len(started) == 1
    assert _wait(lambda: started[0].requested_to == 10_000)
    assert calls == [(0, 10_000)]
    assert _early_readahead(["info", str(movie)]) == []


@pytest.mark.parametrize("preset", [None, "3"])
def test_cli_runs_blas_on_one_thread_unless_told(preset):
    """The command line sets the BLAS pools to one thread before numpy is imported,
    and leaves a value the user set alone."""
    import os
    import subprocess
    import sys

    code = ("import sys; from grainplug.cli import main; assert 'numpy' not in sys.modules; "
            "main(['--version']); import os, numpy; "
            "print(os.environ['OPENBLAS_NUM_THREADS'], os.environ['OMP_NUM_THREADS'])")
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS",
                                                            "MKL_NUM_THREADS")}
    if preset:
        env["OPENBLAS_NUM_THREADS"] = preset
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.split()[-2:] == [preset or "1", "1"]


@pytest.mark.parametrize("fmt", ["avi", "ffv1", "h264", "mjpeg"])
def test_video_read_seeks_to_the_frame(tmp_path, fmt):
    """``read(k)`` reaches frame k by seeking (no decoding from the start) and returns
    the same frame as streaming does, for intra-only and inter-coded video."""
    from grainplug.readers import open_movie

    movie = synthesize(SynthConfig(n_frames=60, seed=3), tmp_path, fmt=fmt).movie
    with open_movie(movie, verify=True) as m:
        every = list(m.frames())
        for k in (1, 17, 33, 59):
            seeked = m._read_by_seeking(k)
            assert seeked is not None, k
            np.testing.assert_array_equal(seeked, every[k])
            np.testing.assert_array_equal(m.read(k), every[k])
    with open_movie(movie) as m:  # without the packets counted: the frame rate gives the time
        np.testing.assert_array_equal(m.read(41), every[41])


def test_threaded_stream_equals_serial(tmp_path):
    from grainplug.calibration import find_tube
    from grainplug.diagram import BandSampler, build_diagram, build_diagram_blocks
    from grainplug.readers import open_movie

    movie = synthesize(SynthConfig(n_frames=75, seed=5), tmp_path, fmt="tiff").movie
    with open_movie(movie) as m:
        tube = find_tube(m.sample(16)[1])
        sampler = BandSampler(tube)
        t = np.arange(75) / 250.0
        serial = build_diagram(m.analysis_frames(), sampler, n_frames=75, time_s=t, mm_per_px=0.2)
        seen: list[int] = []
        threaded = build_diagram_blocks(m.block_reader(), sampler, n_frames=75, time_s=t, mm_per_px=0.2,
                                        block_frames=8, threads=3, progress=seen.append)
    np.testing.assert_array_equal(threaded.values, serial.values)
    assert seen == sorted(seen) and seen[-1] == 75
    one, two = analyze(movie, threads=1), analyze(movie, threads=2)
    assert one.summary["celerity_m_s"] == two.summary["celerity_m_s"]
    np.testing.assert_array_equal(one.diagram.values, two.diagram.values)


@pytest.mark.parametrize("orientation", ["vertical", "horizontal"])
@pytest.mark.parametrize("flip", [(0,), (1,), (2,), (0, 1), (0, 1, 2)])
def test_band_sampler_reads_backward_layouts_in_place(rng, monkeypatch, orientation, flip):
    """Frames whose axes are stored backwards (bottom-up AVI rows, BGR) are sampled
    through a reversed view, not copied: same profile as from a C-ordered copy, and
    the offsets are computed once for the whole stream."""
    from grainplug.calibration.tube import TubeGeometry
    from grainplug.diagram import BandSampler

    stored = rng.integers(0, 256, (6, 48, 40, 3), dtype=np.uint8)
    views = [f[tuple(slice(None, None, -1) if a in flip else slice(None) for a in range(3))] for f in stored]
    tube = TubeGeometry(orientation=orientation, tilt_deg=4.0, axis_x0_px=18.3, inner_diameter_px=11.0,
                        contrast=0.5, method="test", canonical_shape=(48, 40) if orientation == "vertical"
                        else (40, 48), background_level=100.0)
    ref = BandSampler(tube)
    expected = [ref(np.ascontiguousarray(v)) for v in views]
    sampler = BandSampler(tube)
    prepared = []
    original = BandSampler._prepare
    monkeypatch.setattr(BandSampler, "_prepare", lambda self, f: (prepared.append(f.strides), original(self, f)))
    contiguous = np.ascontiguousarray

    def no_frame_copies(a, *args, **kwargs):
        if np.ndim(a) == 3:
            pytest.fail("a frame was copied")
        return contiguous(a, *args, **kwargs)

    monkeypatch.setattr(np, "ascontiguousarray", no_frame_copies)
    got = [sampler(v) for v in views]
    assert len(prepared) == 1
    for a, b in zip(got, expected, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-6)


def test_tiff_stacks_beyond_4_gb_are_written_as_bigtiff(tmp_path, rng):
    import tifffile

    from grainplug.readers import open_movie
    from grainplug.synthetic import MovieWriter

    frames = rng.integers(0, 256, (3, 64, 48, 3), dtype=np.uint8)
    for n_frames, big in ((3, False), (2_000_000, True)):  # 2e6 frames of 9 kB: 18 GB announced
        path = tmp_path / f"m{n_frames}.tif"
        with MovieWriter(path, "tiff", fps=250.0, n_frames=n_frames) as w:
            for f in frames:
                w.write(f)
        with tifffile.TiffFile(path) as tif:
            assert tif.is_bigtiff is big
        with open_movie(path) as m:
            np.testing.assert_array_equal(np.stack(list(m.frames())), frames)


@pytest.mark.parametrize(("fmt", "width", "rgb"), [("avi", 128, True), ("avi", 127, True), ("avi", 126, False),
                                                   ("mov", 128, True)])
def test_raw_video_read_straight_from_the_file(tmp_path, fmt, width, rgb):
    """Raw video: frames memory-mapped at the index's positions equal PyAV's decoding
    (odd widths with padded rows, grey, AVI and MOV), and the analysis gives the same
    diagram and times whichever way the frames come."""
    from grainplug.calibration import find_tube
    from grainplug.diagram import BandSampler, build_diagram, build_diagram_blocks
    from grainplug.readers import open_movie

    movie = synthesize(SynthConfig(n_frames=40, seed=6, width_px=width, rgb=rgb), tmp_path, fmt=fmt).movie
    with open_movie(movie) as m:
        decoded = list(m.analysis_frames())
        stamps = m.timestamps_s()
        converted = list(m.frames())
    with open_movie(movie) as m:  # the sample is copied from the file, in the layout of frames()
        idx, sample = m.sample(16)
        assert m._raw_frame is not None
        assert len(idx) == 16
        for k, frame in zip(idx, sample, strict=True):
            assert frame.flags.c_contiguous
            np.testing.assert_array_equal(frame, converted[k])
    with open_movie(movie) as m:
        read_block = m.block_reader()
        assert read_block is not None
        straight = read_block(0, 40)
        for a, b in zip(straight, decoded, strict=True):
            np.testing.assert_array_equal(a, b)
        np.testing.assert_allclose(m.timestamps_s(), stamps)
        tube = find_tube(m.sample(16)[1])
        t = np.arange(40) / 250.0
        one = build_diagram(iter(decoded), BandSampler(tube), n_frames=40, time_s=t, mm_per_px=0.2)
        two = build_diagram_blocks(read_block, BandSampler(tube), n_frames=40, time_s=t, mm_per_px=0.2,
                                   block_frames=7, threads=2)
    np.testing.assert_array_equal(one.values, two.values)


def test_compressed_video_is_decoded(tmp_path):
    from grainplug.readers import open_movie

    movie = synthesize(SynthConfig(n_frames=20, seed=6), tmp_path, fmt="ffv1").movie
    with open_movie(movie) as m:
        assert m.block_reader() is None


def _write_bottom_up_avi(path, frames, fps=250):
    """A minimal AVI written by hand (not by FFmpeg): 24-bit BGR DIB rows stored bottom-up,
    padded to 4 bytes, an idx1 index — the layout of many cameras' uncompressed AVIs."""
    import struct

    def chunk(fourcc, data):
        return fourcc + struct.pack("<I", len(data)) + data + (b"\0" if len(data) % 2 else b"")

    n, h, w, _ = frames.shape
    line = (w * 3 + 3) // 4 * 4
    size = line * h
    avih = struct.pack("<14I", int(1e6 / fps), size * fps, 0, 0x10, n, 0, 1, size, w, h, 0, 0, 0, 0)
    strh = struct.pack("<4s4sIHHIIIIIIIIhhhh", b"vids", b"DIB ", 0, 0, 0, 0, 1, fps, 0, n, size,
                       0xFFFFFFFF, 0, 0, 0, w, h)
    strf = struct.pack("<IiiHHIIiiII", 40, w, h, 1, 24, 0, size, 0, 0, 0, 0)  # height > 0: bottom-up
    strl = chunk(b"LIST", b"strl" + chunk(b"strh", strh) + chunk(b"strf", strf))
    hdrl = chunk(b"LIST", b"hdrl" + chunk(b"avih", avih) + strl)
    movi, idx, off = [], [], 4
    for f in frames:
        rows = np.zeros((h, line), np.uint8)
        rows[:, : w * 3] = f[::-1, :, ::-1].reshape(h, w * 3)
        c = chunk(b"00db", rows.tobytes())
        idx.append(struct.pack("<4sIII", b"00db", 0x10, off, size))
        movi.append(c)
        off += len(c)
    body = b"AVI " + hdrl + chunk(b"LIST", b"movi" + b"".join(movi)) + chunk(b"idx1", b"".join(idx))
    path.write_bytes(b"RIFF" + struct.pack("<I", len(body)) + body)


def test_bottom_up_avi_written_by_other_means(tmp_path, rng):
    """Rows stored bottom-up (negative line size in FFmpeg): decoded, native and memory-mapped
    frames all come out the right way up, and the analysis agrees with the same frames in TIFF."""
    from grainplug.readers import open_movie

    frames = rng.integers(0, 256, (12, 20, 30, 3), dtype=np.uint8)  # 30 px: rows padded to 92 bytes
    _write_bottom_up_avi(tmp_path / "bu.avi", frames)
    with open_movie(tmp_path / "bu.avi") as m:
        np.testing.assert_array_equal(np.stack(list(m.frames())), frames)
        native = np.stack(list(m.analysis_frames()))
        np.testing.assert_array_equal(native[..., ::-1], frames)  # BGR as stored, rows in order
        read_block = m.block_reader()
        assert read_block is not None
        np.testing.assert_array_equal(np.stack(read_block(0, 12)), native)
        np.testing.assert_array_equal(m.read(7), frames[7])
        idx, sample = m.sample(5)  # copied from the file: RGB, the right way up
        np.testing.assert_array_equal(np.stack(sample), frames[idx])
        from grainplug.readers.base import read_file

        offsets = m.frame_offsets()  # where each frame's stored bytes begin: its bottom row, BGR
        assert len(offsets) == 12
        for k in (0, 11):
            np.testing.assert_array_equal(read_file(tmp_path / "bu.avi", int(offsets[k]), (30, 3), np.uint8),
                                          frames[k, -1, :, ::-1])

    tif = synthesize(SynthConfig(n_frames=150, seed=8, celerity_m_s=-0.05), tmp_path / "t", fmt="tiff")
    with open_movie(tif.movie) as m:
        movie = np.stack(list(m.frames()))
    _write_bottom_up_avi(tmp_path / "movie.avi", movie)
    a, b = analyze(tif.movie), analyze(tmp_path / "movie.avi")
    assert b.flow_direction == a.flow_direction == "down"
    assert b.summary["celerity_m_s"] == pytest.approx(a.summary["celerity_m_s"], rel=1e-6)
    np.testing.assert_allclose(b.diagram.values, a.diagram.values, rtol=0, atol=1e-4)


def test_readahead_pauses_and_is_adopted_by_the_reader(tmp_path, monkeypatch):
    import os
    import time

    from grainplug import _system
    from grainplug._system import ReadAhead
    from grainplug.readers import open_movie

    movie = synthesize(SynthConfig(n_frames=32, seed=1), tmp_path, fmt="tiff").movie
    calls: list[int] = []

    def slow(off):  # a disk that takes 5 ms a chunk: the file cannot be done before the pause
        time.sleep(0.005)
        calls.append(off)

    monkeypatch.setattr(os, "posix_fadvise", lambda fd, off, n, adv: slow(off), raising=False)
    monkeypatch.setattr(_system, "read_to_cache", lambda fd, null, off, n: slow(off))
    monkeypatch.setattr(_system, "readahead_chunk_bytes", lambda path: 16 * 1024)
    assert movie.stat().st_size > 100 * 16 * 1024
    ra = ReadAhead(movie, 1e12)
    assert _wait(lambda: len(calls) >= 2)
    ra.pause()
    time.sleep(0.05)
    n_paused = len(calls)
    time.sleep(0.1)
    assert len(calls) == n_paused and ra.requested_to < ra.size  # nothing more asked while paused
    monkeypatch.setattr(_system, "read_to_cache", lambda fd, null, off, n: calls.append(off))  # a fast disk now
    monkeypatch.setattr(os, "posix_fadvise", lambda fd, off, n, adv: calls.append(off), raising=False)
    assert ReadAhead.for_path(str(movie)) is ra
    with open_movie(movie) as m:
        m.prefetch()
        assert m._readahead is ra  # the reader adopts the command line's read-ahead, and resumes it
        assert _wait(lambda: ra.requested_to == ra.size)
    assert ReadAhead.for_path(movie) is None  # closed with the movie


def test_read_file_and_sparse_maps_give_the_file_bytes(tmp_path, rng):
    from grainplug.errors import MovieError
    from grainplug.readers.base import map_file, read_file

    data = rng.integers(0, 2**16, 50_000, dtype=np.uint16)
    path = tmp_path / "x.raw"
    path.write_bytes(b"hdr" + data.tobytes())
    for random_access in (False, True):
        np.testing.assert_array_equal(read_file(path, 3 + 2 * 100, (10, 30), np.uint16, random_access=random_access),
                                      data[100:400].reshape(10, 30))
    for sparse in (False, True):  # offsets off the page grid, shapes of several axes
        got = map_file(path, 3 + 2 * 5000, (20, 1000), np.uint16, sparse=sparse)
        np.testing.assert_array_equal(got, data[5000:25000].reshape(20, 1000))
    with pytest.raises(MovieError, match="truncated"):
        read_file(path, 3 + 2 * 49_990, (20,), np.uint16)


@pytest.mark.parametrize("length", [2, 3, 4, 5, 6, 7, 8])
def test_row_closing_equals_binary_closing(rng, length):
    from grainplug.plugs.segment import close_rows

    for p in (0.2, 0.5, 0.8, 0.95):
        mask = rng.random((60, 97)) < p
        expected = ndimage.binary_closing(mask, structure=np.ones((1, length), bool), border_value=0)
        np.testing.assert_array_equal(close_rows(mask, length), expected)
    erosion = ndimage.minimum_filter1d(mask.view(np.uint8), 7, axis=1, mode="constant", cval=0).view(bool)
    np.testing.assert_array_equal(erosion, ndimage.binary_erosion(mask, structure=np.ones((1, 7), bool)))


def _link_frame_by_frame(runs, n_frames):
    """The former frame-by-frame linking: the reference for the vectorised one."""
    from grainplug.plugs.tracking import Tracks

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
    from grainplug.plugs.segment import Runs

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
    from grainplug.plugs.tracking import link

    cases = [_random_runs(rng, n) for n in (1, 2, 5, 40, 300)]
    # smooth motion: long tracks, the usual case
    from grainplug.plugs.segment import Runs

    k = np.repeat(np.arange(200), 3)
    a = (np.tile([10, 80, 150], 200) + np.repeat(np.arange(200) // 4, 3)) % 190
    order = np.lexsort((a, k))
    cases.append(Runs(k[order], a[order], a[order] + 20, np.zeros(600), np.zeros(600)))
    cases.append(Runs(*(np.zeros(0, int) for _ in range(3)), np.zeros(0), np.zeros(0)))
    seen = set()
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
    assert seen == {"start", "entered", "merge", "split", "end", "left"}  # every branch taken


def test_readahead_reads_whole_files_through_the_kernel_and_falls_back(tmp_path, monkeypatch):
    """A whole-file read-ahead reads with sendfile to /dev/null (pages cached in large folios,
    nothing copied out), chunk after chunk to the end; where that fails it asks with
    POSIX_FADV_WILLNEED instead, from where it stopped."""
    import os
    import sys

    from grainplug import _system

    if not (hasattr(os, "sendfile") and sys.platform.startswith("linux")):
        pytest.skip("sendfile to /dev/null is used on Linux only")
    path = tmp_path / "movie.raw"
    path.write_bytes(os.urandom(300_000))
    monkeypatch.setattr(_system, "readahead_chunk_bytes", lambda p: 64 * 1024)
    read: list[tuple[int, int]] = []
    real = _system.read_to_cache

    def spy(fd, null, off, n):
        real(fd, null, off, n)  # the real call, on a real file
        read.append((off, n))

    monkeypatch.setattr(_system, "read_to_cache", spy)
    ra = _system.ReadAhead(path, 1e12)
    assert _wait(lambda: ra.requested_to == ra.size)
    assert [off for off, _ in read] == list(range(0, 300_000, 64 * 1024))
    ra.close()

    asked: list[int] = []
    monkeypatch.setattr(os, "posix_fadvise", lambda fd, off, n, adv: asked.append(off), raising=False)

    def fails_once_started(fd, null, off, n):
        if off >= 128 * 1024:
            raise OSError("no sendfile here")

    monkeypatch.setattr(_system, "read_to_cache", fails_once_started)
    ra = _system.ReadAhead(path, 1e12)
    assert _wait(lambda: ra.requested_to == ra.size)
    assert asked == list(range(128 * 1024, 300_000, 64 * 1024))
    ra.close()


def test_analysis_modules_import_scipy_filters_only_when_used():
    """The figure helper imports grainplug.analysis to unpickle a result: that must not
    pay for scipy.ndimage (~0.2 s); the first filter imports it."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "import grainplug.analysis, grainplug.outputs, grainplug.plotting.helper\n"
        "print(sorted(m for m in ('scipy.ndimage', 'scipy.special', 'skimage.filters') if m in sys.modules))\n"
        "from grainplug._lazy import ndimage\n"
        "import numpy as np\n"
        "out = ndimage.gaussian_filter1d(np.arange(5.0), 1.0)\n"
        "real = sys.modules['scipy.ndimage']\n"
        "print('scipy.ndimage' in sys.modules, ndimage.gaussian_filter1d is real.gaussian_filter1d)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split("\n")
    assert out[0] == "[]"
    assert out[1] == "True True"


def _bubble_medians_by_loop(runs, tracks, min_frames):
    """Frame by frame, neighbour by neighbour (the former code)."""
    import itertools

    gaps = {}
    for k in np.unique(runs.frame):
        idx = runs.in_frame(int(k))
        for u, d in itertools.pairwise(idx):
            if np.isfinite(runs.bottom_mm[u]) and np.isfinite(runs.top_mm[d]):
                key = (int(tracks.run_track[u]), int(tracks.run_track[d]))
                gaps.setdefault(key, []).append(float(runs.top_mm[d] - runs.bottom_mm[u]))
    return np.asarray([np.median(v) for v in gaps.values() if len(v) >= min_frames])


def test_bubble_lengths_vectorised_equal_the_loop(result):
    from grainplug.measures.lengths import _bubble_medians

    runs, tracks = result.runs, result.tracks
    assert len(runs) > 100
    for min_frames in (1, 3, 10):
        got = _bubble_medians(runs, tracks, min_frames)
        ref = _bubble_medians_by_loop(runs, tracks, min_frames)
        assert got.size == ref.size > 0
        np.testing.assert_allclose(np.sort(got), np.sort(ref), rtol=0, atol=1e-12)
