"""Hostile input, second battery: the 36 command lines of the independent tester's 690 that were not clean.

Each case failed on the code before its fix: a user's file deleted, a write into ``/`` or into a folder of the
user's files, a crash instead of one line, a huge job started without a check, a silently wrong result, or a
stderr line that is neither ``error:`` nor ``warning:``. Most run the command line as a user does
(``python -m grainplug``): exit status, exactly one ``error:`` line, nothing written or changed.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import tifffile

import grainplug as gp
from grainplug.synthetic import SynthConfig
from grainplug.synthetic.render import Renderer

SRC = str(Path(gp.__file__).resolve().parents[1])


def gp_run(*args: object, cwd: Path | None = None, timeout: float = 120) -> tuple[int, str, str]:
    """``python -m grainplug ARGS`` in a child process: exit status, stdout, stderr."""
    env = {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", ""), "MPLBACKEND": "Agg"}
    p = subprocess.run([sys.executable, "-m", "grainplug", *map(str, args)], capture_output=True, text=True,
                       cwd=cwd, env=env, timeout=timeout)
    return p.returncode, p.stdout, p.stderr


def one_error(err: str, *words: str) -> None:
    """Exactly one line on stderr, ``error: ...``, naming ``words``; no traceback, no internal error."""
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "report it" not in err and "Traceback" not in err, err
    for w in words:
        assert w in lines[0], err


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (hidden ones too) with its bytes."""
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def frames() -> np.ndarray:
    return np.stack(list(Renderer(SynthConfig(n_frames=60, width_px=64, height_px=300, seed=1, rgb=False)).frames()))


@pytest.fixture
def movie(tmp_path, frames) -> Path:
    p = tmp_path / "movies" / "movie.tif"
    p.parent.mkdir()
    tifffile.imwrite(p, frames, metadata={"fps": 250.0})
    return p


@pytest.fixture
def manifest(movie) -> Path:
    m = movie.parent / "m.csv"
    m.write_text("run,movie\nr1,movie.tif\n")
    return m


# -- 1. data loss: a user's folder taken for grainplug's (rows 1-6) -----------------------------
def _campaign_with_notes(out: Path, marker: str) -> None:
    out.mkdir()
    (out / "campaign.csv").write_text("run,celerity_m_s\nr1,-0.05\n")
    (out / "runs").mkdir()
    (out / "notes.txt").write_text("what I saw")
    if marker == "empty":  # what batch wrote before it listed its files
        (out / ".grainplug").write_text("")
    else:
        (out / ".grainplug").write_text(json.dumps({"kind": "campaign", "files": {"campaign.csv": 30}}))


@pytest.mark.parametrize("marker", ["empty", "listed"])
@pytest.mark.parametrize("command", ["analyze", "paper", "simulate"])
def test_a_campaign_folder_is_never_replaced_whole(tmp_path, movie, command, marker):
    out = tmp_path / "camp"
    _campaign_with_notes(out, marker)
    before = snapshot(out)
    args = {"analyze": ["analyze", movie, "--out", out, "--no-figures"],
            "paper": ["paper", "--out", out, "--no-figures", "--no-simulations"],
            "simulate": ["simulate", "--out", out, "--cells", 64, "--duration-tc", 5]}[command]
    code, _, err = gp_run(*args, "--overwrite")
    assert code == 2
    one_error(err, "campaign's folder")
    assert snapshot(out) == before


@pytest.mark.parametrize(("files", "command"), [
    ({"summary.json": "{}\n"}, "analyze"),  # a user's own summary.json
    ({"campaign.csv": "a,b\n"}, "paper"),  # a user's own campaign.csv
    ({".grainplug": ""}, "analyze"),  # an empty marker
    ({".grainplug": "not json"}, "simulate"),  # a marker of the first versions, or garbage
])
def test_a_user_folder_with_a_file_of_grainplug_s_name_is_refused(tmp_path, movie, files, command):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("what I saw")
    for name, text in files.items():
        (out / name).write_text(text)
    before = snapshot(out)
    args = {"analyze": ["analyze", movie, "--out", out, "--no-figures"],
            "paper": ["paper", "--out", out, "--no-figures", "--no-simulations"],
            "simulate": ["simulate", "--out", out, "--cells", 64, "--duration-tc", 5]}[command]
    code, _, err = gp_run(*args, "--overwrite")
    assert code == 2
    one_error(err)
    assert "notes.txt" in err or "did not write" in err or "campaign" in err, err
    assert snapshot(out) == before


def test_an_output_of_another_kind_is_not_replaced(tmp_path, movie):
    out = tmp_path / "a"
    assert gp_run("analyze", movie, "--out", out, "--no-figures")[0] == 0
    assert json.loads((out / ".grainplug").read_text())["kind"] == "analysis"
    before = snapshot(out)
    code, _, err = gp_run("simulate", "--out", out, "--cells", 64, "--duration-tc", 5, "--overwrite")
    assert code == 2
    one_error(err, "holds a grainplug analysis, not a simulation")
    assert snapshot(out) == before


def test_an_old_analysis_folder_without_a_file_list(tmp_path, movie):
    """Folders of the first versions (a one-line marker, no list): replaced when they hold only what an
    analysis writes, refused when they hold anything else."""
    out = tmp_path / "old"
    assert gp_run("analyze", movie, "--out", out, "--no-figures")[0] == 0
    (out / ".grainplug").write_text("grainplug output folder: replaced whole by each run\n")
    (out / "notes.txt").write_text("what I saw")
    code, _, err = gp_run("analyze", movie, "--out", out, "--no-figures", "--overwrite")
    assert code == 2
    one_error(err, "notes.txt")
    assert (out / "notes.txt").read_text() == "what I saw"
    (out / "notes.txt").unlink()
    assert gp_run("analyze", movie, "--out", out, "--no-figures", "--overwrite")[0] == 0
    assert json.loads((out / ".grainplug").read_text())["kind"] == "analysis"


def test_batch_lists_what_it_wrote_and_refuses_places_not_its_own(tmp_path, movie, manifest):
    camp = tmp_path / "camp"
    code, _, err = gp_run("batch", manifest, "--out", camp, "--no-figures", "--no-simulations")
    assert code == 0, err
    seal = json.loads((camp / ".grainplug").read_text())
    assert seal["kind"] == "campaign" and "campaign.csv" in seal["files"]
    (camp / "notes.txt").write_text("what I saw")  # a user's notes in a campaign's folder: kept by a rerun
    assert gp_run("batch", manifest, "--out", camp, "--no-figures", "--no-simulations")[0] == 0
    assert (camp / "notes.txt").read_text() == "what I saw"
    # rows 12-14: a folder of the user's files, the movies' folder, an analysis's folder
    user = tmp_path / "user"
    user.mkdir()
    (user / "notes.txt").write_text("mine")
    ana = tmp_path / "ana"
    assert gp_run("analyze", movie, "--out", ana, "--no-figures")[0] == 0
    for place, words in [(user, "did not write (notes.txt"), (movie.parent, "did not write"),
                         (ana, "holds a grainplug analysis, not a campaign")]:
        before = snapshot(place)
        code, _, err = gp_run("batch", manifest, "--out", place, "--no-figures", "--no-simulations")
        assert code == 2
        one_error(err, words)
        assert snapshot(place) == before


# -- 2. places that are not the user's output folder (rows 7-14) -------------------------------
@pytest.mark.parametrize("command", ["synth", "batch", "analyze", "simulate"])
def test_the_file_system_root_is_refused(tmp_path, movie, manifest, command):
    args = {"synth": ["synth", "--frames", 10], "batch": ["batch", manifest, "--no-figures"],
            "analyze": ["analyze", movie, "--overwrite"], "simulate": ["simulate", "--overwrite"]}[command]
    before = sorted(os.listdir("/"))
    code, _, err = gp_run(*args, "--out", "/")
    assert code == 2
    one_error(err, "system folder")
    assert sorted(os.listdir("/")) == before


def test_synth_refuses_a_folder_not_its_own_and_replaces_its_own_with_overwrite(tmp_path):
    user = tmp_path / "user"
    user.mkdir()
    (user / "notes.txt").write_text("mine")
    (user / "movie.tif").write_bytes(b"the user's own movie")
    before = snapshot(user)
    for extra in ([], ["--overwrite"]):
        code, _, err = gp_run("synth", "--out", user, "--frames", 10, *extra)
        assert code == 2
        one_error(err)
        assert snapshot(user) == before
    out = tmp_path / "syn"
    assert gp_run("synth", "--out", out, "--frames", 10)[0] == 0
    first = snapshot(out)
    assert json.loads(first[".grainplug"])["kind"] == "synthetic"
    code, _, err = gp_run("synth", "--out", out, "--frames", 10, "--seed", 3)  # not without asking
    assert code == 2
    one_error(err, "already exists — pass --overwrite")
    assert snapshot(out) == first
    code, _, err = gp_run("synth", "--out", out, "--frames", 10, "--seed", 3, "--format", "png", "--overwrite")
    assert code == 0, err
    assert not (out / "movie.tif").exists() and (out / "movie_frames").is_dir()  # replaced whole
