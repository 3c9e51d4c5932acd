"""grainplug manifest: a campaign's manifest from a folder of movies' headers, ready for batch."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import pytest

from grainplug.cli import main
from grainplug.synthetic import SynthConfig, synthesize

SAMPLES = Path(__file__).resolve().parents[1].parent / "shared" / "camera-samples"


def _rows(path: Path) -> list[dict[str, str]]:
    text = [line for line in path.read_text().splitlines() if not line.startswith("#")]
    return list(csv.DictReader(text))


@pytest.mark.skipif(not SAMPLES.is_dir(), reason="the real camera samples are not beside the project")
def test_real_camera_files_give_their_saved_frame_rates(tmp_path, capsys):
    """The saved-frame rate, not the record rate: cine_781 records at 90000 fps and saves one in ten; beam records at
    50000 fps and saves one in 2500 (README of the samples). A header whose frames are missing is a comment row."""
    got = {}
    for sub in ("pims", "pyMRAW", "pyidi"):
        out = tmp_path / f"{sub}.csv"
        assert main(["manifest", str(SAMPLES / sub), "--out", str(out)]) == 0
        got.update({r["run"]: r for r in _rows(out)})
        if sub == "pyMRAW":
            assert "# sample_60k_16bit.cih: not read" in out.read_text()
    capsys.readouterr()
    assert float(got["cine_781"]["fps"]) == 9000.0 and float(got["cine_781"]["record_fps"]) == 90000.0
    assert float(got["cine_legacy"]["fps"]) == 35087.0
    assert float(got["data_small_cine"]["fps"]) == 100.0 and got["data_small_cine"]["n_frames"] == "235"
    assert float(got["beam"]["fps"]) == 20.0 and float(got["data_showcase"]["fps"]) == 150.0
    assert got["cine_781"]["trigger_time_utc"].startswith("2019-02-26") and "Phantom" in got["cine_781"]["camera"]
    assert (got["ball_12bit"]["width"], got["ball_12bit"]["height"]) == ("384", "384")
    assert all(r["mass_flow_rate_g_s"] == "" and r["group"] == "" for r in got.values())  # the lab's to fill


def test_a_folder_of_cine_files_runs_as_a_campaign(tmp_path, capsys):
    movies = tmp_path / "movies"
    movies.mkdir()
    for k, fps in enumerate((250.0, 500.0)):
        cfg = SynthConfig(n_frames=80, seed=k, fps=fps, celerity_m_s=-0.05, rgb=False)
        made = synthesize(cfg, tmp_path / f"s{k}", fmt="cine")
        shutil.copy(made.movie, movies / f"run {k}.cine")
    (movies / "notes.txt").write_text("not a movie")
    (movies / "broken.cine").write_bytes(b"\0" * 100)
    assert main(["manifest", str(movies)]) == 0
    printed = capsys.readouterr()
    manifest = movies / "manifest.csv"
    text = manifest.read_text()
    assert "# broken.cine: not read" in text and "notes.txt" not in text
    rows = _rows(manifest)
    assert [(r["run"], float(r["fps"])) for r in rows] == [("run_0", 250.0), ("run_1", 500.0)]
    assert "1 not read" in printed.out
    # an existing manifest is kept unless --force
    assert main(["manifest", str(movies)]) != 0
    assert "exists" in capsys.readouterr().err and manifest.read_text() == text
    # batch reads it (the comment row skipped, the header's columns kept as metadata, none taken for a misspelling)
    out = tmp_path / "campaign"
    assert main(["batch", str(manifest), "--out", str(out), "--no-figures"]) == 0, capsys.readouterr().err
    err = capsys.readouterr().err
    assert "column" not in err
    table = list(csv.DictReader((out / "campaign.csv").read_text().splitlines()))
    assert [r["run"] for r in table] == ["run_0", "run_1"] and all(r["status"] == "ok" for r in table)


def test_no_movie_is_one_line(tmp_path, capsys):
    assert main(["manifest", str(tmp_path)]) != 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "holds no file" in err


def test_movies_in_subfolders_keep_their_subfolder_and_the_batch_finds_them(tmp_path, capsys):
    """`--glob '*/*'` over a campaign kept one run a folder: every movie was listed by its file name alone (all three
    `movie.cine`, at the manifest's folder), so the batch found none. Their paths keep their subfolder, and so do
    their run names; a manifest written elsewhere points at them too."""
    camp = tmp_path / "camp"
    for k in range(3):
        made = synthesize(SynthConfig(n_frames=60, seed=k, fps=250.0, rgb=False), tmp_path / f"m{k}", fmt="cine")
        (camp / f"s{k}").mkdir(parents=True)
        shutil.copy(made.movie, camp / f"s{k}" / "movie.cine")
    for target in (camp / "manifest.csv", tmp_path / "elsewhere" / "m.csv"):
        target.parent.mkdir(exist_ok=True)
        assert main(["manifest", str(camp), "--glob", "*/*", "--out", str(target)]) == 0
        rows = _rows(target)
        assert [r["run"] for r in rows] == ["s0_movie", "s1_movie", "s2_movie"]
        assert all((target.parent / r["movie"]).resolve() == (camp / f"s{k}" / "movie.cine").resolve()
                   for k, r in enumerate(rows))
    capsys.readouterr()
    out = tmp_path / "campaign"
    assert main(["batch", str(camp / "manifest.csv"), "--out", str(out), "--no-figures"]) == 0, \
        capsys.readouterr().err
    table = list(csv.DictReader((out / "campaign.csv").read_text().splitlines()))
    assert [r["status"] for r in table] == ["ok"] * 3
