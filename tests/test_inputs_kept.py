"""No output ever overwrites an input, and only grainplug speaks on stderr (issue 31).

Each command that writes is tried with outputs that resolve to one of its inputs, by the same
path, a symbolic link or a hard link, with the defaults a new user types: it must refuse in one
line before anything is written, and the input must be byte for byte what it was. Commands with
no input file (``stability --plot``, ``simulate``, ``paper``, ``synth``) have nothing to write
over; ``remeasure`` and ``review`` rewrite their own folder by design.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import tifffile
from PIL import Image

import grainplug as gp
from grainplug._atomic import OutputPlaceError
from grainplug.calibration_files import draw_calibration
from grainplug.synthetic import SynthConfig
from grainplug.synthetic.render import Renderer


def cli(*args: object, cwd: Path | None = None) -> subprocess.CompletedProcess:
    """The command line as a user runs it: a process of its own (its stderr is all the user sees)."""
    return subprocess.run([sys.executable, "-m", "grainplug", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=300)


def one_error_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "unexpected" not in err and "Traceback" not in err, err
    return lines[0]


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def frames() -> np.ndarray:
    return np.stack(list(Renderer(SynthConfig(n_frames=60, width_px=64, height_px=300, seed=3, rgb=False)).frames()))


@pytest.fixture
def movie(tmp_path, frames) -> Path:
    p = tmp_path / "movie.tif"
    tifffile.imwrite(p, frames, metadata={"fps": 250.0})
    return p


def checkerboard(path: Path, square_px: int = 20) -> Path:
    board = np.kron(np.indices((12, 16)).sum(0) % 2, np.ones((square_px, square_px))) * 200 + 30
    noise = np.random.default_rng(0).normal(0, 3, board.shape)
    Image.fromarray(np.clip(board + noise, 0, 255).astype(np.uint8)).save(path)
    return path


# -- calibrate ---------------------------------------------------------------------------------
def test_calibrate_with_every_default_keeps_the_photo_and_reads_the_same_again(tmp_path):
    photo = checkerboard(tmp_path / "calibration.png")  # the name a lab gives it, beside the default --out
    before = digest(photo)
    first = cli("calibrate", "calibration.png", "--pitch-mm", "2", "--json", cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    assert digest(photo) == before
    assert (tmp_path / "calibration.json").is_file() and (tmp_path / "calibration_points.png").is_file()
    again = cli("calibrate", "calibration.png", "--pitch-mm", "2", "--out", "again.json", "--json", cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    scale = [gp.load_calibration(tmp_path / n).mm_per_px for n in ("calibration.json", "again.json")]
    assert scale[0] == pytest.approx(0.1, rel=1e-3) and scale[1] == scale[0]


@pytest.mark.parametrize("how", ["same name", "symbolic link", "hard link"])
def test_calibrate_refuses_to_write_its_figure_or_file_over_the_photo(tmp_path, how):
    photo = checkerboard(tmp_path / "board.png")
    before = digest(photo)
    if how == "same name":  # the photo is named as calibrate would name its figure
        photo = photo.rename(tmp_path / "scale_points.png")
    elif how == "symbolic link":
        (tmp_path / "scale_points.png").symlink_to(photo)
    else:
        os.link(photo, tmp_path / "scale_points.png")
    r = cli("calibrate", photo.name, "--pitch-mm", "2", "--out", "scale.json", cwd=tmp_path)
    assert r.returncode == 2
    assert "would be written over the input" in one_error_line(r.stderr)
    assert digest(photo) == before and not (tmp_path / "scale.json").exists()


def test_the_library_never_saves_a_calibration_over_its_image(tmp_path):
    photo = checkerboard(tmp_path / "board.png")
    cal = gp.calibrate_file(photo, pitch_mm=2)
    before = digest(photo)
    with pytest.raises(OutputPlaceError):
        gp.save_calibration(cal, photo)
    with pytest.raises(OutputPlaceError):
        draw_calibration(np.zeros((10, 10)), cal, photo)
    assert digest(photo) == before


# -- analyze -------------------------------------------------------------------------------------
@pytest.mark.parametrize("which", ["--calibration", "--background", "--config"])
def test_analyze_refuses_an_output_folder_that_holds_or_is_one_of_its_inputs(tmp_path, movie, which):
    folder = tmp_path / "results"
    folder.mkdir()
    name = {"--calibration": "calibration.json", "--background": "empty.png", "--config": "grainplug.toml"}[which]
    given = folder / name
    given.write_bytes(b"{}" if name.endswith(".json") else b"fps = 250\n" if name.endswith(".toml") else b"x")
    before = digest(given)
    for out, words in ((folder, "holds the input"), (given, "is the input itself")):
        r = cli("analyze", movie, "--out", out, which, given, "--overwrite", "--no-figures")
        assert r.returncode == 2
        assert words in one_error_line(r.stderr)
        assert digest(given) == before
    assert sorted(p.name for p in folder.iterdir()) == [name]


# -- overlay ---------------------------------------------------------------------------------------
def test_overlay_refuses_to_write_over_the_movie_it_draws_on(tmp_path):
    import shutil

    video = Path(shutil.copy(gp.datasets.sample_movie(), tmp_path / "plugs.mp4"))
    assert cli("analyze", video, "--out", tmp_path / "out", "--no-figures").returncode == 0
    before = digest(video)
    for target in (video, tmp_path / "link.mp4"):
        if target.name == "link.mp4":
            target.symlink_to(video)
        r = cli("overlay", tmp_path / "out", "--out", target)
        assert r.returncode == 2
        assert "would be written over the input" in one_error_line(r.stderr)
        assert digest(video) == before


# -- batch ---------------------------------------------------------------------------------------
def test_batch_refuses_inputs_where_the_campaign_writes(tmp_path, movie):
    out = tmp_path / "campaign"
    (out / "runs" / "a").mkdir(parents=True)
    inside = out / "runs" / "a" / "movie.tif"
    inside.write_bytes(movie.read_bytes())
    cases = []
    m1 = out / "campaign.csv"  # the manifest named as the campaign's own table
    m1.write_text(f"run,movie,fps,mm_per_px\na,{movie},250,0.1\n")
    cases.append((m1, out))
    m2 = tmp_path / "m2.csv"  # a movie inside the runs' folders, replaced whole
    m2.write_text(f"run,movie,fps,mm_per_px\na,{inside},250,0.1\n")
    cases.append((m2, out))
    cases.append((m2, m2))  # the manifest as the output folder
    for manifest, where in cases:
        kept = {p: digest(p) for p in (m1, m2, inside)}
        r = cli("batch", manifest, "--out", where, "--workers", "1", "--no-figures")
        assert r.returncode == 2, r.stderr
        one_error_line(r.stderr)
        assert {p: digest(p) for p in kept} == kept
    assert sorted(p.name for p in out.iterdir()) == ["campaign.csv", "runs"]


# -- only grainplug speaks on stderr ----------------------------------------------------------------
@pytest.fixture
def broken(tmp_path, frames) -> dict[str, Path]:
    """A truncated TIFF, a TIFF whose pages disagree (tifffile's 'incompatible keyframe'), a loop of links."""
    import struct

    whole = tmp_path / "whole.tif"
    tifffile.imwrite(whole, frames[:20], metadata={"fps": 250.0})
    data = whole.read_bytes()
    (tmp_path / "truncated.tif").write_bytes(data[: len(data) // 2])
    mixed = tmp_path / "mixed.tif"
    tifffile.imwrite(mixed, frames[:12], metadata={"fps": 250.0}, compression="zlib")
    with tifffile.TiffFile(mixed) as tif:
        offset = tif.pages[5].offset
    raw = bytearray(mixed.read_bytes())
    for i in range(struct.unpack_from("<H", raw, offset)[0]):  # page 5's width, made another's
        entry = offset + 2 + 12 * i
        tag, kind, _ = struct.unpack_from("<HHI", raw, entry)
        if tag == 256:
            struct.pack_into("<I" if kind == 4 else "<H", raw, entry + 8, 50)
    mixed.write_bytes(bytes(raw))
    (tmp_path / "loop.tif").symlink_to(tmp_path / "loop.tif")
    return {"truncated": tmp_path / "truncated.tif", "mixed": mixed, "loop": tmp_path / "loop.tif"}


@pytest.mark.parametrize("case", ["truncated", "mixed", "loop"])
@pytest.mark.parametrize("command", ["info", "analyze"])
def test_a_broken_movie_gives_grainplugs_one_line_and_nothing_else(tmp_path, broken, case, command):
    args = [broken[case]] if command == "info" else [broken[case], "--out", tmp_path / "out", "--fps", "250"]
    r = cli(command, *args)
    assert r.returncode == 2
    line = one_error_line(r.stderr)
    assert broken[case].name in line
    assert not (tmp_path / "out").exists()


def test_a_librarys_words_reach_the_user_inside_grainplugs_line(broken):
    line = one_error_line(cli("info", broken["truncated"]).stderr)
    assert "truncated" in line and "(tifffile: invalid page offset" in line  # tifffile's own finding, quoted
    debug = cli("--debug", "info", broken["truncated"])
    assert "ERROR tifffile" in debug.stderr  # --debug shows every library's log as it is


def test_a_campaign_of_broken_movies_names_each_and_nothing_else(tmp_path, broken):
    manifest = tmp_path / "m.csv"
    manifest.write_text(f"run,movie,fps,mm_per_px\na,{broken['truncated']},250,0.1\nb,{broken['mixed']},250,0.1\n")
    r = cli("batch", manifest, "--out", tmp_path / "c", "--workers", "1", "--no-figures")
    assert r.returncode == 3
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert [ln.split(":")[0] for ln in lines] == ["failed", "failed", "error"], r.stderr


def test_output_folders_that_are_loops_of_links_are_refused_by_every_command_that_writes_one(tmp_path, broken):
    for args in (["synth", "--out", broken["loop"], "--frames", "10"],
                 ["simulate", "--out", broken["loop"], "--cells", "16", "--duration-tc", "1"],
                 ["paper", "--out", broken["loop"], "--no-simulations", "--no-figures"]):
        r = cli(*args)
        assert r.returncode == 2, r.stderr
        assert "symbolic link" in one_error_line(r.stderr)
