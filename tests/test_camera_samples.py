"""Real camera files (../shared/camera-samples, read by path, never copied).

Each sample must read as its README says (frames, size, saved-frame rate, true bit
depth, colour, flips) and pixel for pixel as an independent reference reader reads it:
pims for .cine and .seq, pyMRAW for .mraw. pims does not apply the camera's vertical
flip flag; grainplug does (as the maker's viewer and FFmpeg's demuxer do), so for a
file with ``bFlipV`` set the two agree after flipping pims' rows.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from warned import of_code

from grainplug.band import Band
from grainplug.cli import main
from grainplug.errors import MovieError
from grainplug.readers import open_movie

SAMPLES = Path(__file__).resolve().parent.parent.parent / "shared" / "camera-samples"

pytestmark = [
    pytest.mark.skipif(not SAMPLES.is_dir(), reason=f"the real camera samples are not at {SAMPLES}"),
]

#: the README's facts: file -> (width, height, frames, saved fps, bit depth, dtype, vertical flip applied)
FACTS = {
    "pims/cine_781.cine": (256, 256, 15, 9000.0, 12, "uint16", True),
    "pims/cine_legacy.cine": (128, 128, 97, 35087.0, 14, "uint16", False),
    "pyidi/data_small_cine.cine": (256, 32, 235, 100.0, 10, "uint16", False),
    "pyMRAW/ball_12bit.cihx": (384, 384, 15, 30000.0, 12, "uint16", False),
    "pyMRAW/beam.cihx": (1024, 80, 4, 20.0, 12, "uint16", False),
    "pyidi/data_showcase.cih": (640, 40, 75, 150.0, 8, "uint8", False),
    "pims/sample_norpix6.seq": (36, 32, 6, None, 8, "uint8", False),
}


def reference_frames(name: str) -> np.ndarray:
    """The frames as the independent reference reader decodes them."""
    path = SAMPLES / name
    if path.suffix in (".cih", ".cihx"):
        pymraw = pytest.importorskip("pyMRAW")
        with warnings.catch_warnings():  # pyMRAW warns about any depth but 12 bits
            warnings.simplefilter("ignore")
            images, _ = pymraw.load_video(str(path))
        return np.asarray(images)
    pims = pytest.importorskip("pims")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        reader = pims.Cine(str(path)) if path.suffix == ".cine" else pims.NorpixSeq(str(path))
        frames = np.stack([np.asarray(reader[k]) for k in range(len(reader))])
        reader.close()
    return frames


@pytest.mark.parametrize("name", sorted(FACTS))
def test_sample_reads_as_its_readme_says(name):
    width, height, n, fps, depth, dtype, flipped = FACTS[name]
    with open_movie(SAMPLES / name) as movie:
        info = movie.info
        frames = np.stack(list(movie.frames()))
        assert (info.width, info.height, info.n_frames, info.channels) == (width, height, n, 1)
        assert info.bit_depth == depth and info.dtype == dtype and info.colour == "grey"
        if fps is not None:
            assert info.fps == pytest.approx(fps, rel=1e-9) and info.fps_source == "file"
        assert frames.shape == (n, height, width) and frames.dtype == dtype
        assert frames.max() < 2**depth  # values as stored, not rescaled to the container
        ref = reference_frames(name)
        np.testing.assert_array_equal(frames, ref[:, ::-1] if flipped else ref)
        # random access and band streaming give the same values as reading in order
        for k in (n - 1, 0, n // 2):
            np.testing.assert_array_equal(movie.read(k), frames[k])
        rng = np.random.default_rng(5)
        rows = rng.integers(0, height, (40, 3))
        cols = rng.integers(0, width, (40, 3))
        band = Band(rows, cols, np.full((40, 3), 1 / 3, np.float32), (height, width))
        want = np.stack([band.profile(f) for f in frames])
        np.testing.assert_allclose(movie.read_band(band, threads=2), want, rtol=1e-6)


def test_cine_saved_rate_comes_from_the_save_decimation_and_the_time_stamps_agree():
    with open_movie(SAMPLES / "pims/cine_781.cine") as movie:
        info = movie.info
    assert info.record_fps == 90000.0 and info.fps == 9000.0
    assert info.fps_note.startswith("record rate 90000 fps / save decimation 10; time stamps agree")
    assert info.details["flip_vertical"] is True and abs(info.details["timestamp_fps"] / 9000 - 1) < 1e-3
    assert info.details["levels"] == {"BlackLevel": 64, "WhiteLevel": 4064}
    assert info.details["first_image_number"] == -5417 and info.details["trigger_time_utc"].startswith("2019-")
    assert not info.warnings


def test_legacy_cine_pixels_are_not_zero_and_its_garbage_levels_are_not_read():
    with open_movie(SAMPLES / "pims/cine_legacy.cine") as movie:
        frame = movie.read(50)
        assert frame.max() > 1000 and "levels" not in movie.info.details  # beyond its short SETUP block


def test_packed_cine_last_frame_is_kept_as_stored_with_a_warning_on_its_time_stamp():
    with open_movie(SAMPLES / "pyidi/data_small_cine.cine") as movie:
        last = movie.read(234)
        info = movie.info
    assert np.all(last == 1012)
    assert info.details["frames_with_bad_timestamp"] == [234]
    [said] = of_code(info, "movie.frames_out_of_step")
    assert said.startswith("frame 234's time stamp is"), info.warnings


def test_seq_rate_is_the_time_stamps_with_a_warning_on_the_header():
    with open_movie(SAMPLES / "pims/sample_norpix6.seq") as movie:
        info = movie.info
    assert 29.0 < info.fps < 31.0 and info.fps_note.startswith("time stamps")
    assert info.details["suggested_fps"] == 10.0
    [said] = of_code(info, "movie.fps_stamps")
    assert f"say {info.fps:.4g} fps" in said and "header suggests 10 fps" in said, info.warnings
    # given a rate, the file's stamps-or-header choice is not made: one warning (given against recorded), not
    # a second one saying the stamps are used
    with open_movie(SAMPLES / "pims/sample_norpix6.seq", fps=10) as movie:
        info = movie.info
    said = of_code(info, "movie.fps_disagrees", "movie.fps_stamps")
    assert info.fps == 10 and said == of_code(info, "movie.fps_disagrees"), info.warnings
    assert len(said) == 1 and said[0].startswith("the frame rate given (10 fps)"), said


@pytest.mark.parametrize(("name", "fps", "note"), [
    ("pyMRAW/beam.cihx", 20.0, "record rate 50000 fps / save step 2500"),
    ("pyidi/data_showcase.cih", 150.0, "record rate 15000 fps / save step 100"),
    ("pyMRAW/ball_12bit.cihx", 30000.0, "record rate 30000 fps"),
])
def test_photron_saved_frame_rate(name, fps, note):
    with open_movie(SAMPLES / name) as movie:
        assert movie.info.fps == pytest.approx(fps) and movie.info.fps_note == note
        assert movie.timestamps_s()[1] == pytest.approx(1 / fps)


def test_frame_rate_given_by_the_user_wins():
    with open_movie(SAMPLES / "pyMRAW" / "beam.cihx", fps=1000.0) as movie:
        assert movie.info.fps == 1000.0 and movie.info.fps_source == "user" and not movie.info.fps_note


def test_photron_header_without_its_data_is_one_clear_error():
    with pytest.raises(MovieError, match=r"sample_60k_16bit\.mraw is not beside it — copy"):
        open_movie(SAMPLES / "pyMRAW" / "sample_60k_16bit.cih")  # the sample is a header only


def test_info_tells_the_truth_on_the_command_line(capsys):
    assert main(["info", str(SAMPLES / "pims/cine_781.cine")]) == 0
    out = capsys.readouterr().out
    assert "9000 fps (file: record rate 90000 fps / save decimation 10" in out
    assert "recorded   90000 fps" in out and "bit depth  12 (uint16)" in out
    assert "flipped    vertical" in out
    assert main(["info", str(SAMPLES / "pyidi/data_small_cine.cine")]) == 0
    out, err = capsys.readouterr()
    assert "bit depth  10 (uint16)" in out and "warning: frame 234's time stamp is out of step" in err
    assert main(["info", "--json", str(SAMPLES / "pims/sample_norpix6.seq")]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["colour"] == "grey" and any("header suggests 10 fps" in w for w in d["warnings"])
    # its stamps give the rate; the frames are timed index / fps (the key said "timestamps_in_file": false)
    assert d["fps_note"].startswith("time stamps") and d["frame_times"] == "frame index / fps"


def test_a_strip_with_no_tube_is_refused_in_one_line(tmp_path, capsys):
    """The small cine sample is a 32 px strip of texture: it got a 3 px "tube", "regime static" and a 16 mm plug.
    A tube needs a bore of 6 px or walls beside it: refused in one line, nothing written."""
    out = tmp_path / "strip"
    assert main(["analyze", str(SAMPLES / "pyidi/data_small_cine.cine"), "--out", str(out)]) != 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no tube found (bore 3.0 px wide" in err and "Traceback" not in err
    assert not out.exists()


def test_a_droplet_is_not_reported_as_holding_plugs():
    """cine_781 films a droplet (no tube): it was given a tilted "tube" and has_plugs true. In back light no wall is
    seen beside what moves, and no plug is followed: no plugs, the statement says there is no tube, a warning why."""
    import grainplug as gp

    res = gp.analyze(SAMPLES / "pims/cine_781.cine")
    s = res.summary
    assert s["has_plugs"] is False and s["celerity_m_s"] is None and s["regime"] == "none"
    assert res.statement.startswith("no tube") and "tube.walls_unseen" in s["warning_codes"]


@pytest.mark.parametrize("given_scale", [None, 0.1])
def test_a_beam_with_no_wall_and_no_plug_whole_is_not_a_static_train(given_scale):
    """pyidi's data_showcase films a vibrating beam, 7 px wide, no tube: without a scale it came out a confident
    "static" train (has_plugs true with no plug seen whole: the tracks were the view's two ends), with a scale
    "no plugs". Both now say there is no tube, and measure nothing."""
    import grainplug as gp

    res = gp.analyze(SAMPLES / "pyidi/data_showcase.mraw", mm_per_px=given_scale)
    s = res.summary
    assert s["has_plugs"] is False and s["celerity_m_s"] is None and s["regime"] in ("none", None), s["regime"]
    assert s["plug_length_mm"] is None and s["bubble_length_mm"] is None


def test_a_short_bands_overlay_keeps_its_time_stamp_clear_of_the_scale_bar(tmp_path):
    """In a band 40 px high (a horizontal tube filmed in a short frame) the time stamp's box covered the scale bar's
    "10 mm": it moves to the top right."""
    import grainplug as gp
    from grainplug.overlay import draw_frame
    from grainplug.synthetic import SynthConfig
    from grainplug.synthetic.render import Renderer

    cfg = SynthConfig(n_frames=60, width_px=40, height_px=400, flow_direction="right", seed=2)
    frames = np.stack(list(Renderer(cfg).frames()))
    res = gp.analyze(frames, fps=cfg.fps, mm_per_px=cfg.mm_per_px)
    img = draw_frame(res, frames[5], 5, top_value=255.0)
    rows, cols = img.shape[:2]
    assert rows < 44 and cols > 200
    dark = img.max(axis=2) < 30
    assert dark[0:16, cols - 110:].mean() > 0.6  # the time stamp, top right
    assert dark[rows - 24:, 0:45].mean() > 0.5  # the scale bar, bottom left, not written over
