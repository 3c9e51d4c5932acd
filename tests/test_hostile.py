"""Hostile input (issue 17): one clear line and a documented exit status, nothing written, nothing lost.

Each case failed on the code before issue 17's first step (an "unexpected ... report it" line, a
traceback, numpy warnings on stderr, a silently wrong or half-written result).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
import tifffile
from warned import of_code

import grainplug as gp
from grainplug._atomic import OutputPlaceError
from grainplug.cli import main
from grainplug.synthetic import SynthConfig
from grainplug.synthetic.render import Renderer


@pytest.fixture(scope="module")
def frames() -> np.ndarray:
    return np.stack(list(Renderer(SynthConfig(n_frames=60, width_px=64, height_px=300, seed=1, rgb=False)).frames()))


@pytest.fixture
def movie(tmp_path, frames) -> Path:
    p = tmp_path / "movie.tif"
    tifffile.imwrite(p, frames, metadata={"fps": 250.0})
    return p


def run(capsys, *args: object) -> tuple[int, str]:
    capsys.readouterr()
    code = main([str(a) for a in args])
    return code, capsys.readouterr().err


def one_line(err: str, *words: str) -> None:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "report it" not in err and "Traceback" not in err and "Warning" not in err, err
    for w in words:
        assert w in lines[0], err


# -- numbers at the door ------------------------------------------------------------------
@pytest.mark.parametrize(("flag", "value", "words"), [
    ("--fps", "inf", "must be a finite number"),
    ("--fps", "1e12", "between 1 and 1e+07 frames per second"),
    ("--fps", "nan", "must be a finite number"),
    ("--mm-per-px", "inf", "must be a finite number"),
    ("--mm-per-px", "1e300", "mm per pixel"),
    ("--tube-diameter-mm", "inf", "must be a finite number"),
    ("--min-plug-mm", "inf", "must be a finite number"),
    ("--threads", "0", "between 1 and 1024"),
])
def test_analyze_numbers_are_checked_before_anything_runs(tmp_path, capsys, movie, flag, value, words):
    code, err = run(capsys, "analyze", movie, "--out", tmp_path / "out", flag, value, "--no-figures")
    assert code == 2
    one_line(err, flag, words)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("args", "words"), [
    (["--k-max", "inf"], "--k-max"),
    (["--n-k", "1000000000000"], "--n-k: 1,000,000,000,000 wavenumbers would take about"),
    (["--plot", "x.xyz"], "--plot must name a .png, .svg or .pdf file"),
])
def test_stability_numbers_and_plot_names(tmp_path, capsys, monkeypatch, args, words):
    monkeypatch.chdir(tmp_path)  # put back afterwards: the folder is removed once the test passes
    code, err = run(capsys, "stability", *args)
    assert code == 2
    one_line(err, words)


def test_library_parameters_are_checked_too():
    import grainplug as gp

    for kw in ({"fps": float("inf")}, {"fps": 1e12}, {"mm_per_px": float("nan")}, {"min_plug_mm": float("inf")},
               {"tube_diameter_mm": 0.0}, {"sample_frames": 10**9}):
        with pytest.raises(gp.ParameterError):
            gp.AnalysisParams(**kw)
    with pytest.raises(gp.ParameterError, match="wavenumbers would take about"):
        gp.analyze_stability(gp.ModelParams(), n_k=10**12)
    with pytest.raises(gp.ParameterError, match="n_k must be at least 2"):
        gp.analyze_stability(gp.ModelParams(), n_k=float("inf"))


# -- output places ------------------------------------------------------------------------
def test_output_places_that_cannot_be_right(tmp_path, capsys, movie):
    (tmp_path / "afile").write_text("x")
    (tmp_path / "loop1").symlink_to(tmp_path / "loop2")
    (tmp_path / "loop2").symlink_to(tmp_path / "loop1")
    (tmp_path / "theirs").mkdir()
    (tmp_path / "theirs" / "thesis.docx").write_text("years of work")
    cases = [
        (tmp_path / "afile", "is a file"),
        (tmp_path / "afile" / "sub", "which is a file"),
        (tmp_path / "loop1", "symbolic links"),
        (movie, "is the input itself"),
        (tmp_path, "holds the input movie.tif"),
        (tmp_path / "theirs", "holds files grainplug did not write"),
    ]
    for out, words in cases:
        code, err = run(capsys, "analyze", movie, "--out", out, "--no-figures")
        assert code == 2, (out, err)
        one_line(err, words)
    assert (tmp_path / "theirs" / "thesis.docx").read_text() == "years of work"
    assert movie.stat().st_size > 0 and (tmp_path / "afile").read_text() == "x"


def test_a_rerun_is_refused_then_replaces_the_folder_whole_with_overwrite(tmp_path, capsys, movie):
    out = tmp_path / "out"
    assert main(["analyze", str(movie), "--out", str(out)]) == 0
    assert (out / "diagram.png").exists()
    before = (out / "summary.json").read_bytes()
    capsys.readouterr()
    assert main(["analyze", str(movie), "--out", str(out), "--no-figures"]) == 2  # not without asking
    one_line(capsys.readouterr().err, "already exists — pass --overwrite")
    assert (out / "summary.json").read_bytes() == before
    # what grainplug did not write there (a user's notes, a reviewer's corrections) is never deleted
    texts = {"notes.txt": "what I saw", "corrections.json": json.dumps(gp.Corrections().add("exclude", track=0)
                                                                        .as_dict())}
    for extra, text in texts.items():
        (out / extra).write_text(text)
        assert main(["analyze", str(movie), "--out", str(out), "--no-figures", "--overwrite"]) == 2
        one_line(capsys.readouterr().err, f"holds what grainplug did not write there: {extra}")
        assert (out / "summary.json").read_bytes() == before and (out / extra).exists()
        with pytest.raises(OutputPlaceError, match=extra):
            gp.load_result(out).save(out)  # the Python API too
        (out / extra).unlink()
    assert main(["analyze", str(movie), "--out", str(out), "--no-figures", "--overwrite"]) == 0
    assert not (out / "diagram.png").exists()  # the earlier run's files go with it
    s = json.loads((out / "summary.json").read_text())
    assert set(s["outputs"].values()) <= {p.name for p in out.iterdir()}  # what it lists, it wrote
    assert not [p for p in tmp_path.iterdir() if ".grainplug-" in p.name]  # no temporary folder left


def test_a_killed_run_leaves_the_previous_result_and_is_cleaned_up(tmp_path, capsys, movie):
    out = tmp_path / "out"
    assert main(["analyze", str(movie), "--out", str(out), "--no-figures"]) == 0
    before = (out / "summary.json").read_text()
    # what a run killed half-way leaves: its temporary folder (a dead process id), and one killed
    # between the two renames: the previous result set aside and no folder in place
    dead = 2**22 + 12345
    (tmp_path / f".out.grainplug-new-{dead}-abc").mkdir()
    os.replace(out, tmp_path / f".out.grainplug-old-{dead}-xyz")
    from grainplug._atomic import atomic_directory

    with atomic_directory(out, replace=True) as tmp:
        (tmp / "summary.json").write_text(before)
    assert (out / "summary.json").read_text() == before
    assert not [p for p in tmp_path.iterdir() if ".grainplug-" in p.name]


def test_a_full_disk_is_one_line_and_the_previous_result_stays(tmp_path, monkeypatch, movie):
    import errno

    import grainplug as gp
    from grainplug._atomic import OutputPlaceError

    out = tmp_path / "out"
    res = gp.analyze(movie)
    res.save(out, figures=False, report=False)
    before = (out / "summary.json").read_text()

    def full(*a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr("grainplug.store.write_result", full)
    monkeypatch.setattr("grainplug.outputs.write_result", full)
    with pytest.raises(OutputPlaceError, match=r"the disk is full .* \(the previous result, if any, is intact\)"):
        res.save(out, figures=False, report=False)
    assert (out / "summary.json").read_text() == before
    assert not [p for p in tmp_path.iterdir() if ".grainplug-" in p.name]


# -- movies -----------------------------------------------------------------------------------
def _pages(path: Path, pages: list[np.ndarray]) -> Path:
    with tifffile.TiffWriter(path) as t:
        for p in pages:
            t.write(p)
    return path


@pytest.mark.parametrize("kind", ["sizes", "depths", "black", "white", "line", "trailing axis"])
def test_hostile_movies(tmp_path, capsys, frames, kind):
    f = frames
    if kind == "sizes":
        path, words = _pages(tmp_path / "m.tif", [f[k] if k < 10 else f[k][:, :60] for k in range(20)]), \
            "page 10 is 300x60 uint8 but page 0 is 300x64 uint8"
    elif kind == "depths":
        path, words = _pages(tmp_path / "m.tif", [f[k] if k % 2 else f[k].astype(np.uint16) * 256
                                                  for k in range(20)]), "must all have one size and bit depth"
    elif kind in ("black", "white"):
        path = tmp_path / "m.tif"
        tifffile.imwrite(path, np.full((30, 300, 64), 0 if kind == "black" else 255, np.uint8))
        words = "every sampled frame is uniform"
    elif kind == "line":
        path = tmp_path / "m.tif"
        tifffile.imwrite(path, np.random.default_rng(0).integers(0, 255, (30, 1, 5000), dtype=np.uint8))
        words = "too small to hold a tube"
    else:  # T x H x W x 1 is a valid grey stack, not a truncated file
        path = tmp_path / "m.tif"
        tifffile.imwrite(path, f[..., None])
        code, err = run(capsys, "analyze", path, "--out", tmp_path / "out", "--fps", 250, "--no-figures")
        assert code == 0, err
        assert json.loads((tmp_path / "out" / "summary.json").read_text())["n_frames"] == len(f)
        return
    code, err = run(capsys, "analyze", path, "--out", tmp_path / "out", "--fps", 250, "--no-figures")
    assert code == 2
    one_line(err, words)
    assert not (tmp_path / "out").exists()


# -- manifests ------------------------------------------------------------------------------
@pytest.mark.parametrize(("name", "content", "words"), [
    ("m.csv", b"run,movie\n\xff\xfe,movie.tif\n", "m.csv, line 2: not UTF-8 text"),
    ("m.toml", b'defaults = 3\n[[run]]\nmovie = "movie.tif"\n', "'defaults' must be a table"),
    ("m.csv", b"run,movie\n..,movie.tif\n", "column run: '..' cannot name a run's folder"),
    ("m.csv", b"run,movie\na/b,movie.tif\n", "column run: 'a/b' cannot name a run's folder"),
    ("m.csv", b"run,movie\na b,movie.tif\na_b,movie.tif\n", "would share the folder runs/a_b"),
    ("m.csv", b'run,movie\nr0,movie.tif\n"a,movie.tif\nr2,movie.tif\n', "m.csv, line 3: not valid CSV"),
    # a record is named by the line it starts on, though a quoted field spans two
    ("m.csv", b'run,movie,mm_per_px\nr0,movie.tif,0.1\nr1,"movie\n.tif",abc\n', "m.csv, line 3, column mm_per_px"),
    ("m.csv", b"run,movie,fps\na,movie.tif,inf\n", "m.csv, line 2, column fps"),
    ("m.csv", b"run,movie\na,movie.tif,extra\n", "more values than the header"),
])
def test_bad_manifests(tmp_path, capsys, movie, name, content, words):
    (tmp_path / name).write_bytes(content)
    code, err = run(capsys, "batch", tmp_path / name, "--out", tmp_path / "camp")
    assert code == 2
    one_line(err, words)
    assert not (tmp_path / "camp").exists()


def test_a_folder_or_a_pipe_is_no_manifest_and_a_pipe_no_movie(tmp_path, capsys, movie):
    code, err = run(capsys, "batch", tmp_path, "--out", tmp_path / "camp")
    one_line(err, "is a folder — give the manifest file")
    os.mkfifo(tmp_path / "pipe")
    (tmp_path / "m.csv").write_text("run,movie\na,pipe\n")
    code, err = run(capsys, "batch", tmp_path / "m.csv", "--out", tmp_path / "camp")  # used to hang
    assert code == 2
    one_line(err, "column movie", "is not a regular file")


def test_failed_runs_give_exit_status_3(tmp_path, capsys, movie):
    (tmp_path / "m.csv").write_text("run,movie\ngood,movie.tif\nbad,missing.tif\nworse,missing2.tif\n")
    code, err = run(capsys, "batch", tmp_path / "m.csv", "--out", tmp_path / "camp", "--no-figures")
    assert code == 3
    # every failed run named, one line each (after the good run's own warnings)
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("warning: run good: ")]
    assert [ln.split(":")[0] for ln in lines] == ["failed", "failed", "error"], err
    assert "run bad: " in lines[0] and "missing.tif" in lines[0] and "run worse: " in lines[1]
    assert lines[2].startswith("error: 2 of 3 runs failed") and "Traceback" not in err
    assert (tmp_path / "camp" / "runs" / "good" / "summary.json").exists()


# -- doubtful frames --------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["dark", "over-exposed", "repeated"])
def test_doubtful_frames_are_bridged_and_counted(frames, kind):
    import grainplug as gp

    clean = gp.analyze(frames, fps=250.0)
    bad = frames.copy()
    if kind == "dark":
        bad[20:25] = 0  # the lamp failed for five frames: the celerity read 85 % low before
        idx = "frames 20, 21, 22, 23, 24"
    elif kind == "over-exposed":
        bad[30] = 255  # a flash: the scale and celerity moved by 5 %
        idx = "frame 30"
    else:
        bad[40:43] = bad[39]  # the camera repeated a frame three times
        idx = "frames 40, 41, 42"
    res = gp.analyze(bad, fps=250.0)
    assert res.celerity_m_s == pytest.approx(clean.celerity_m_s, rel=0.01)
    assert res.plug_length_mm == pytest.approx(clean.plug_length_mm, rel=0.02)
    [said] = of_code(res, "frames.repaired")
    assert f"{kind} ({idx})" in said, res.warnings


def test_flicker_is_not_taken_for_bad_frames(rng):
    from grainplug.diagram.frames import repair_frames

    values = (100 + 50 * (rng.random((500, 300)) < 0.5)).astype(np.float32)
    values *= (1 + 0.1 * np.sin(np.arange(500) * 0.7))[:, None].astype(np.float32)  # +-10 % lamp flicker
    fixed, repair = repair_frames(values, top=255.0)
    assert repair.n_bad == 0 and fixed is values


def test_a_still_noiseless_scene_is_not_called_repeated():
    from grainplug.diagram.frames import repair_frames

    row = np.linspace(10, 200, 300, dtype=np.float32)
    values = np.repeat(row[None], 100, axis=0)
    values[50:] += 5  # one change half-way: every other frame repeats the one before
    _fixed, repair = repair_frames(values, top=255.0)
    assert repair.n_bad == 0 and repair.n_still == 98
    assert repair.describe(100).startswith("98 of 100 frames repeat the one before exactly")


def test_a_frozen_movie_is_said_and_does_not_crash_after_writing(tmp_path, capsys, frames):
    """Found by a held-out battery: one frame repeated 60 times crashed the summary print after the
    outputs were written ('unexpected TypeError')."""
    movie = tmp_path / "frozen.tif"
    tifffile.imwrite(movie, np.repeat(frames[:1], 60, axis=0))
    code = main(["analyze", str(movie), "--out", str(tmp_path / "o"), "--fps", "250", "--mm-per-px", "0.185",
                 "--no-figures"])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "59 of 60 frames repeat the one before exactly" in err and "unexpected" not in err
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    [said] = of_code(summary, "frames.repaired")
    assert said.startswith("59 of 60 frames repeat"), summary["warnings"]


@pytest.mark.parametrize("bad", [np.nan, np.inf])
@pytest.mark.parametrize("where", ["every frame", "one frame"])
def test_frames_with_nan_or_infinite_pixels_are_one_clear_error(frames, bad, where):
    """A masked dead pixel (NaN) in float frames was reported as "every sampled frame is uniform (all pixels
    nan)"; an infinite one crashed with a reshape error after numpy's warnings; one in a frame that was not
    sampled gave "no plugs"."""
    import grainplug as gp
    from grainplug.errors import MovieError

    a = frames.astype(np.float32)
    if where == "every frame":
        a[:, 150, 30] = bad
    else:
        a[1, 150, 32] = bad  # in the tube, in a frame the tube search does not sample
    said = r"1 of the 60 frames \(frame 1 of" if where == "one frame" else "sampled frames"
    with pytest.raises(MovieError, match=said + r".*hold NaN or infinite pixels.*replace them first"):
        gp.analyze(a, fps=250.0)


def test_a_camera_s_dark_offset_does_not_hide_the_plugs(frames):
    """8-bit contrast under a 16-bit camera's offset of 16000 (1 % relative contrast): the log grey levels'
    contrast was taken as flat (too narrow for the histogram's bins in float32), and the run said "no plugs"."""
    import grainplug as gp

    clean = gp.analyze(frames, fps=250.0)
    offset = gp.analyze(frames.astype(np.uint16) + np.uint16(16000), fps=250.0, mm_per_px=clean.mm_per_px)
    assert offset.has_plugs
    assert offset.celerity_m_s == pytest.approx(clean.celerity_m_s, rel=0.01)
    assert offset.plug_length_mm == pytest.approx(clean.plug_length_mm, rel=0.02)


def test_float16_frames_are_analysed_without_numpy_warnings(frames):
    """The saturation check compared float16 frames with 65535, beyond float16's range ("overflow encountered in
    cast"); float frames have no top value a camera clips at (the suite runs with warnings as errors)."""
    import grainplug as gp

    res = gp.analyze(frames.astype(np.float16), fps=250.0)
    assert res.has_plugs and res.celerity_m_s == pytest.approx(gp.analyze(frames, fps=250.0).celerity_m_s, rel=0.01)
