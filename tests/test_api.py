"""The public Python API: what a researcher does in a notebook, by behaviour."""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import grainplug as gp
from grainplug.synthetic import SynthConfig, synthesize

SRC = Path(gp.__file__).resolve().parent


@pytest.fixture(scope="module")
def movie(tmp_path_factory):
    """A short lossless movie (TIFF) with known truth."""
    return synthesize(SynthConfig(n_frames=120, seed=3, fps=250.0), tmp_path_factory.mktemp("m"), fmt="tiff")


@pytest.fixture(scope="module")
def result(movie):
    return gp.analyze(movie.movie)


def assert_same(a, b, where="result"):
    """Field-by-field equality of results (arrays exactly, NaN equal to NaN)."""
    if dataclasses.is_dataclass(a):
        assert type(a) is type(b), where
        for f in dataclasses.fields(a):
            assert_same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.dtype == b.dtype, where
        np.testing.assert_array_equal(a, b, err_msg=where)
    elif isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for k in a:
            assert_same(a[k], b[k], f"{where}[{k!r}]")
    elif isinstance(a, (list, tuple)):
        assert type(a) is type(b) and len(a) == len(b), where
        for k, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same(x, y, f"{where}[{k}]")
    elif isinstance(a, float) and np.isnan(a):
        assert isinstance(b, float) and np.isnan(b), where
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


def test_import_is_light_and_exposes_the_api():
    code = ("import sys, grainplug as gp; heavy = [m for m in ('numpy', 'scipy', 'matplotlib', 'pandas', 'av') "
            "if m in sys.modules]; print(gp.__version__, heavy)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out[0] == gp.__version__ and out[1] == "[]"
    for name in gp.__all__:
        assert getattr(gp, name) is not None, name
    assert callable(gp.analyze) and callable(gp.load_result) and callable(gp.open_movie)
    with pytest.raises(AttributeError):
        gp.no_such_thing  # noqa: B018
    # the subpackages the docs point to, without importing them first; dir() lists the API, not the module's imports
    assert gp.campaigns.manifest.read_manifest and gp.calibration and gp.errors.GrainplugError is gp.GrainplugError
    assert {"analyze", "campaigns", "calibration"} <= set(dir(gp)) and not {"importlib", "TYPE_CHECKING"} & set(dir(gp))


def test_analyze_takes_a_path_an_open_movie_or_frames_in_memory(movie, result):
    with gp.open_movie(movie.movie) as m:
        frames = np.stack(list(m.frames()))
        from_movie = gp.analyze(m)
        assert m.read(0).shape == frames.shape[1:]  # a movie passed in is left open
    from_array = gp.analyze(frames, fps=250.0)
    # the same pixels give the same numbers, whatever carried them
    for other in (from_movie, from_array):
        np.testing.assert_array_equal(other.diagram.values, result.diagram.values)
        assert other.celerity_m_s == result.celerity_m_s
        assert other.plug_length_mm == result.plug_length_mm
    assert from_array.input["kind"] == "array" and from_array.input["shape"] == list(frames.shape)
    truth = movie.truth
    assert result.celerity_m_s == pytest.approx(truth["celerity_m_s"], rel=0.04)


def test_analyze_takes_dask_arrays_and_overrides(movie, result):
    da = pytest.importorskip("dask.array")
    with gp.open_movie(movie.movie) as m:
        frames = np.stack(list(m.frames()))
    lazy = da.from_array(frames, chunks=(7, -1, -1, -1))
    res = gp.analyze(lazy, fps=250.0, mm_per_px=movie.truth["mm_per_px"], min_plug_mm=4.0)
    assert res.params.min_plug_mm == 4.0 and res.scale_source == "user"
    np.testing.assert_allclose(res.diagram.values, result.diagram.values)


def test_missing_frame_rate_and_bad_parameters_name_the_parameter(movie):
    frames = np.zeros((20, 64, 32), np.uint8)
    with pytest.raises(gp.ParameterError) as err:
        gp.analyze(frames)
    assert err.value.param == "fps" and "frame rate" in str(err.value)
    with pytest.raises(gp.ParameterError) as err:
        gp.analyze(movie.movie, min_plug_mm=-1)
    assert err.value.param == "min_plug_mm" and "--" not in str(err.value)
    with pytest.raises(gp.ParameterError) as err:
        gp.analyze(movie.movie, min_plug_m=3)  # a typo is named, with the right names
    assert "min_plug_mm" in str(err.value)
    with pytest.raises(gp.MovieError):
        gp.analyze(np.zeros((20, 64), np.uint8), fps=100)


def test_a_students_slips_are_refused_in_one_line_or_taken_as_meant(movie, result):
    """What a notebook user types by mistake: one clear error naming the parameter (never a deep numpy or
    attribute error), or the value taken as meant where it can only mean one thing."""
    from decimal import Decimal

    with gp.open_movie(movie.movie) as m:
        frames = np.stack(list(m.frames(0, 30)))
    refused = [
        (lambda: gp.analyze(frames, fps="250"), "fps: must be a number"),
        (lambda: gp.analyze(frames[0], fps=250), "one colour frame, not a movie"),
        (lambda: gp.analyze([frames[0], frames[1][:-1], *frames[2:]], fps=250), "not all the same size"),
        (lambda: gp.analyze((frames.mean(-1) - 128).astype(np.int8), fps=250), "hold negative values"),
        (lambda: gp.analyze(["a.png", "b.png"]), "give the folder"),
        (lambda: gp.analyze(frames, fps=250, threads="4"), "threads: give a whole number"),
        (lambda: gp.analyze(movie.movie, [1]), "must be an AnalysisParams"),
        (lambda: gp.AnalysisParams(calibration="cal.json"), "must be a Calibration"),
        (lambda: gp.AnalysisParams(roi=(0, 0, 128)), "four whole pixel numbers"),
        (lambda: gp.AnalysisParams(start_frame=True), "must be a frame number"),
    ]
    for call, needle in refused:
        with pytest.raises(gp.GrainplugError, match=needle):
            call()
    # numbers in another dress, and parameters as a dict, are what they say
    p = gp.AnalysisParams(fps=np.array(250.0), mm_per_px=Decimal("0.185"), sample_frames=32.0,
                          roi=np.array([0, 0, 128, 640]))
    assert (p.fps, p.mm_per_px, p.sample_frames, p.roi) == (250.0, 0.185, 32, (0, 0, 128, 640))
    assert type(p.sample_frames) is int and type(p.fps) is float
    assert gp.analyze(movie.movie, {"fps": 250.0}).summary["celerity_m_s"] == result.summary["celerity_m_s"]
    assert gp.AnalysisParams(start_frame=5.0, end_frame=np.float64(20)).start_frame == 5
    with pytest.raises(gp.ParameterError, match="mm_per_px: must be a number"):
        gp.AnalysisParams(mm_per_px=Decimal("sNaN"))
    # grey levels as Python ints (int64) or .astype(int) are the unsigned levels they fit
    as_ints = gp.analyze([f.tolist() for f in frames[:20]], fps=250, mm_per_px=0.185)
    assert as_ints.info.dtype == "uint8"
    assert as_ints.summary["celerity_m_s"] == gp.analyze(frames[:20], fps=250, mm_per_px=0.185).summary[
        "celerity_m_s"]


def test_an_empty_track_table_keeps_the_columns_types(tmp_path, result):
    """A run without plugs has no tracks; its empty table has the columns' types, so that concatenating runs'
    tables keeps float celerities (it was object in every column)."""
    none = synthesize(SynthConfig(n_frames=40, seed=1, regime="none"), tmp_path, fmt="tiff")
    empty = gp.analyze(none.movie).tracks
    assert len(empty) == 0
    assert dict(empty.dtypes) == dict(result.tracks.dtypes)
    assert empty.celerity_m_s.dtype == np.float64


def test_result_tables(result):
    e, t, p, b = result.edges, result.tracks, result.plugs, result.bubbles
    assert list(e.columns) == ["frame", "movie_frame", "time_s", "plug_id", "top_mm", "bottom_mm"]
    assert len(e) == len(result.runs) and e.time_s.is_monotonic_increasing
    assert len(t) == len(result.links) and set(e.plug_id) == set(t.plug_id)
    # the lengths that make the means
    assert p.length_mm.mean() == pytest.approx(result.plug_length_mm)
    assert len(p) == result.summary["n_plugs"]
    assert b.length_mm.mean() == pytest.approx(result.summary["bubble_length_mm"], abs=1e-4)
    assert (b.upstream_plug_id != b.downstream_plug_id).all()
    d = result.to_xarray()
    assert d.dims == ("time_s", "position_mm") and d.shape == result.diagram.values.shape
    assert d.attrs["mm_per_px"] == result.mm_per_px
    z = result.to_xarray(contrast=True)
    assert float(z.quantile(0.9)) > 0.5 > float(z.quantile(0.1))  # plugs near 1, bubbles near 0


def test_result_displays_briefly(result):
    text = repr(result)
    assert len(text.splitlines()) <= 6 and len(text) < 800
    assert f"{result.celerity_m_s:+.4f}" in text
    page = result._repr_html_()
    assert "celerity" in page and "data:image/png;base64," in page and len(page) < 200_000
    from grainplug.warning_codes import coded

    warned = dataclasses.replace(result, warnings=[coded("scale.model_alone", "check the scale")])
    assert "warning: check the scale" in repr(warned) and "<li>check the scale</li>" in warned._repr_html_()
    assert "CodedWarning" not in repr(warned) + warned._repr_html_()  # the sentence, not the object
    # its parts print their numbers, not their arrays; the headline numbers are attributes
    assert len(repr(result.motion)) < 600 and "celerity_m_s" in repr(result.motion)
    assert result.regime == result.motion.regime and result.bubble_length_mm == result.lengths.bubble_length_mm


def test_plot_draws_into_given_axes(result):
    from matplotlib.figure import Figure

    fig = Figure()
    ax = fig.subplots()
    assert result.plot(ax=ax) is ax
    assert ax.images and ax.get_xlabel() == "time t (s)"
    assert any("celerity" in line.get_label() for line in ax.lines)


def test_save_and_load_round_trip(result, tmp_path):
    written = result.save(tmp_path / "run", figures=False, report=False)
    assert {"summary", "edges", "tracks", "diagram", "result"} <= set(written)  # the keys of summary.json's outputs
    again = gp.load_result(tmp_path / "run")
    assert_same(result, again)
    assert again.summary == result.summary
    assert again.tracks.equals(result.tracks) and again.edges.equals(result.edges)


def test_load_result_says_what_is_wrong(tmp_path):
    with pytest.raises(gp.GrainplugError, match=r"result\.save"):
        gp.load_result(tmp_path)
    (tmp_path / "result.npz").write_bytes(b"not a zip")
    with pytest.raises(gp.GrainplugError, match="not a grainplug result"):
        gp.load_result(tmp_path)


def test_failed_save_leaves_previous_results_intact(result, tmp_path, monkeypatch):
    out = tmp_path / "run"
    result.save(out, figures=False, report=False)
    before = {f.name: f.read_bytes() for f in out.iterdir()}

    def broken(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr("grainplug.outputs.write_result", broken)
    with pytest.raises(OSError, match="disk full"):
        result.save(out, figures=False, report=False)
    assert {f.name: f.read_bytes() for f in out.iterdir()} == before  # nothing half-written, nothing lost


def test_no_global_state_in_the_library():
    """No registry, argv pre-scan, environment edits, backend choice at import, or fork."""
    patterns = {
        r"os\.fork\(": "fork",
        r"_registry": "module-level registry",
        r"os\.environ\[[^]]+\]\s*=|os\.environ\.setdefault|os\.putenv": "environment edit",
        r"matplotlib\.use\(": "backend chosen by the library",
        r"daemon=True": "daemon thread",
    }
    found = []
    for path in SRC.rglob("*.py"):
        text = path.read_text()
        for pattern, what in patterns.items():
            if re.search(pattern, text):
                found.append(f"{path.relative_to(SRC)}: {what}")
        if "sys.argv" in text and path.name not in ("__init__.py", "demo.py", "__main__.py"):
            found.append(f"{path.relative_to(SRC)}: reads sys.argv")
    assert not found, found


def test_an_open_movie_is_not_changed_by_the_analysis(movie):
    with gp.open_movie(movie.movie) as m:
        before = m.info
        res = gp.analyze(m, fps=500.0)
        assert m.info == before  # the caller's movie keeps its own frame rate
    assert res.info.fps == 500.0 and res.info.fps_source == "user"
    assert res.diagram.time_s[1] == pytest.approx(1 / 500.0)


def test_a_movie_filmed_upside_down_gives_the_same_plugs(movie, result):
    """The flow direction is applied once, after streaming: turning the camera over and saying
    the flow runs up gives the same positions along the flow, celerity and lengths."""
    with gp.open_movie(movie.movie) as m:
        frames = np.stack(list(m.frames()))
    scale = movie.truth["mm_per_px"]
    down = gp.analyze(frames, fps=250.0, mm_per_px=scale, flow_direction="down")
    up = gp.analyze(np.ascontiguousarray(frames[:, ::-1]), fps=250.0, mm_per_px=scale, flow_direction="up")
    assert up.flow_direction == "up" and not up.warnings
    assert up.diagram.values.shape == down.diagram.values.shape
    np.testing.assert_allclose(up.diagram.position_mm, down.diagram.position_mm, atol=0.5 * scale)
    assert np.corrcoef(up.diagram.values.ravel(), down.diagram.values.ravel())[0, 1] > 0.999
    assert up.celerity_m_s == pytest.approx(down.celerity_m_s, rel=0.005)
    assert up.plug_length_mm == pytest.approx(down.plug_length_mm, rel=0.005)
    assert up.summary["tube_axis_angle_deg"] == pytest.approx(-90.0, abs=1.0)


def test_a_celerity_that_rounds_to_zero_has_no_sign():
    """A static run's repr and figure title read 0.0000, not -0.0000."""
    from grainplug._format import signed

    assert [signed(v, 4) for v in (-1e-6, 0.0, 2e-5, -0.05, 0.05109)] == ["0.0000", "0.0000", "0.0000", "-0.0500",
                                                                           "+0.0511"]
