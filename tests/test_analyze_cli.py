"""`grainplug analyze`: outputs, JSON, provenance, bad input."""

from __future__ import annotations

import csv
import json

import numpy as np
import pandas as pd
import pytest
from test_cli_basics import assert_one_line_error, run
from warned import of_code

from grainplug.summary import EDGE_SCHEMA, TABLES_SCHEMA_VERSION, TRACK_SCHEMA
from grainplug.synthetic import SynthConfig, synthesize


@pytest.fixture(scope="module")
def movie(tmp_path_factory):
    d = tmp_path_factory.mktemp("m")
    return synthesize(SynthConfig(n_frames=200, seed=4, regime="oscillating", celerity_m_s=0.03,
                                  frequency_hz=8.0), d, fmt="avi")


def test_outputs(tmp_path, capsys, movie):
    out = tmp_path / "out"
    code, stdout, err = run(capsys, "analyze", movie.movie, "--out", out, "--json")
    assert code == 0, err
    s = json.loads(stdout)
    for key in ("celerity_m_s", "celerity_ci95_m_s", "plug_length_mm", "plug_length_ci95_mm",
                "plug_length_over_diameter", "bubble_length_mm", "oscillation_frequency_hz",
                "oscillation_amplitude_mm", "regime", "n_plugs", "n_frames", "fps", "mm_per_px",
                "tube_axis_angle_deg", "tube_diameter_px", "grainplug_version", "parameters", "input"):
        assert key in s, key
    assert s["regime"] == "oscillating"
    assert s["input"]["bytes"] == movie.movie.stat().st_size
    assert s["parameters"]["tube_diameter_mm"] == 3.0
    on_disk = json.loads((out / "summary.json").read_text())
    assert on_disk["celerity_m_s"] == s["celerity_m_s"]
    for name in ("plug_edges.csv", "tracks.csv", "diagram.npz", "diagram.png", "spectrum.png",
                 "frame.png", "report.html"):
        assert (out / name).stat().st_size > 0, name
    assert not [p for p in out.iterdir() if p.name.startswith(".grainplug-")]
    with open(out / "plug_edges.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["frame", "movie_frame", "time_s", "plug_id", "top_mm", "bottom_mm"]
    with open(out / "tracks.csv") as fh:
        tracks = list(csv.DictReader(fh))
    assert {"plug_id", "first_frame", "last_frame", "celerity_m_s", "mean_length_mm"} <= set(tracks[0])
    for name, schema in (("plug_edges.csv", EDGE_SCHEMA), ("tracks.csv", TRACK_SCHEMA)):
        table = pd.read_csv(out / name)  # read with no hints: every column in its documented type
        read = {c: "string" if pd.api.types.is_string_dtype(t) else str(t) for c, t in table.dtypes.items()}
        assert read == {c: d for c, (d, _) in schema.items()}, name
    assert on_disk["tables_schema_version"] == TABLES_SCHEMA_VERSION
    z = np.load(out / "diagram.npz")
    assert z["values"].shape == (200, len(z["position_mm"]))
    assert len(z["time_s"]) == 200
    assert "grainplug_version" in json.loads(str(z["provenance"]))


def test_human_output_and_propagative_has_no_spectrum(tmp_path, capsys):
    res = synthesize(SynthConfig(n_frames=120, seed=5), tmp_path / "m", fmt="tiff")
    code, stdout, err = run(capsys, "analyze", res.movie, "--out", tmp_path / "o")
    assert code == 0, err
    assert "celerity" in stdout and "m/s" in stdout and "propagative" in stdout
    assert not (tmp_path / "o" / "spectrum.png").exists()


def test_no_plugs_statement(tmp_path, capsys):
    res = synthesize(SynthConfig(n_frames=60, regime="none", no_plug_fill="compact"), tmp_path / "m")
    code, stdout, err = run(capsys, "analyze", res.movie, "--out", tmp_path / "o", "--json")
    assert code == 0, err
    s = json.loads(stdout)
    assert s["has_plugs"] is False and s["regime"] == "none"
    assert s["celerity_m_s"] is None and s["oscillation_frequency_hz"] is None
    assert "no plugs" in s["statement"]
    page = (tmp_path / "o" / "report.html").read_text()  # the caption does not describe edges that are not drawn
    assert "No plug edge is drawn" in page and "Vermillion" not in page


def test_folder_needs_fps(tmp_path, capsys):
    res = synthesize(SynthConfig(n_frames=30, seed=2, rgb=False), tmp_path / "m", fmt="png")
    code, _, err = run(capsys, "analyze", res.movie, "--out", tmp_path / "o")
    assert_one_line_error(code, err, "--fps")
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())
    code, stdout, err = run(capsys, "analyze", res.movie, "--out", tmp_path / "o", "--fps", 250, "--json")
    assert code == 0, err
    assert json.loads(stdout)["celerity_m_s"] == pytest.approx(-0.05, rel=0.04)


@pytest.mark.parametrize("args,words", [
    (["--mm-per-px", "-1"], ["mm-per-px"]),
    (["--tube-diameter-mm", "0"], ["tube-diameter"]),
    (["--fps", "0"], ["fps"]),
    (["--threads", "0"], ["threads"]),
])
def test_bad_parameters(tmp_path, capsys, movie, args, words):
    code, _, err = run(capsys, "analyze", movie.movie, "--out", tmp_path / "o", *args)
    assert_one_line_error(code, err, *words)


def test_a_typed_scale_takes_the_tubes_diameter_too(tmp_path, capsys, movie):
    """A lab with a 4 mm tube that types its scale gets lambda/D with 4 mm (it was refused, and without the
    flag D = 3 mm was used silently); grainplug.toml takes the pair as well."""
    code, stdout, err = run(capsys, "analyze", movie.movie, "--out", tmp_path / "o", "--mm-per-px", "0.185",
                            "--tube-diameter-mm", "4", "--no-figures", "--json")
    assert code == 0, err
    s = json.loads(stdout)
    assert s["tube_diameter_mm"] == 4.0 and s["mm_per_px"] == pytest.approx(0.185)
    assert s["plug_length_over_diameter"] == pytest.approx(s["plug_length_mm"] / 4.0, rel=1e-3)
    (tmp_path / "grainplug.toml").write_text("[analyze]\nmm_per_px = 0.185\ntube_diameter_mm = 4\n")
    code, stdout, err = run(capsys, "analyze", movie.movie, "--out", tmp_path / "o2", "--config",
                            tmp_path / "grainplug.toml", "--no-figures", "--json")
    assert code == 0, err
    assert json.loads(stdout)["tube_diameter_mm"] == 4.0


def test_missing_and_corrupt(tmp_path, capsys):
    code, _, err = run(capsys, "analyze", tmp_path / "none.avi", "--out", tmp_path / "o")
    assert_one_line_error(code, err, "no such file")
    bad = tmp_path / "bad.mp4"
    bad.write_bytes(b"\x00" * 5000)
    code, _, err = run(capsys, "analyze", bad, "--out", tmp_path / "o")
    assert_one_line_error(code, err, "bad.mp4")


@pytest.mark.parametrize("direction,angle", [("left", 180.0), ("up", -90.0), ("right", 0.0)])
def test_flow_direction_inferred_from_falling_grains(tmp_path, capsys, direction, angle):
    res = synthesize(SynthConfig(n_frames=150, seed=8, flow_direction=direction, celerity_m_s=-0.04),
                     tmp_path / "m")
    code, out, err = run(capsys, "analyze", res.movie, "--out", tmp_path / "o", "--json", "--mm-per-px", 0.185)
    assert code == 0, err
    s = json.loads(out)
    assert s["flow_direction"] == direction
    assert s["flow_direction_source"].startswith("inferred")
    wrapped = (s["tube_axis_angle_deg"] - angle + 180.0) % 360.0 - 180.0
    assert abs(wrapped) < 0.2
    assert s["celerity_m_s"] == pytest.approx(-0.04, rel=0.02)
    assert s["falling_grain_speed_m_s"] == pytest.approx(0.8, rel=0.05)


def test_flow_direction_assumed_without_grains(tmp_path, capsys):
    res = synthesize(SynthConfig(n_frames=120, seed=8, flow_direction="left", falling_grains_per_mm=0.0),
                     tmp_path / "m")
    code, out, err = run(capsys, "analyze", res.movie, "--out", tmp_path / "o", "--json")
    assert code == 0, err
    s = json.loads(out)
    assert s["flow_direction"] == "right" and s["flow_direction_source"] == "assumed"
    [said] = of_code(s, "flow.assumed")
    assert "assumed to run right" in said, s["warnings"]
    code, out, err = run(capsys, "analyze", res.movie, "--out", tmp_path / "o2", "--json", "--flow-direction", "left")
    assert code == 0, err
    s = json.loads(out)
    assert s["flow_direction_source"] == "user" and s["celerity_m_s"] == pytest.approx(-0.05, rel=0.04)


def test_given_direction_against_the_grains_is_flagged(tmp_path, capsys):
    res = synthesize(SynthConfig(n_frames=120, seed=8, flow_direction="up"), tmp_path / "m")
    code, out, err = run(capsys, "analyze", res.movie, "--out", tmp_path / "o", "--json", "--flow-direction", "down")
    assert code == 0, err
    s = json.loads(out)
    assert s["flow_direction"] == "down" and s["warnings"]
    [said] = of_code(s, "flow.against_given")
    assert "direction (down; " in said, s["warnings"]


def test_threads_do_not_change_the_result(tmp_path, capsys):
    res = synthesize(SynthConfig(n_frames=80, seed=9), tmp_path / "m", fmt="tiff")
    out = []
    for n in ("1", "2"):
        code, stdout, err = run(capsys, "analyze", res.movie, "--out", tmp_path / n, "--threads", n, "--json",
                                "--no-figures")
        assert code == 0, err
        out.append(json.loads(stdout))
    assert out[0]["celerity_m_s"] == out[1]["celerity_m_s"]
    assert out[0]["plug_length_mm"] == out[1]["plug_length_mm"]


def test_publication_figures_png_svg_pdf_at_200_dpi(movie, tmp_path, capsys):
    """--publication: every figure as PNG at 200 dpi, SVG and PDF, listed in the summary (by default PNG at
    200 dpi only); --style applies a matplotlib style sheet; bad values are one line."""
    from PIL import Image

    out = tmp_path / "pub"
    style = tmp_path / "journal.mplstyle"
    style.write_text("font.size: 7\naxes.linewidth: 0.5\n")
    code, _, err = run(capsys, "analyze", movie.movie, "--out", out, "--publication", "--style", style)
    assert code == 0, err
    for stem in ("diagram", "frame"):
        for ext in ("png", "svg", "pdf"):
            assert (out / f"{stem}.{ext}").stat().st_size > 1000, (stem, ext)
    assert (out / "diagram.svg").read_text().lstrip().startswith("<?xml")
    assert (out / "diagram.pdf").read_bytes()[:5] == b"%PDF-"
    with Image.open(out / "diagram.png") as im:
        dpi = im.info["dpi"]
    assert round(dpi[0]) == 200
    s = json.loads((out / "summary.json").read_text())
    assert s["figures"] == {"dpi": 200, "formats": ["png", "svg", "pdf"], "style": str(style)}
    assert {"diagram.svg", "diagram.pdf", "frame.pdf"} <= set(s["outputs"].values())
    plain = tmp_path / "plain"
    code, _, err = run(capsys, "analyze", movie.movie, "--out", plain)
    assert code == 0, err
    assert {p.suffix for p in plain.glob("*.*") if p.suffix in (".png", ".svg", ".pdf")} == {".png"}
    with Image.open(plain / "diagram.png") as im:
        assert round(im.info["dpi"][0]) == 200
    code, _, err = run(capsys, "analyze", movie.movie, "--out", tmp_path / "x", "--figure-formats", "png,tiff")
    assert_one_line_error(code, err, "--figure-formats", "tiff")
    code, _, err = run(capsys, "analyze", movie.movie, "--out", tmp_path / "y", "--style", "no-such-style")
    assert_one_line_error(code, err, "--style", "no-such-style")
    code, _, err = run(capsys, "analyze", movie.movie, "--out", tmp_path / "z", "--publication", "--figure-formats",
                       "png")
    assert_one_line_error(code, err, "--publication", "--figure-formats")
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists() and not (tmp_path / "z").exists()


def test_remeasure_redraws_the_figures_as_they_were_written(movie, tmp_path, capsys):
    """remeasure (and the review app's corrections, through it) keeps the run's figure formats, resolution and
    style: it used to rewrite a publication run's figures as PNG at 110 dpi and delete its SVG and PDF."""
    from PIL import Image

    for flags, files, dpi in ((["--figure-formats", "png,pdf", "--dpi", "150"], {"png", "pdf"}, 150),
                              (["--publication"], {"png", "svg", "pdf"}, 200)):
        out = tmp_path / flags[0].strip("-")
        code, _, err = run(capsys, "analyze", movie.movie, "--out", out, *flags)
        assert code == 0, err
        before = json.loads((out / "summary.json").read_text())["figures"]
        code, _, err = run(capsys, "remeasure", out)
        assert code == 0, err
        assert json.loads((out / "summary.json").read_text())["figures"] == before
        assert {p.suffix[1:] for p in out.glob("diagram.*") if p.suffix not in (".npz", ".tif")} == files
        with Image.open(out / "frame.png") as im:
            assert round(im.info["dpi"][0]) == dpi


def test_progress_on_a_terminal_counts_to_the_real_total(tmp_path):
    """In a terminal, the progress bar counts the frames of the window analysed, to their real total."""
    import os
    import pty
    import re
    import subprocess
    import sys

    movie = synthesize(SynthConfig(n_frames=150, seed=3), tmp_path / "m", fmt="tiff").movie
    master, slave = pty.openpty()
    proc = subprocess.Popen([sys.executable, "-m", "grainplug", "analyze", str(movie), "--out", str(tmp_path / "o"),
                             "--start", "20", "--end", "130", "--no-figures"],
                            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=slave,
                            env={**os.environ, "MPLBACKEND": "Agg", "TERM": "xterm", "COLUMNS": "120"})
    os.close(slave)
    seen = bytearray()
    while True:
        try:
            chunk = os.read(master, 1 << 16)
        except OSError:  # the terminal closed with the process
            break
        if not chunk:
            break
        seen += chunk
    os.close(master)
    assert proc.wait(timeout=120) == 0, seen.decode(errors="replace")
    counts = [(int(a), int(b)) for a, b in re.findall(rb"(\d+)/(\d+) frames", bytes(seen))]
    assert counts, seen.decode(errors="replace")
    assert {total for _, total in counts} == {110}  # the window, not the movie's 150
    assert counts[-1] == (110, 110), counts


def test_plugs_filtered_out_by_min_plug_mm_are_not_called_a_single_phase(tmp_path):
    """Two phases seen, every run of grains shorter than --min-plug-mm: the statement says so and names the
    parameter (it used to assert a compact flow)."""
    import grainplug as gp
    from grainplug.synthetic import SynthConfig, synthesize

    movie = synthesize(SynthConfig(n_frames=40, seed=3), tmp_path / "m", fmt="tiff")
    res = gp.analyze(movie.movie, min_plug_mm=500.0)
    assert res.motion is None and "single phase" not in res.statement
    assert "at least 500 mm long" in res.statement and "longer than the" in res.statement
    assert "lower min_plug_mm=" in res.statement and "--" not in res.statement  # the library's words


def test_no_oscillation_has_no_amplitude(tmp_path):
    """A propagative run has no oscillation: its frequency and amplitude are absent (null), not 0."""
    import grainplug as gp
    from grainplug.synthetic import SynthConfig, synthesize

    made = synthesize(SynthConfig(n_frames=100, seed=2, celerity_m_s=-0.05), tmp_path / "m", fmt="tiff")
    s = gp.analyze(made.movie).summary
    assert s["regime"] == "propagative"
    assert s["oscillation_frequency_hz"] is None and s["oscillation_amplitude_mm"] is None
    assert made.truth["oscillation_amplitude_mm"] is None
