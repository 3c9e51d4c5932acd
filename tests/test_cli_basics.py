"""`grainplug info` and `synth`; bad input gives one clear line and a non-zero exit."""

from __future__ import annotations

import json

import pytest

from grainplug.cli import main
from grainplug.synthetic import FORMATS, SynthConfig, synthesize


def run(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(code, err, *words):
    assert code != 0
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ")
    assert "Traceback" not in err
    for w in words:
        assert w in lines[0]


@pytest.mark.parametrize("fmt", list(FORMATS))
def test_info_reads_every_synth_format(tmp_path, capsys, fmt):
    args = ["synth", "--out", tmp_path, "--format", fmt, "--frames", 5, "--seed", 2]
    if fmt == "cine":
        args += ["--bit-depth", "16"]
    code, out, err = run(capsys, *args)
    assert code == 0, err
    movie = next(p for p in tmp_path.iterdir() if p.name.startswith("movie") and p.suffix != ".cih")
    extra = ["--fps", 250] if FORMATS[fmt].suffix == "" else []
    code, out, err = run(capsys, "info", movie, "--json", *extra)
    assert code == 0, err
    d = json.loads(out)
    assert d["n_frames"] == 5
    assert (d["width"], d["height"]) == (128, 640)
    assert d["fps"] == pytest.approx(250.0)
    assert d["duration_s"] == pytest.approx(5 / 250)
    code, out, err = run(capsys, "info", movie, *extra)
    assert code == 0 and "frames     5" in out and "128 x 640" in out


def test_missing_path(tmp_path, capsys):
    code, _, err = run(capsys, "info", tmp_path / "nope.avi")
    assert_one_line_error(code, err, "no such file", "nope.avi")


def test_empty_folder(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    code, _, err = run(capsys, "info", tmp_path / "empty")
    assert_one_line_error(code, err, "no images")


@pytest.mark.parametrize("fmt", ["h264", "avi", "ffv1"])
def test_truncated_video(tmp_path, capsys, fmt):
    res = synthesize(SynthConfig(n_frames=20, seed=1), tmp_path, fmt=fmt)
    data = res.movie.read_bytes()
    res.movie.write_bytes(data[: len(data) // 2])
    code, _, err = run(capsys, "info", res.movie)
    assert_one_line_error(code, err)
    assert any(w in err for w in ("truncated", "corrupt", "complete"))


def test_truncated_tiff(tmp_path, capsys):
    res = synthesize(SynthConfig(n_frames=20, seed=1), tmp_path, fmt="tiff")
    data = res.movie.read_bytes()
    res.movie.write_bytes(data[: len(data) // 2])
    code, _, err = run(capsys, "info", res.movie)
    assert_one_line_error(code, err)


@pytest.mark.parametrize("name,content", [("notes.avi", b"this is not a movie at all\n" * 50),
                                          ("data.mp4", bytes(range(256)) * 40),
                                          ("empty.mkv", b""),
                                          ("garbage.tif", b"II*\x00garbage" * 10)])
def test_not_a_movie(tmp_path, capsys, name, content):
    p = tmp_path / name
    p.write_bytes(content)
    code, _, err = run(capsys, "info", p)
    assert_one_line_error(code, err, name)


def test_bad_parameter(tmp_path, capsys):
    code, _, err = run(capsys, "synth", "--out", tmp_path, "--tilt-deg", "12")
    assert_one_line_error(code, err, "tilt")
    code, _, err = run(capsys, "synth", "--out", tmp_path, "--format", "gif")
    assert_one_line_error(code, err, "gif")
    res = synthesize(SynthConfig(n_frames=2), tmp_path / "m")
    code, _, err = run(capsys, "info", res.movie, "--fps", "-3")
    assert_one_line_error(code, err, "fps")


def test_debug_shows_traceback(tmp_path):
    with pytest.raises(Exception, match="no such file"):
        main(["--debug", "info", str(tmp_path / "nope.avi")])


def test_ctrl_c_inside_compiled_code_is_an_interruption(monkeypatch, tmp_path, capsys):
    """numba turns a Ctrl-C in a compiled loop into "SystemError: ... returned a result with an exception
    set", the KeyboardInterrupt as its cause: the command line says "interrupted" (130), not a bug (1)."""
    import grainplug.campaigns.paper as paper
    from grainplug.cli import main

    def interrupted(**_kw):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:
            raise SystemError("CPUDispatcher(<function advance>) returned a result with an exception set") from exc

    monkeypatch.setattr(paper, "reproduce", interrupted)
    assert main(["paper", "--out", str(tmp_path / "p")]) == 130
    assert capsys.readouterr().err.strip() == "error: interrupted"


def test_a_high_speed_clips_duration_keeps_its_digits(tmp_path, capsys):
    """15 frames at 30 000 fps (0.5 ms) read "0.001 s" (three fixed decimals): four significant digits now."""
    code, out, err = run(capsys, "synth", "--out", tmp_path, "--format", "tiff", "--frames", 15, "--seed", 2)
    assert code == 0, err
    code, out, err = run(capsys, "info", tmp_path / "movie.tif", "--fps", 30000)
    assert code == 0 and "duration   0.0005 s" in out, out
    code, out, err = run(capsys, "info", tmp_path / "movie.tif", "--fps", 9000)
    assert "duration   0.001667 s" in out


@pytest.mark.parametrize("depth", ["8", "16"])
def test_synth_cine_is_written_at_the_bit_depth_asked(tmp_path, capsys, depth):
    code, _, err = run(capsys, "synth", "--out", tmp_path, "--format", "cine", "--frames", 3, "--seed", 2,
                       "--bit-depth", depth)
    assert code == 0, err
    code, out, err = run(capsys, "info", tmp_path / "movie.cine", "--json")
    assert code == 0, err
    d = json.loads(out)
    assert d["bit_depth"] == int(depth), d
    assert (tmp_path / "movie.cine").stat().st_size < 3 * 128 * 640 * int(depth) // 8 + 20_000  # no 16-bit padding
