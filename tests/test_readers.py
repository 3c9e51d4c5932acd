"""Every reader round-trips what `synth` wrote; natural order; rates and counts."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import grey

from grainplug.errors import MovieError
from grainplug.readers import natural_key, open_movie
from grainplug.synthetic import FORMATS, SynthConfig, synthesize
from grainplug.synthetic.render import Renderer

N = 10
LOSSLESS = [f for f, spec in FORMATS.items() if spec.lossless]
#: mean absolute grey error allowed for lossy formats (8-bit levels) at noise sigma 3
LOSSY_MEAN_ERR = {"jpeg": 2.0, "mjpeg": 2.5, "h264": 4.0}
GREY_ONLY = {"mraw", "cine"}
DEPTHS = {  # bit depths each format stores
    "tiff": (8, 16), "png": (8, 16), "tiff-folder": (8, 16), "ffv1": (8, 16), "mraw": (8, 16),
    "cine": (16,),
}


def _cases() -> list[tuple[str, bool, int]]:
    cases = []
    for fmt in FORMATS:
        for rgb in (False, True):
            if rgb and fmt in GREY_ONLY:
                continue
            for depth in DEPTHS.get(fmt, (8,)):
                if fmt == "png" and rgb and depth == 16:
                    continue
                cases.append((fmt, rgb, depth))
    return cases


@pytest.mark.parametrize(("fmt", "rgb", "depth"), _cases())
def test_round_trip(tmp_path, fmt, rgb, depth):
    cfg = SynthConfig(n_frames=N, rgb=rgb, bit_depth=depth, seed=3, noise_sigma=3.0)
    result = synthesize(cfg, tmp_path, fmt=fmt)
    expected = list(Renderer(cfg).frames())
    with open_movie(result.movie) as movie:
        info = movie.info
        frames = list(movie.frames())
    assert info.n_frames == N == len(frames)
    assert (info.height, info.width) == (cfg.height_px, cfg.width_px)
    assert info.bit_depth == depth
    if FORMATS[fmt].suffix:  # files hold their frame rate; image folders do not
        assert info.fps == pytest.approx(250.0)
    else:
        assert info.fps is None
    if FORMATS[fmt].lossless:
        yuv_or_rgb_only = fmt in ("mov",) and not rgb
        for got, exp in zip(frames, expected, strict=True):
            assert got.dtype == exp.dtype
            if yuv_or_rgb_only:
                np.testing.assert_array_equal(got[..., 0], exp)
            else:
                np.testing.assert_array_equal(got, exp)
    else:
        err = np.mean([np.abs(grey(g) - grey(e)).mean() for g, e in zip(frames, expected, strict=True)])
        assert err < LOSSY_MEAN_ERR[fmt], f"{fmt}: mean error {err:.2f} grey levels"


def test_frame_ranges_and_random_access(tmp_path):
    cfg = SynthConfig(n_frames=12, seed=1)
    result = synthesize(cfg, tmp_path, fmt="ffv1")
    with open_movie(result.movie) as movie:
        every = list(movie.frames())
        sub = list(movie.frames(2, 11, 3))
        assert len(sub) == 3
        for k, f in zip((2, 5, 8), sub, strict=True):
            np.testing.assert_array_equal(f, every[k])
        np.testing.assert_array_equal(movie.read(7), every[7])
        ts = movie.timestamps_s()
        assert movie.has_file_timestamps
        np.testing.assert_allclose(ts, np.arange(12) / 250.0, atol=1e-6)


def test_tiff_reads_only_what_it_needs(tmp_path):
    cfg = SynthConfig(n_frames=5, seed=2)
    result = synthesize(cfg, tmp_path, fmt="tiff")
    with open_movie(result.movie) as movie:
        full = movie.read(3)
        part = movie.region(3, slice(10, 50), slice(20, 40))
        np.testing.assert_array_equal(part, full[10:50, 20:40])


def test_natural_sort_order(tmp_path):
    names = ["img_10.png", "img_2.png", "img_1.png", "img_100.png", "img_20.png"]
    assert sorted(names, key=natural_key) == [
        "img_1.png", "img_2.png", "img_10.png", "img_20.png", "img_100.png"]
    # a folder written by synth is numbered without padding; frame order must hold
    cfg = SynthConfig(n_frames=12, seed=4, rgb=False, noise_sigma=0)
    result = synthesize(cfg, tmp_path / "s", fmt="png")
    expected = list(Renderer(cfg).frames())
    with open_movie(result.movie, fps=500) as movie:
        assert movie.info.fps == 500 and movie.info.fps_source == "user"
        assert movie.info.duration_s == pytest.approx(12 / 500)
        for got, exp in zip(movie.frames(), expected, strict=True):
            np.testing.assert_array_equal(got, exp)


def test_glob_selects_images(tmp_path):
    cfg = SynthConfig(n_frames=4, seed=5, rgb=False)
    result = synthesize(cfg, tmp_path, fmt="png")
    for p in list(result.movie.iterdir())[:2]:
        p.rename(p.with_name("other_" + p.name))
    with open_movie(result.movie, glob="frame_*.png") as movie:
        assert movie.info.n_frames == 2
    with open_movie(result.movie) as movie:
        assert movie.info.n_frames == 4


def test_fps_override(tmp_path):
    result = synthesize(SynthConfig(n_frames=4, fps=500.0), tmp_path, fmt="avi")
    with open_movie(result.movie) as movie:
        assert movie.info.fps == pytest.approx(500.0)
        assert movie.info.fps_source == "file"
    with open_movie(result.movie, fps=1000) as movie:
        assert movie.info.fps == 1000 and movie.info.fps_source == "user"


@pytest.mark.parametrize("fmt", ["tiff", "avi", "ffv1", "mjpeg", "h264"])
def test_sample_frames_are_the_movie_frames(tmp_path, fmt):
    """Whatever way a reader samples (a read per frame, raw frames from the file, seeking,
    key frames found when the packets were counted), the sample holds the frames that
    :meth:`frames` gives at those indices, spread over the movie."""
    movie = synthesize(SynthConfig(n_frames=60, seed=2), tmp_path, fmt=fmt).movie
    with open_movie(movie) as m:
        every = list(m.frames())
    with open_movie(movie) as m:
        idx, sample = m.sample(12)
    assert len(idx) == len(sample) >= 8
    assert idx[-1] - idx[0] >= (30 if fmt != "h264" else 8)
    for k, frame in zip(idx, sample, strict=True):
        np.testing.assert_array_equal(frame, every[k])


def test_a_file_named_tif_that_is_not_one_is_named_so(tmp_path):
    fake = tmp_path / "run.tif"
    fake.write_text("hello, these are my notes")
    with pytest.raises(MovieError, match="is not a TIFF file"):
        open_movie(fake)
