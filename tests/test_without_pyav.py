"""The default install holds no PyAV (its wheels bundle an FFmpeg built with the GPL encoders x264
and x265): videos are then read through OpenCV, the overlay is a WebM, and whatever needs PyAV says
how to get it. ``import av`` is made to fail here as it does where PyAV is not installed."""

from __future__ import annotations

import sys

import pytest

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
