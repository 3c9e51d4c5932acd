"""grainplug.toml: a lab's settings for analyze, beside the movie or with --config; the command line wins."""

from __future__ import annotations

import json
import shutil

import pytest

from grainplug.cli import main
from grainplug.synthetic import SynthConfig, synthesize


@pytest.fixture(scope="module")
def movie(tmp_path_factory):
    d = tmp_path_factory.mktemp("cfg")
    return synthesize(SynthConfig(n_frames=120, seed=4, noise_sigma=2), d / "run", fmt="tiff").movie


def beside(movie, folder, settings: str):
    """A copy of ``movie`` in ``folder`` with a ``grainplug.toml`` of ``settings``; its path."""
    folder.mkdir()
    local = folder / movie.name
    shutil.copy(movie, local)
    (folder / "grainplug.toml").write_text(settings)
    return local


def analyze(capsys, *args):
    code = main(["analyze", *map(str, args), "--no-figures", "--json"])
    out, err = capsys.readouterr()
    return code, (json.loads(out) if code == 0 else None), err


def test_settings_beside_the_movie_and_the_command_line_wins(movie, tmp_path, capsys):
    local = beside(movie, tmp_path / "day1", '[analyze]\nmm-per-px = 0.2\nstart = "20"\nmin_plug_mm = 4.0\n')
    code, s, err = analyze(capsys, local, "--out", tmp_path / "a")
    assert code == 0, err
    assert s["mm_per_px"] == 0.2 and s["n_frames"] == 100 and s["parameters"]["min_plug_mm"] == 4.0
    assert "settings from" in err and "grainplug.toml" in err
    code, s, err = analyze(capsys, local, "--out", tmp_path / "b", "--mm-per-px", "0.18", "--start", "0")
    assert code == 0 and s["mm_per_px"] == 0.18 and s["n_frames"] == 120


def test_explicit_settings_file_with_a_relative_path(movie, tmp_path, capsys):
    (tmp_path / "lab").mkdir()
    (tmp_path / "lab" / "settings.toml").write_text('[analyze]\ncalibration = "missing/day1.json"\n')
    code, _, err = analyze(capsys, movie, "--out", tmp_path / "o", "--config", tmp_path / "lab" / "settings.toml")
    # the path is taken relative to the settings file, and its absence said in one line
    assert code == 2 and str(tmp_path / "lab" / "missing" / "day1.json") in err and len(err.splitlines()) == 1


@pytest.mark.parametrize("text,words", [("[analyze\nfps = 3", "not a readable TOML"),
                                        ("[analyze]\nfpss = 3\n", "unknown setting 'fpss'"),
                                        ("[analyze]\nfps = 'fast'\n", "fps: Invalid value for '--fps'"),
                                        ("[analyze]\nfps = 1e12\n", "must be between 1 and 1e+07"),
                                        ("analyze = 3\n", "must be a table")])
def test_bad_settings_are_one_line(movie, tmp_path, capsys, text, words):
    cfg = tmp_path / "bad.toml"
    cfg.write_text(text)
    code, _, err = analyze(capsys, movie, "--out", tmp_path / "o", "--config", cfg)
    assert code == 2 and words in err and str(cfg) in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "o").exists()
    code, _, err = analyze(capsys, movie, "--out", tmp_path / "o", "--config", tmp_path / "none.toml")
    assert code == 2 and "no such settings file" in err


def test_a_lab_keeps_publication_figures_on_in_its_settings(movie, tmp_path, capsys):
    """publication = true in grainplug.toml: every figure also as SVG and PDF, as --publication does."""
    local = beside(movie, tmp_path / "lab", "[analyze]\npublication = true\n")
    assert main(["analyze", str(local), "--out", str(tmp_path / "o"), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["figures"]["formats"] == ["png", "svg", "pdf"]
    assert {p.suffix for p in (tmp_path / "o").glob("diagram.*")} == {".npz", ".tif", ".png", ".svg", ".pdf"}


def test_a_style_sheet_beside_the_settings_is_found_from_anywhere(movie, tmp_path, capsys, monkeypatch):
    """style = "paper.mplstyle" in grainplug.toml is the sheet beside that file (it was looked for in the
    working directory, and refused as '--style'); it is recorded as a full path, so that remeasure, run from
    another directory, draws the figures with it again (it silently dropped it)."""
    folder = tmp_path / "lab"
    local = beside(movie, folder, '[analyze]\nstyle = "paper.mplstyle"\n')
    (folder / "paper.mplstyle").write_text("font.family: serif\nfont.size: 7\n")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    out = tmp_path / "o"
    assert main(["analyze", str(local), "--out", str(out)]) == 0, capsys.readouterr().err
    style = json.loads((out / "summary.json").read_text())["figures"]["style"]
    assert style == str(folder / "paper.mplstyle")
    monkeypatch.chdir(tmp_path)
    assert main(["remeasure", str(out)]) == 0
    assert json.loads((out / "summary.json").read_text())["figures"]["style"] == style


def test_a_relative_style_path_is_recorded_in_full(movie, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.mplstyle").write_text("font.size: 7\n")
    assert main(["analyze", str(movie), "--out", "o", "--style", "mine.mplstyle"]) == 0
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["figures"]["style"] == str(
        tmp_path / "mine.mplstyle")


def test_the_command_line_s_figure_formats_win_over_publication_in_the_settings(movie, tmp_path, capsys):
    """publication = true in grainplug.toml and --figure-formats on the command line: the command line wins (it
    was refused as giving both); the other way round too."""
    local = beside(movie, tmp_path / "lab", "[analyze]\npublication = true\n")
    assert main(["analyze", str(local), "--out", str(tmp_path / "a"), "--figure-formats", "png", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["figures"]["formats"] == ["png"]
    (tmp_path / "lab" / "grainplug.toml").write_text('[analyze]\nfigure_formats = "svg"\n')
    assert main(["analyze", str(local), "--out", str(tmp_path / "b"), "--publication", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["figures"]["formats"] == ["png", "svg", "pdf"]
