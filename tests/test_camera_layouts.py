"""Camera layouts no public sample covers, on files the tests write (camera_writers.py).

Packed 10/12-bit and 8-bit cines, flips, save decimation and time stamps, RGB and raw
Bayer colour (demosaiced, checked on a known scene), Photron 8/12/16-bit with both
headers, NorPix 8/16-bit and colour, and damaged files: each gives the frames written,
or one clear line.
"""

from __future__ import annotations

import json
import tracemalloc

import numpy as np
import pytest
from camera_writers import mosaic, write_cine, write_mraw, write_seq
from test_reader_formats import check_contract
from warned import codes, of_code

import grainplug as gp
from grainplug.band import Band
from grainplug.cli import main
from grainplug.errors import MovieError
from grainplug.readers import open_movie
from grainplug.synthetic import SynthConfig
from grainplug.synthetic.render import Renderer

RNG = np.random.default_rng(11)


def random_frames(n: int, h: int, w: int, bits: int) -> np.ndarray:
    dtype = np.uint8 if bits == 8 else np.uint16
    return RNG.integers(0, 2**bits, (n, h, w)).astype(dtype)


# -- Phantom .cine --------------------------------------------------------------------------
@pytest.mark.parametrize(("layout", "bits", "real_bpp", "depth"), [
    ("8", 8, 8, 8), ("16", 16, 12, 12), ("16", 16, 16, 16), ("p10", 10, 10, 10), ("p12l", 12, 12, 12),
])
@pytest.mark.parametrize(("flip_v", "flip_h"), [(False, False), (True, False), (False, True), (True, True)])
def test_cine_layouts_and_flips_read_back_the_frames_written(tmp_path, layout, bits, real_bpp, depth, flip_v,
                                                             flip_h):
    frames = random_frames(7, 12, 24, bits)
    path = write_cine(tmp_path / "m.cine", frames, layout=layout, real_bpp=real_bpp, flip_v=flip_v, flip_h=flip_h)
    with open_movie(path) as movie:
        assert movie.info.bit_depth == depth and movie.info.dtype == frames.dtype.name
        assert movie.info.details["flip_vertical"] is flip_v and movie.info.details["flip_horizontal"] is flip_h
        np.testing.assert_array_equal(np.stack(list(movie.frames())), frames)


def small_band(rng: np.random.Generator, shape: tuple[int, int], rows: tuple[int, int],
               cols: tuple[int, int]) -> Band:
    """A band inside a window of the frame (its edges not on whole bytes of packed pixels)."""
    r = rng.integers(*rows, (20, 3))
    c = rng.integers(*cols, (20, 3))
    w = rng.uniform(0.1, 1.0, (20, 3)).astype(np.float32)
    return Band(r, c, w / w.sum(axis=1, keepdims=True), shape)


@pytest.mark.parametrize("layout", ["p10", "p12l"])
@pytest.mark.parametrize(("flip_v", "flip_h"), [(False, False), (True, True), (False, True), (True, False)])
def test_packed_frames_unpacked_in_the_band_window_give_the_band_profiles(tmp_path, layout, flip_v, flip_h):
    frames = random_frames(20, 16, 40, 10 if layout == "p10" else 12)
    path = write_cine(tmp_path / "m.cine", frames, layout=layout, flip_v=flip_v, flip_h=flip_h)
    rng = np.random.default_rng(2)
    with open_movie(path) as movie:
        for rows, cols in (((3, 11), (5, 14)), ((0, 16), (37, 40)), ((15, 16), (0, 40)), ((0, 1), (0, 1))):
            band = small_band(rng, (16, 40), rows, cols)
            want = np.stack([band.profile(f) for f in frames])
            np.testing.assert_allclose(movie.read_band(band, threads=2), want, rtol=1e-6, err_msg=f"{rows} {cols}")


def test_cine_passes_the_reader_contract(tmp_path):
    cfg = SynthConfig(n_frames=24, width_px=64, height_px=160, fps=250.0, rgb=False, bit_depth=16, seed=4)
    truth = np.stack(list(Renderer(cfg).frames())) >> 6  # 10-bit values
    path = write_cine(tmp_path / "m.cine", truth, fps=250.0, layout="p10", flip_v=True)
    with open_movie(path) as movie:
        check_contract(movie, truth, 250.0, True, np.random.default_rng(1))


@pytest.mark.parametrize(("decimation", "stamp_fps", "want_fps", "warned"), [
    (1.0, None, 2000.0, False),  # no time stamps: the header's rate
    (10.0, None, 200.0, False),  # record rate / save decimation
    (10.0, 200.0, 200.0, False),  # time stamps agree
    (1.0, 1500.0, 1500.0, True),  # time stamps disagree: they win, with a warning
])
def test_cine_saved_frame_rate(tmp_path, decimation, stamp_fps, want_fps, warned):
    frames = random_frames(30, 8, 8, 16)
    header_fps = 2000.0 / decimation
    stamps = None if stamp_fps is None else 1.6e9 + np.arange(30) / stamp_fps
    path = write_cine(tmp_path / "m.cine", frames, fps=header_fps, decimation=decimation, stamps_s=stamps)
    with open_movie(path) as movie:
        info = movie.info
    assert info.fps == pytest.approx(want_fps, rel=1e-5)  # the writer's float stamps resolve 0.2 us
    assert info.record_fps == (2000.0 if decimation > 1 else None)
    assert ("movie.fps_stamps" in codes(info)) is warned, info.warnings
    assert all(f"time stamps say {stamp_fps:.6g} fps" in w for w in of_code(info, "movie.fps_stamps"))


def test_old_cine_setup_block_without_the_new_fields(tmp_path):
    frames = random_frames(5, 8, 16, 16)
    path = write_cine(tmp_path / "m.cine", frames, fps=3000.0, setup_length=5692)
    with open_movie(path) as movie:
        assert movie.info.fps == 3000.0 and "levels" not in movie.info.details
        np.testing.assert_array_equal(movie.read(4), frames[4])


def smooth_scene(h: int, w: int, bits: int) -> np.ndarray:
    """A colour scene smooth enough for demosaicing to rebuild: three different gradients."""
    y, x = np.mgrid[0:h, 0:w] / max(h, w)
    top = 2**bits - 1
    rgb = np.stack([0.2 + 0.6 * x, 0.8 - 0.5 * y, 0.3 + 0.4 * np.sin(3 * x + 2 * y) ** 2], axis=-1)
    return np.round(rgb * top).astype(np.uint8 if bits == 8 else np.uint16)


@pytest.mark.parametrize(("cfa", "pattern"), [(3, "GBRG"), (4, "RGGB")])
@pytest.mark.parametrize("layout", ["8", "16"])
def test_raw_bayer_cine_is_demosaiced_to_the_scene(tmp_path, cfa, pattern, layout):
    bits = 8 if layout == "8" else 12
    scene = smooth_scene(40, 64, bits)
    raw = mosaic(scene, pattern)
    path = write_cine(tmp_path / "m.cine", np.stack([raw, raw]), layout=layout, bayer_cfa=cfa, real_bpp=bits)
    with open_movie(path) as movie:
        assert movie.info.channels == 3 and movie.info.colour == f"bayer {pattern}, demosaiced"
        rgb = movie.read(1)
    assert rgb.shape == scene.shape and rgb.dtype == scene.dtype
    inner = (slice(2, -2), slice(2, -2))
    err = np.abs(rgb[inner].astype(float) - scene[inner]).mean(axis=(0, 1)) / 2**bits
    swapped = np.abs(rgb[inner][..., ::-1].astype(float) - scene[inner]).mean(axis=(0, 1)) / 2**bits
    assert np.all(err < 0.01), err  # each channel within 1 % of the range
    assert swapped[0] > 10 * err[0] and swapped[2] > 10 * err[2]  # red and blue are where they belong


def test_raw_bayer_cine_with_a_sensor_dependent_pattern_is_refused(tmp_path):
    path = write_cine(tmp_path / "m.cine", random_frames(2, 8, 8, 16), bayer_cfa=1)
    with pytest.raises(MovieError, match=r"raw colour \(Bayer\) data .* export the movie as colour"):
        open_movie(path)


@pytest.mark.parametrize("layout", ["rgb24", "rgb48"])
def test_rgb_cine_reads_back_red_green_blue(tmp_path, layout):
    bits = 8 if layout == "rgb24" else 16
    scene = smooth_scene(10, 14, bits)
    path = write_cine(tmp_path / "m.cine", np.stack([scene] * 3), layout=layout, real_bpp=bits)
    with open_movie(path) as movie:
        assert movie.info.channels == 3 and movie.info.colour == "rgb"
        np.testing.assert_array_equal(movie.read(2), scene)


def test_analysis_of_a_packed_flipped_decimated_cine_equals_that_of_its_frames(tmp_path):
    cfg = SynthConfig(n_frames=120, width_px=48, height_px=300, fps=500.0, rgb=False, bit_depth=16, seed=3)
    frames = np.stack(list(Renderer(cfg).frames())) >> 6
    path = write_cine(tmp_path / "m.cine", frames, fps=500.0, layout="p10", flip_v=True, decimation=4.0,
                      stamps_s=1.6e9 + np.arange(len(frames)) / 500.0)
    from_file = gp.analyze(path)
    from_array = gp.analyze(frames, fps=500.0)
    assert from_file.info.fps == 500.0 and from_file.has_plugs
    assert from_file.summary["celerity_m_s"] == pytest.approx(from_array.summary["celerity_m_s"], rel=1e-9)
    assert from_file.summary["plug_length_mm"] == pytest.approx(from_array.summary["plug_length_mm"], rel=1e-9)


# -- Photron .mraw ----------------------------------------------------------------------------
@pytest.mark.parametrize("bits", [8, 12, 16])
@pytest.mark.parametrize("cihx", [False, True])
def test_mraw_depths_and_headers(tmp_path, bits, cihx):
    frames = random_frames(9, 10, 16, bits)
    header = write_mraw(tmp_path / "m", frames, bits=bits, fps=500.0, step=10, cihx=cihx)
    for given in (header, header.with_suffix(".mraw")):
        with open_movie(given) as movie:
            info = movie.info
            assert (info.n_frames, info.bit_depth, info.fps, info.record_fps) == (9, bits, 500.0, 5000.0)
            assert info.fps_note == "record rate 5000 fps / save step 10"
            np.testing.assert_array_equal(np.stack(list(movie.frames())), frames)


def test_mraw_passes_the_reader_contract(tmp_path):
    cfg = SynthConfig(n_frames=24, width_px=64, height_px=160, fps=250.0, rgb=False, bit_depth=16, seed=4)
    truth = np.stack(list(Renderer(cfg).frames())) >> 4  # 12-bit values
    header = write_mraw(tmp_path / "m", truth, bits=12, fps=250.0, cihx=True)
    with open_movie(header) as movie:
        check_contract(movie, truth, 250.0, True, np.random.default_rng(1))


def test_12bit_mraw_streams_in_constant_memory(tmp_path):
    """The memory a 12-bit .mraw takes while streamed does not grow with its length."""
    def peak_bytes(n_frames: int) -> int:
        frames = random_frames(n_frames, 128, 256, 12)
        header = write_mraw(tmp_path / f"m{n_frames}", frames, bits=12)
        band = Band(np.arange(128)[:, None].repeat(4, 1), np.tile(np.arange(100, 104), (128, 1)),
                    np.full((128, 4), 0.25, np.float32), (128, 256))
        with open_movie(header) as movie:
            tracemalloc.start()
            profiles = movie.read_band(band, threads=2)
            peak = tracemalloc.get_traced_memory()[1] - profiles.nbytes
            tracemalloc.stop()
        np.testing.assert_allclose(profiles[7], band.profile(frames[7]), rtol=1e-6)
        return peak

    short, long = peak_bytes(64), peak_bytes(640)  # 4 MB and 42 MB once unpacked
    assert long < 1.2 * short + 2**20, (short, long)


@pytest.mark.parametrize(("colour", "model"), [("Color", "FASTCAM x type 100K-C-8GB"),
                                               ("Raw", "FASTCAM x type 100K-C-8GB")])
def test_colour_photron_files_are_refused(tmp_path, colour, model):
    header = write_mraw(tmp_path / "m", random_frames(2, 4, 4, 8), bits=8, colour=colour, model=model)
    with pytest.raises(MovieError, match=r"colour Photron files .* are not supported — save the movie as monochrome"):
        open_movie(header)


def test_raw_data_of_a_monochrome_photron_sensor_is_grey(tmp_path):
    frames = random_frames(3, 4, 6, 12)
    header = write_mraw(tmp_path / "m", frames, bits=12, colour="Raw", cihx=True)
    with open_movie(header) as movie:
        assert movie.info.colour == "grey"
        np.testing.assert_array_equal(movie.read(2), frames[2])


# -- NorPix .seq --------------------------------------------------------------------------------
@pytest.mark.parametrize(("bits", "image_format", "rgb"), [(8, 100, False), (16, 100, False), (8, 200, True),
                                                           (8, 400, True)])
def test_seq_layouts_read_back_the_frames_written(tmp_path, bits, image_format, rgb):
    frames = random_frames(6, 10, 12, bits)
    if rgb:
        frames = np.stack([frames, frames // 2, 255 - frames], axis=-1)
    stamps = 1.7e9 + np.arange(6) / 250.0
    path = write_seq(tmp_path / "m.seq", frames, stamps_s=stamps, suggested_fps=250.0, image_format=image_format)
    with open_movie(path) as movie:
        info = movie.info
        assert info.channels == (3 if rgb else 1) and info.bit_depth == bits
        assert info.fps == pytest.approx(250.0, rel=1e-4) and not info.warnings
        np.testing.assert_array_equal(np.stack(list(movie.frames())), frames)


def test_seq_passes_the_reader_contract(tmp_path):
    cfg = SynthConfig(n_frames=24, width_px=64, height_px=160, fps=250.0, rgb=False, bit_depth=8, seed=4)
    truth = np.stack(list(Renderer(cfg).frames()))
    path = write_seq(tmp_path / "m.seq", truth, stamps_s=1.7e9 + np.arange(24) / 250.0, suggested_fps=250.0)
    with open_movie(path) as movie:
        check_contract(movie, truth, 250.0, True, np.random.default_rng(1))


def test_seq_with_dropped_frames_says_so(tmp_path):
    stamps = 1.7e9 + np.array([0, 1, 2, 3, 5, 6, 7, 8]) / 100.0
    path = write_seq(tmp_path / "m.seq", random_frames(8, 4, 4, 8), stamps_s=stamps, suggested_fps=100.0)
    with open_movie(path) as movie:
        assert movie.info.fps == pytest.approx(100.0, rel=1e-3)
        [said] = of_code(movie.info, "movie.frames_out_of_step")
        assert said.startswith("frame 4's time stamp is"), movie.info.warnings


# -- damaged files ------------------------------------------------------------------------------
def cut(path, keep_bytes):
    data = path.read_bytes()
    path.write_bytes(data[:keep_bytes])
    return path


def test_truncated_cine_is_refused_or_read_in_part(tmp_path, capsys):
    frames = random_frames(10, 16, 16, 16)
    path = write_cine(tmp_path / "m.cine", frames)
    cut(path, path.stat().st_size - 300)  # the last frame loses its end
    with pytest.raises(MovieError, match=r"is truncated: it holds 9 of the 10 frames .* allow_truncated=True"):
        open_movie(path)
    with open_movie(path, allow_truncated=True) as movie:
        assert movie.info.n_frames == 9 and of_code(movie.info, "movie.truncated") == [movie.info.warnings[0]]
        assert "the first 9 of the 10 frames" in movie.info.warnings[0]
        np.testing.assert_array_equal(movie.read(8), frames[8])
    assert main(["info", str(path)]) != 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and "--allow-truncated" in err
    assert main(["info", "--allow-truncated", str(path)]) == 0
    out, err = capsys.readouterr()
    assert "frames     9" in out and "warning: the file is truncated" in err


@pytest.mark.parametrize("keep", [10, 60, 500])
def test_cine_cut_inside_its_headers_is_one_clear_error(tmp_path, keep):
    path = cut(write_cine(tmp_path / "m.cine", random_frames(3, 8, 8, 16)), keep)
    with pytest.raises(MovieError, match=r"truncated|not a Phantom"):
        open_movie(path)


def test_truncated_mraw_and_seq(tmp_path):
    header = write_mraw(tmp_path / "m", random_frames(5, 8, 8, 12), bits=12)
    cut(header.with_suffix(".mraw"), 8 * 8 * 3 // 2 * 3 + 7)
    with pytest.raises(MovieError, match="holds 3 of the 5 frames"):
        open_movie(header)
    with open_movie(header, allow_truncated=True) as movie:
        assert movie.info.n_frames == 3
    path = write_seq(tmp_path / "m.seq", random_frames(4, 8, 8, 8), stamps_s=1.7e9 + np.arange(4) / 50)
    cut(path, path.stat().st_size - 600)
    with pytest.raises(MovieError, match="truncated"):
        open_movie(path)
    with open_movie(path, allow_truncated=True) as movie:
        assert movie.info.n_frames == 3


def test_zero_length_and_wrong_extension(tmp_path):
    (tmp_path / "empty.cine").write_bytes(b"")
    with pytest.raises(MovieError, match=r"is empty \(0 bytes\)"):
        open_movie(tmp_path / "empty.cine")
    path = write_cine(tmp_path / "m.cine", random_frames(3, 8, 8, 16))
    path.rename(tmp_path / "m.avi")
    with pytest.raises(MovieError, match=r"is a Phantom \.cine file despite its '\.avi' extension — rename it"):
        open_movie(tmp_path / "m.avi")
    (tmp_path / "not.cine").write_bytes(b"\x00" * 400)
    with pytest.raises(MovieError, match=r"is not a Phantom \.cine file"):
        open_movie(tmp_path / "not.cine")
    (tmp_path / "not.seq").write_bytes(b"\x01" * 2000)
    with pytest.raises(MovieError, match=r"is not a NorPix \.seq file"):
        open_movie(tmp_path / "not.seq")


def test_photron_header_of_another_recording(tmp_path):
    write_mraw(tmp_path / "a", random_frames(4, 8, 8, 16), bits=16)
    header = write_mraw(tmp_path / "b", random_frames(2, 8, 8, 16), bits=16)
    (tmp_path / "a.mraw").replace(tmp_path / "b.mraw")  # b's header, a's (larger) data
    with open_movie(header) as movie:
        [said] = of_code(movie.info, "movie.extra_bytes")
        assert said.startswith("b.mraw holds ") and "b.cih" in said, movie.info.warnings
    header = write_mraw(tmp_path / "c", random_frames(4, 8, 8, 16), bits=16)
    write_mraw(tmp_path / "d", random_frames(2, 8, 8, 16), bits=16)
    (tmp_path / "d.mraw").replace(tmp_path / "c.mraw")  # c's header, d's (smaller) data
    with pytest.raises(MovieError, match="truncated: it holds 2 of the 4 frames"):
        open_movie(header)


def test_a_movie_warning_reaches_the_command_line_the_summary_and_the_report(tmp_path, capsys):
    cfg = SynthConfig(n_frames=120, width_px=48, height_px=300, fps=500.0, rgb=False, bit_depth=16, seed=3)
    frames = np.stack(list(Renderer(cfg).frames())) >> 4
    path = write_cine(tmp_path / "m.cine", frames, fps=500.0, real_bpp=12)
    cut(path, path.stat().st_size - 1000)
    assert main(["analyze", str(path), "--out", str(tmp_path / "out")]) != 0
    assert "--allow-truncated" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
    assert main(["analyze", str(path), "--out", str(tmp_path / "out"), "--allow-truncated"]) == 0
    err = capsys.readouterr().err
    assert "warning: the file is truncated: reading the first 119 of the 120 frames" in err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    [said] = of_code(summary, "movie.truncated")
    assert summary["n_frames"] == 119 and "the first 119 of the 120 frames" in said
    assert "the file is truncated: reading the first 119" in (tmp_path / "out" / "report.html").read_text()
