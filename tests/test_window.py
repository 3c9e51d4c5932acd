"""A time window (--start/--end): the same numbers as the movie cut to those frames, on every reader path."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import tifffile
from warned import codes, of_code

import grainplug as gp
from grainplug.calibration.tube import find_tube
from grainplug.cli import main
from grainplug.diagram.extract import band_along_tube
from grainplug.readers.window import FrameWindow
from grainplug.synthetic import SynthConfig, synthesize

START, STOP = 100, 250


@pytest.fixture(scope="module")
def movies(tmp_path_factory):
    d = tmp_path_factory.mktemp("window")
    cfg = SynthConfig(n_frames=300, seed=3, noise_sigma=2, celerity_m_s=-0.05)
    return {fmt: synthesize(cfg, d / fmt, fmt=fmt).movie for fmt in ("tiff", "avi")}


@pytest.mark.parametrize("fmt", ["tiff", "avi"])
def test_a_window_reads_what_the_movie_holds_there(movies, fmt):
    """The reader contract through the window: frames, samples, band profiles and times are the
    movie's own, shifted (the TIFF takes the memory-mapped block path, the AVI the decoded one)."""
    with gp.open_movie(movies[fmt]) as movie:
        frames = list(movie.frames())
        tube = find_tube([frames[k] for k in range(0, 300, 10)])
        band, _ = band_along_tube(tube)
        whole = movie.read_band(band)
    with gp.open_movie(movies[fmt]) as movie:
        win = FrameWindow(movie, START, STOP)
        assert win.info.n_frames == STOP - START and win.first_frame_index == START
        assert win.info.details["window_frames"] == [START, STOP]
        np.testing.assert_array_equal(win.read(0), frames[START])
        np.testing.assert_array_equal(win.read(STOP - START - 1), frames[STOP - 1])
        idx, sample = win.sample(5)
        for i, f in zip(idx, sample, strict=True):
            np.testing.assert_array_equal(f, frames[START + int(i)])
        np.testing.assert_array_equal(win.read_band(band), whole[START:STOP])
    with pytest.raises(ValueError, match="not within"):
        FrameWindow(movie, 250, 400)


def test_a_window_gives_the_numbers_of_the_cut_movie(movies):
    frames = tifffile.imread(movies["tiff"])
    full = gp.analyze(movies["tiff"])
    fps = full.info.fps
    cut = gp.analyze(frames[START:STOP], fps=fps)
    for win in (gp.analyze(movies["tiff"], start_frame=START, end_frame=STOP),
                gp.analyze(movies["tiff"], start_s=START / fps, end_s=STOP / fps)):
        assert win.info.n_frames == STOP - START
        # (to round-off: the fits see times shifted by the window's start)
        assert win.celerity_m_s == pytest.approx(cut.celerity_m_s, rel=1e-12)
        assert win.plug_length_mm == pytest.approx(cut.plug_length_mm, rel=1e-12)
        np.testing.assert_allclose(win.diagram.time_s, cut.diagram.time_s + START / fps)  # the movie's times
        assert win.summary["parameters"]["start_frame"] in (START, None)
        # the tables give the movie's frame numbers beside the window's indices
        assert (win.edges.movie_frame - win.edges.frame == START).all()
        assert (cut.edges.movie_frame == cut.edges.frame).all()
        assert (win.tracks.first_movie_frame - win.tracks.first_frame == START).all()


def test_a_window_in_a_compressed_video(movies):
    truth = json.loads((movies["avi"].parent / "truth.json").read_text())
    win = gp.analyze(movies["avi"], start_frame=START, end_frame=STOP, mm_per_px=truth["mm_per_px"])
    assert win.info.n_frames == STOP - START
    assert win.diagram.time_s[0] == pytest.approx(START / win.info.fps)
    assert win.celerity_m_s == pytest.approx(truth["celerity_m_s"], rel=0.03)


def test_window_options_and_their_errors(movies, tmp_path, capsys):
    out = tmp_path / "o"
    code = main(["analyze", str(movies["tiff"]), "--out", str(out), "--start", "100", "--end", "1.0s",
                 "--no-figures", "--json"])
    printed, err = capsys.readouterr()
    assert code == 0, err
    summary = json.loads(printed)
    assert summary["n_frames"] == 150 and summary["parameters"]["start_frame"] == 100
    assert summary["parameters"]["end_s"] == 1.0
    for args, words in ((["--start", "2x"], "neither a frame number"), (["--start", "295"], "--start: the window "
                                                                        "holds 5 of the movie's 300 frames"),
                        (["--start", "2s", "--end", "1s"], "holds 0")):
        code = main(["analyze", str(movies["tiff"]), "--out", str(tmp_path / "bad"), *args])
        err = capsys.readouterr().err
        assert code == 2 and words in err and len(err.strip().splitlines()) == 1, err
        assert not (tmp_path / "bad").exists()
    with pytest.raises(gp.ParameterError, match="not both"):
        gp.AnalysisParams(start_frame=3, start_s=0.1)


def test_an_end_past_the_movie_is_said_and_frames_keep_the_movies_numbers(movies):
    """An end past the last frame was clamped without a word (an end in the wrong unit went unnoticed); a doubtful
    frame of a window is named by its number in the movie, as the tables and the reader's warnings name it."""
    from grainplug.diagram.frames import FrameRepair

    res = gp.analyze(movies["tiff"], start_frame=START, end_frame=400, mm_per_px=0.185)
    [said] = of_code(res, "window.end_past_movie")
    assert "frame 400" in said and "300 frames" in said and res.info.n_frames == 300 - START
    whole = gp.analyze(movies["tiff"], end_frame=400, mm_per_px=0.185)  # a window that is the whole movie
    assert of_code(whole, "window.end_past_movie") and whole.info.n_frames == 300
    # in seconds: the movie's duration as info prints it (rounded up by a frame at most) is its end, not past it
    duration = 300 / whole.info.fps
    exact = gp.analyze(movies["tiff"], start_frame=START, end_s=duration * 1.001, mm_per_px=0.185)
    assert "window.end_past_movie" not in codes(exact), exact.warnings
    late = gp.analyze(movies["tiff"], start_frame=START, end_s=2 * duration, mm_per_px=0.185)
    [said] = of_code(late, "window.end_past_movie")
    assert f"{2 * duration:g} s" in said and f"{duration:.4g} s" in said, late.warnings
    repair = FrameRepair(bright=np.array([34]))
    assert "(frame 134)" in repair.describe(150, first=100) and "(frame 34)" in repair.describe(150)


def test_a_bad_time_stamp_outside_the_window_is_not_the_windows():
    """The reader's warning about frame 234's stamp stays with a window holding that frame, not with one that
    does not (it was repeated for frames 10 to 200 of a 235-frame record)."""
    from grainplug.readers.array import ArrayMovie
    from grainplug.readers.cine import frames_named
    from grainplug.warning_codes import coded

    movie = ArrayMovie(np.zeros((50, 16, 16), np.uint8), fps=100.0)
    bad = coded("movie.frames_out_of_step", f"{frames_named([40])} out of step with the others")
    info = dataclasses.replace(movie.info, warnings=(bad,), details={"frames_with_bad_timestamp": [40]})
    movie.info = info
    assert bad not in FrameWindow(movie, 0, 30).info.warnings
    assert bad in FrameWindow(movie, 30, 50).info.warnings


def test_manifest_window_columns(movies, tmp_path):
    from grainplug.campaigns import read_manifest

    (tmp_path / "m.csv").write_text(f"run,movie,start_frame,end_s\na,{movies['tiff']},100,1.0\n")
    spec = read_manifest(tmp_path / "m.csv")[0]
    assert spec.params.start_frame == 100 and spec.params.end_s == 1.0


# -- region of interest -------------------------------------------------------------------------
@pytest.fixture(scope="module")
def two_tubes(tmp_path_factory):
    """Two tubes side by side (left: plugs climbing at 0.05 m/s, right: 0.08 m/s), in memory and as a TIFF."""
    from grainplug.synthetic import SynthConfig, synthesize

    root = tmp_path_factory.mktemp("two")
    a = synthesize(SynthConfig(n_frames=150, seed=1, celerity_m_s=-0.05), root / "a", fmt="tiff")
    b = synthesize(SynthConfig(n_frames=150, seed=2, celerity_m_s=-0.08), root / "b", fmt="tiff")
    with gp.open_movie(a.movie) as ma, gp.open_movie(b.movie) as mb:
        frames = np.concatenate([np.stack(list(ma.frames())), np.stack(list(mb.frames()))], axis=2)
    path = root / "two.tif"
    tifffile.imwrite(path, frames, photometric="rgb")
    return frames, path


def test_a_region_of_interest_chooses_one_of_two_tubes(two_tubes):
    frames, _ = two_tubes
    left = gp.analyze(frames, fps=250, roi=(0, 0, 128, 640))
    right = gp.analyze(frames, fps=250, roi=(128, 0, 256, 640))
    assert left.celerity_m_s == pytest.approx(-0.05, rel=0.03)
    assert right.celerity_m_s == pytest.approx(-0.08, rel=0.03)
    assert "tube.second_region" not in codes(left), left.warnings
    # without a region, one tube is analysed and the other is pointed out, with the fix
    both = gp.analyze(frames, fps=250)
    said = of_code(both, "tube.second_region")
    assert len(said) == 1 and "roi=" in said[0], both.warnings
    with pytest.raises(gp.ParameterError, match="roi") as err:
        gp.analyze(frames, fps=250, roi=(0, 0, 400, 640))
    assert err.value.param == "roi"


@pytest.mark.parametrize("roi", [(0, 0, 60, 640), (62, 0, 128, 640)])
def test_a_region_that_cuts_the_tube_is_said(two_tubes, roi):
    """A region drawn through the tube (its bore spans x = 56-72) gave a climbing celerity twice the truth, or an
    "oscillating" regime, with only a warning that the contents were not seen to change; regions around the whole
    tube and its walls are measured as before, without the warning."""
    frames, _ = two_tubes
    res = gp.analyze(frames, fps=250, roi=roi)
    [said] = of_code(res, "tube.cut_by_frame")
    assert "widen roi=" in said, res.warnings
    assert not any("contents were not seen to change" in w for w in of_code(res, "scale.edges_only")), res.warnings
    # a region on the bore alone: the contents change across the whole width, the walls out of view, said so
    bore = gp.analyze(frames, fps=250, roi=(56, 0, 72, 640))
    assert of_code(bore, "scale.tube_wide"), bore.warnings
    # a whole tube beside a second one cut by the frame's edge is not cut
    from grainplug.synthetic import SynthConfig
    from grainplug.synthetic.render import Renderer

    a, b = (np.stack(list(Renderer(SynthConfig(n_frames=120, seed=seed)).frames())) for seed in (1, 2))
    beside = gp.analyze(np.concatenate([a, b[:, :, :60]], axis=2), fps=250)
    assert beside.tube.axis_x0_px == pytest.approx(63.5, abs=1)  # the whole one
    assert "tube.cut_by_frame" not in codes(beside), beside.warnings
    for whole in [(40, 0, 90, 640), (50, 0, 78, 640), (0, 0, 128, 640)]:
        res = gp.analyze(frames, fps=250, roi=whole)
        assert "tube.cut_by_frame" not in codes(res), (whole, res.warnings)


def test_no_second_tube_is_seen_in_a_record_too_short_for_the_plugs_to_move(tmp_path):
    """12 frames at 5000 fps (the plugs move 0.1 mm): the tube changes no more than the background's noise,
    which is no reason to suspect another tube."""
    from grainplug.synthetic import SynthConfig, synthesize

    movie = synthesize(SynthConfig(n_frames=12, fps=5000.0, seed=3), tmp_path, fmt="tiff").movie
    res = gp.analyze(movie)
    assert "tube.second_region" not in codes(res), res.warnings


def test_roi_on_the_command_line_reads_the_band_from_the_file(two_tubes, tmp_path, capsys):
    """Through a file (the band read with shifted pixels on the reader's fast path): the same numbers as in
    memory; a malformed --roi is one line."""
    frames, path = two_tubes
    assert main(["analyze", str(path), "--fps", "250", "--roi", "128,0,256,640", "--out", str(tmp_path / "r"),
                 "--no-figures"]) == 0
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert s["parameters"]["roi"] == [128, 0, 256, 640]
    assert s["celerity_m_s"] == pytest.approx(gp.analyze(frames, fps=250, roi=(128, 0, 256, 640)).celerity_m_s,
                                              abs=1e-6)
    capsys.readouterr()
    assert main(["analyze", str(path), "--roi", "1,2,3", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--roi" in err[0]
