"""The default install holds no PyAV (its wheels bundle an FFmpeg built with the GPL encoders x264
and x265): videos are then read through OpenCV, the overlay is a WebM, and whatever needs PyAV says
how to get it. ``import av`` is made to fail here as it does where PyAV is not installed."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from warned import codes, of_code

import grainplug as gp
from grainplug.errors import ParameterError


@pytest.fixture(scope="module")
def with_pyav(tmp_path_factory):
    """The bundled sample analysed through PyAV, for comparison."""
    return gp.analyze(gp.datasets.sample_movie())


@pytest.fixture
def no_pyav(monkeypatch):
    monkeypatch.setitem(sys.modules, "av", None)


def test_the_sample_is_analysed_through_opencv_as_through_pyav(with_pyav, no_pyav, tmp_path, capsys):
    """Same edges to a pixel's worth and same measures within their intervals; the overlay is a WebM."""
    from grainplug.cli import main
    from grainplug.readers import open_movie, pyav_available

    assert not pyav_available()
    sample = gp.datasets.sample_movie()
    with open_movie(sample) as m:
        assert m.info.format == "video-opencv:mp4/h264" and m.info.warnings == ()
    res = gp.analyze(sample)
    assert res.info.format.startswith("video-opencv:")
    assert res.summary["n_plugs"] == with_pyav.summary["n_plugs"]
    assert res.mm_per_px == pytest.approx(with_pyav.mm_per_px, rel=0.005)
    assert abs(res.celerity_m_s - with_pyav.celerity_m_s) < 0.02 * abs(with_pyav.celerity_m_s)
    assert abs(res.plug_length_mm - with_pyav.plug_length_mm) < res.mm_per_px
    out = tmp_path / "run"
    res.save(out, figures=False)
    assert main(["overlay", str(out), "--every", "10"]) == 0
    assert str(out / "overlay.webm") in capsys.readouterr().out
    assert (out / "overlay.webm").stat().st_size > 1000


def test_what_needs_pyav_says_how_to_get_it(with_pyav, no_pyav, tmp_path):
    from grainplug.overlay import write_overlay
    from grainplug.synthetic import SynthConfig, synthesize

    out = tmp_path / "run"
    with_pyav.save(out, figures=False)
    with pytest.raises(ParameterError, match=r'pip install "grainplug\[video\]", or give a name ending in \.webm'):
        write_overlay(out, out / "overlay.mp4")
    assert not (out / "overlay.mp4").exists()
    with pytest.raises(ParameterError, match=r'needs PyAV: pip install "grainplug\[video\]"'):
        synthesize(SynthConfig(n_frames=4, width_px=32, height_px=64), tmp_path / "m", fmt="h264")
    assert not (tmp_path / "m").exists()  # refused before anything was written


def grey_mkv(path, gaps_ms, *, rate=250, width=None, height=None, h264=False):
    """A lossless grey (FFV1) Matroska movie of synthetic plug flow whose frames are ``gaps_ms`` apart (one
    gap per frame after the first; times in whole ms, as Matroska stores them); or H.264, a key frame every
    50 frames and no B-frames."""
    from fractions import Fraction

    import av
    import numpy as np

    from grainplug.synthetic import SynthConfig
    from grainplug.synthetic.render import Renderer

    size = {} if width is None else {"width_px": width, "height_px": height}
    frames = list(Renderer(SynthConfig(n_frames=len(gaps_ms) + 1, rgb=False, seed=7, **size)).frames())
    stamps = np.concatenate([[0], np.cumsum(gaps_ms)]).astype(int)
    with av.open(str(path), "w") as out:
        stream = out.add_stream("libx264" if h264 else "ffv1", **({"rate": rate} if rate else {}))
        stream.width, stream.height = frames[0].shape[1], frames[0].shape[0]
        stream.pix_fmt = "yuv420p" if h264 else "gray"
        stream.time_base = stream.codec_context.time_base = Fraction(1, 1000)
        if h264:
            stream.codec_context.gop_size = 50
            stream.options = {"bf": "0"}
        for f, t in zip(frames, stamps, strict=True):
            vf = av.VideoFrame.from_ndarray(f, format="gray")
            vf.pts, vf.time_base = int(t), Fraction(1, 1000)
            for packet in stream.encode(vf):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)
    return path


@pytest.fixture(scope="module")
def uneven(tmp_path_factory):
    """A lossless Matroska movie whose first 60 frames are 4 ms apart and the next 60 frames 8 ms apart."""
    return grey_mkv(tmp_path_factory.mktemp("vfr") / "vfr.mkv", [4] * 60 + [8] * 59)


@pytest.mark.parametrize("reader", ["pyav", "opencv"])
def test_uneven_frame_times_are_used_and_said(uneven, monkeypatch, reader):
    """Both readers: all 120 frames (not refused as truncated: the count estimated from the duration is
    too high), timed by the file's stamps, and a warning that they are uneven."""
    import numpy as np

    if reader == "opencv":
        monkeypatch.setitem(sys.modules, "av", None)
    res = gp.analyze(uneven)
    assert res.info.n_frames == 120 and res.info.format.startswith("video-opencv" if reader == "opencv" else "video:")
    np.testing.assert_allclose(np.diff(res.diagram.time_s)[[0, 58, 60, 118]], [0.004, 0.004, 0.008, 0.008],
                               atol=1e-6)
    said = of_code(res, "time.uneven")
    assert len(said) == 1 and "4 to 8 ms" in said[0], res.warnings
    with gp.open_movie(uneven) as m:  # frames reached by seeking are the frames in order
        every = list(m.frames())
        for k in (100, 5, 119, 61):
            np.testing.assert_array_equal(m.read(k), every[k])


@pytest.mark.parametrize("reader", ["pyav", "opencv"])
def test_a_window_of_uneven_frames_keeps_their_own_times(uneven, monkeypatch, reader):
    """--start/--end on a variable-rate file: both readers time the window's frames by the file's stamps, with
    the movie's own times, and warn (the OpenCV reader used to time a window by the rate, silently)."""
    import numpy as np

    if reader == "opencv":
        monkeypatch.setitem(sys.modules, "av", None)
    res = gp.analyze(uneven, start_frame=10, end_frame=100)
    assert res.info.n_frames == 90
    assert res.diagram.time_s[0] == pytest.approx(0.040, abs=1e-6)  # frame 10, 4 ms apart from the start
    np.testing.assert_allclose(np.diff(res.diagram.time_s)[[0, 49, 50, 88]], [0.004, 0.004, 0.008, 0.008],
                               atol=1e-6)
    assert len(of_code(res, "time.uneven")) == 1, res.warnings


def test_the_opencv_reader_s_stamps_keep_the_movie_protocol(uneven, no_pyav):
    """After reading the first frames only, timestamps_s still has one time a frame (by the rate) and says no
    file stamps; the first frames' own stamps are there for a window; after a whole pass, every frame's."""
    import numpy as np

    with gp.open_movie(uneven) as m:
        for _ in m.frames(0, 10):
            pass
        assert not m.has_file_timestamps and len(m.timestamps_s()) == 120
        np.testing.assert_allclose(m.file_timestamps_upto(10), 0.004 * np.arange(10), atol=1e-6)
        assert m.file_timestamps_upto(11) is None
        for _ in m.frames():
            pass
        assert m.has_file_timestamps and m.timestamps_s()[-1] == pytest.approx(0.004 * 60 + 0.008 * 59)


@pytest.fixture(scope="module")
def deep_colour(tmp_path_factory):
    """A 16-bit colour FFV1 movie, which OpenCV reads as 8 bits."""
    from grainplug.synthetic import SynthConfig, synthesize

    return synthesize(SynthConfig(n_frames=8, width_px=64, height_px=160, bit_depth=16, seed=2),
                      tmp_path_factory.mktemp("deep"), fmt="ffv1").movie


def test_the_terminal_shows_the_fix_whole_and_a_bad_file_in_one_line(deep_colour, no_pyav, tmp_path, capfd):
    """The install hint keeps its ``[video]`` (not eaten as markup), and what FFmpeg prints about a file
    that is no movie stays off the terminal: one line."""
    from grainplug.cli import main

    assert main(["info", str(deep_colour)]) == 0
    err = capfd.readouterr().err
    assert 'pip install "grainplug[video]"' in err
    bad = tmp_path / "text.mp4"
    bad.write_text("not a movie\n" * 50)
    assert main(["analyze", str(bad), "--out", str(tmp_path / "out")]) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "text.mp4" in err[0], err
    assert not (tmp_path / "out").exists()


@pytest.fixture(scope="module")
def yuv10(tmp_path_factory):
    """A lossless 10-bit YUV (yuv420p10le) FFV1 movie."""
    from fractions import Fraction

    import av
    import numpy as np

    path = tmp_path_factory.mktemp("yuv10") / "yuv10.mkv"
    rng = np.random.default_rng(5)
    with av.open(str(path), "w") as out:
        stream = out.add_stream("ffv1", rate=Fraction(250))
        stream.width, stream.height, stream.pix_fmt = 64, 48, "yuv420p10le"
        for _ in range(10):
            frame = rng.integers(0, 65535, (48, 64, 3), dtype=np.uint16)
            for packet in stream.encode(av.VideoFrame.from_ndarray(frame, format="rgb48le")):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)
    return path


@pytest.mark.parametrize("reader", ["pyav", "opencv"])
def test_deep_yuv_video_is_said_to_be_read_as_8_bits(yuv10, monkeypatch, reader):
    """Both readers hand out 10-bit YUV as 8-bit RGB, and say so; the fix is another export, not PyAV."""
    if reader == "opencv":
        monkeypatch.setitem(sys.modules, "av", None)
    with gp.open_movie(yuv10) as m:
        assert m.info.dtype == "uint8" and m.info.bit_depth == 8
        assert len(m.info.warnings) == 1 and of_code(m.info, "movie.deep_read_shallow") == list(m.info.warnings)
        assert "YUV" in m.info.warnings[0] and "16-bit TIFF" in m.info.warnings[0]
        assert "pip install" not in m.info.warnings[0]


def test_the_default_install_declares_no_pyav():
    """pyproject.toml: PyAV (whose wheels bundle the GPL encoders x264 and x265) only in extras."""
    import re
    import tomllib
    from pathlib import Path

    project = tomllib.loads((Path(__file__).resolve().parent.parent / "pyproject.toml").read_text())["project"]
    names = {re.split(r"[<>=!~\[ ;]", dep, maxsplit=1)[0].lower() for dep in project["dependencies"]}
    assert "av" not in names and "imageio-ffmpeg" not in names
    assert any(dep.startswith("av") for dep in project["optional-dependencies"]["video"])


def numbered_frame(k: int) -> np.ndarray:
    """A 64 x 64 frame that shows its number ``k`` in binary (16 squares), whatever the codec does to it."""
    img = np.zeros((64, 64), np.uint8)
    for b in range(16):
        if (k >> b) & 1:
            r, c = divmod(b, 4)
            img[r * 16:(r + 1) * 16, c * 16:(c + 1) * 16] = 255
    return img


def frame_number(img: np.ndarray) -> int:
    grey = img.mean(axis=2) if img.ndim == 3 else img
    return sum(1 << b for b in range(16) if grey[(b // 4) * 16:(b // 4 + 1) * 16, (b % 4) * 16:(b % 4 + 1) * 16].mean()
               > 127)


def test_a_seek_among_close_frames_is_checked_by_their_own_spacing(tmp_path, monkeypatch):
    """H.264 in Matroska, 200 frames 40 ms apart, then 200 frames 10 ms apart: OpenCV's seek lands two frames
    off among the close ones. Once the movie was read through, the landing is caught (the frame's stamp is
    checked against its own neighbours' spacing, not half the average period) and the frame decoded forward."""
    from fractions import Fraction

    import av

    path = tmp_path / "vfr.mkv"
    stamps = np.r_[np.arange(200) * 40, 8000 + np.arange(1, 201) * 10]
    with av.open(str(path), "w") as out:
        stream = out.add_stream("libx264")
        stream.width = stream.height = 64
        stream.pix_fmt = "yuv420p"
        stream.time_base = stream.codec_context.time_base = Fraction(1, 1000)
        stream.codec_context.gop_size = 50
        stream.options = {"bf": "0"}
        for k, t in enumerate(stamps):
            vf = av.VideoFrame.from_ndarray(np.stack([numbered_frame(k)] * 3, -1), format="rgb24")
            vf.pts, vf.time_base = int(t), Fraction(1, 1000)
            for packet in stream.encode(vf):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)
    monkeypatch.setitem(sys.modules, "av", None)
    with gp.open_movie(path) as m:
        assert m.info.n_frames == 400
        assert [frame_number(f) for f in m.frames()] == list(range(400))  # read through: stamps recorded
        assert m.has_file_timestamps
        for k in (0, 323, 324, 326, 250, 399, 201, 5):
            assert frame_number(m.read(k)) == k
        assert [frame_number(f) for f in m.frames(323, 330)] == list(range(323, 330))


@pytest.mark.parametrize("reader", ["pyav", "opencv"])
def test_a_constant_rate_in_whole_milliseconds_is_even(tmp_path, monkeypatch, reader):
    """60 fps in Matroska: frames 16 and 17 ms apart (whole ms) are a constant rate, not uneven; the times are
    the rate's (exact), with no warning."""
    import numpy as np

    gaps = np.diff(np.round(np.arange(91) * 1000 / 60)).astype(int).tolist()
    movie = grey_mkv(tmp_path / "r60.mkv", gaps, rate=60)
    if reader == "opencv":
        monkeypatch.setitem(sys.modules, "av", None)
    res = gp.analyze(movie)
    assert "time.uneven" not in codes(res), res.warnings
    np.testing.assert_allclose(res.diagram.time_s, np.arange(91) / 60, atol=1e-9)


def test_a_failed_read_leaves_the_reader_usable(tmp_path, monkeypatch):
    """An MP4 with its index first, cut to 60 %: reading past the cut fails in one line, and the frames before
    it are read right afterwards (the capture's position is not trusted after an error)."""
    from fractions import Fraction

    import av
    import numpy as np

    from grainplug.errors import MovieError
    from grainplug.synthetic import SynthConfig
    from grainplug.synthetic.render import Renderer

    frames = list(Renderer(SynthConfig(n_frames=120, width_px=48, height_px=96, seed=2)).frames())
    path = tmp_path / "cut.mp4"
    with av.open(str(path), "w", options={"movflags": "faststart"}) as out:
        stream = out.add_stream("libx264", rate=Fraction(250), options={"g": "10"})
        stream.width, stream.height, stream.pix_fmt = 48, 96, "yuv420p"
        for f in frames:
            for packet in stream.encode(av.VideoFrame.from_ndarray(f, format="rgb24")):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)
    with gp.open_movie(path) as whole:
        every = list(whole.frames())
    data = path.read_bytes()
    path.write_bytes(data[: int(0.6 * len(data))])
    monkeypatch.setitem(sys.modules, "av", None)
    for fps in (None, 5000.0):  # a user's frame rate: seeks cannot be checked, frames are decoded forward
        with gp.open_movie(path, fps=fps) as m:
            assert m.info.n_frames == 120  # the index says so
            np.testing.assert_array_equal(m.read(5), every[5])
            with pytest.raises(MovieError, match=r"truncated|does not decode"):
                m.read(119)
            for k in (0, 10, 3):
                np.testing.assert_array_equal(m.read(k), every[k], err_msg=f"frame {k} after the error")


def test_info_says_how_the_analysis_will_time_the_frames(uneven, capsys):
    """info --json's frame_times follows the analysis: the stamps of an uneven file, index / fps with a given
    rate (it said the file's stamps whenever a video had them)."""
    import json

    from grainplug.cli import main

    for extra, said in (([], "the file's time stamps (unevenly spaced)"), (["--fps", "250"], "frame index / fps")):
        assert main(["info", "--json", str(uneven), *extra]) == 0
        assert json.loads(capsys.readouterr().out)["frame_times"] == said


def test_a_seek_in_a_variable_rate_mp4_before_its_stamps_are_known_gives_the_frame_asked(tmp_path):
    """Before a pass has read the stamps, the OpenCV reader checked a seek by the rate alone: in a variable-rate
    MP4, OpenCV lands on the frame at index / fps, whose stamp passes, and frame 33 came back as frame 32. The
    frame before the one sought must now be one period earlier, else frames are decoded in order."""
    from fractions import Fraction

    import av
    import numpy as np

    from grainplug.readers.cvvideo import OpenCVVideoMovie

    gaps = np.random.default_rng(1).choice([5, 10, 30], size=60)[:-1]
    stamps = np.concatenate([[0], np.cumsum(gaps)]).astype(int)
    path = tmp_path / "vfr.mp4"
    with av.open(str(path), "w") as out:
        stream = out.add_stream("libx264", rate=1000)
        stream.width = stream.height = 64
        stream.pix_fmt = "yuv420p"
        stream.time_base = stream.codec_context.time_base = Fraction(1, 1000)
        stream.options = {"crf": "0", "g": "10", "bf": "0"}
        for k, t in enumerate(stamps):  # frame k is uniformly 4 k grey: its level names it
            vf = av.VideoFrame.from_ndarray(np.full((64, 64, 3), 4 * k, np.uint8), format="rgb24")
            vf.pts, vf.time_base = int(t), Fraction(1, 1000)
            out.mux(stream.encode(vf))
        out.mux(stream.encode())
    wrong = []
    with OpenCVVideoMovie(path) as movie:  # no stamps known: frames reached forward and back by seeking
        for k in (50, 20, 59, 5, 40, 33, 10, 45, 12, 38, 27):
            level = round(float(movie.read(k).mean()) / 4)
            if level != k:
                wrong.append((k, level))
    assert wrong == []
