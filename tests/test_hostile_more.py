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


# -- 3. crashes instead of one line (rows 15-19, 24) ---------------------------------------------
def test_a_name_too_long_is_one_line(tmp_path, movie):
    long = "x" * 300
    for args in (["info", tmp_path / f"{long}.tif"],
                 ["analyze", movie, "--out", tmp_path / long, "--no-figures"]):
        code, _, err = gp_run(*args)
        assert code == 2
        one_error(err, "the name is too long", "give a shorter name")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["movies"]


@pytest.fixture
def damaged(tmp_path, movie) -> Path:
    """An analysis whose result.npz was cut short (a copy interrupted, a full disk)."""
    out = tmp_path / "done"
    assert gp_run("analyze", movie, "--out", out, "--no-figures")[0] == 0
    data = (out / "result.npz").read_bytes()
    (out / "result.npz").write_bytes(data[:1000])
    return out


@pytest.mark.parametrize("command", [["remeasure", "--no-figures"], ["overlay"], ["review", "--no-browser"]])
def test_a_damaged_result_is_one_line(damaged, command):
    before = snapshot(damaged)
    code, out, err = gp_run(command[0], damaged, *command[1:], timeout=60)  # review: refused before serving
    assert code == 2
    one_error(err, "result.npz is damaged", "analyse the movie again")
    assert "review " not in out  # no address printed: nothing served
    assert snapshot(damaged) == before


@pytest.mark.parametrize("harm", ["missing", "another"])
def test_a_result_without_its_diagram_beside_it_is_one_line(tmp_path, movie, harm):
    """result.npz refers to the diagram in diagram.npz beside it (not a second copy): a folder copied in part, or
    a diagram.npz from another analysis, is one clear line, not a wrong diagram."""
    out = tmp_path / "done"
    assert gp_run("analyze", movie, "--out", out, "--no-figures")[0] == 0
    import grainplug as gp

    whole = gp.load_result(out)
    with np.load(out / "diagram.npz", allow_pickle=False) as d:
        assert np.array_equal(whole.diagram.values, d["values"]) and np.array_equal(whole.normalized.z, d["contrast"])
    if harm == "missing":
        (out / "diagram.npz").unlink()
        words = ("needs diagram.npz beside it", "copy an analysis folder whole")
    else:
        with open(out / "diagram.npz", "wb") as fh:
            np.savez(fh, values=whole.diagram.values[:-1], contrast=whole.normalized.z[:-1])
        words = ("does not hold the result's diagram.values", "analyse the movie again")
    code, _, err = gp_run("remeasure", out, "--no-figures", timeout=60)
    assert code == 2
    one_error(err, *words)


def test_a_damaged_result_in_python(tmp_path):
    import io
    import zipfile

    from grainplug.errors import GrainplugError
    from grainplug.store import read_result

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("__tree__.npy", b"cut")
    path = tmp_path / "result.npz"
    for data in (b"PK\x03\x04 cut short", buf.getvalue()):
        path.write_bytes(data)
        with pytest.raises(GrainplugError, match="damaged or not a grainplug result"):
            read_result(path, {})


@pytest.mark.parametrize(("args", "words"), [
    (["--diameter-mm", "1e308"], "--diameter-mm: must be a finite number below"),
    (["--grain-density-kg-m3", "1e300"], "--grain-density-kg-m3: must be a finite number below"),
])
def test_stability_inputs_that_overflow_are_one_line(args, words):
    code, _, err = gp_run("stability", *args)
    assert code == 2
    one_error(err, words)


def test_synth_seed_out_of_range_is_one_line_and_leaves_no_folder(tmp_path):
    code, _, err = gp_run("synth", "--out", tmp_path / "syn", "--seed", -1, "--frames", 10)
    assert code == 2
    one_error(err, "--seed: must be a whole number from 0")
    assert not (tmp_path / "syn").exists()


# -- 4. a cost check before a huge job (rows 20-23, 25-27) ----------------------------------------
@pytest.mark.parametrize(("args", "words"), [
    (["--width", 1000000], "--width: a 1000000 x 640 px frame needs about"),
    (["--width", 100000, "--height", 100000], "GiB to render"),
    (["--celerity-m-s", "1e308"], "--celerity-m-s: plugs at 1e+308 m/s"),
])
def test_synth_sizes_are_checked_before_rendering(tmp_path, args, words):
    code, _, err = gp_run("synth", "--out", tmp_path / "syn", "--frames", 10, *args, timeout=30)
    assert code == 2
    one_error(err, words)
    assert not (tmp_path / "syn").exists()


@pytest.mark.parametrize("args", [
    ["--cells", 1000000, "--duration-tc", 10000000],
    ["--cells", 100000, "--duration-tc", 10000000, "--output-interval-tc", 0.0001],
    ["--cells", 1000000, "--duration-tc", 100000],
])
def test_simulate_memory_is_checked_before_the_run(tmp_path, args):
    code, _, err = gp_run("simulate", "--out", tmp_path / "sim", *args, timeout=30)
    assert code == 2
    one_error(err, "saved states of", "GiB free — give fewer --cells")
    assert not (tmp_path / "sim").exists()


def test_a_simulation_longer_than_the_limit_is_refused_after_its_first_seconds(monkeypatch):
    from grainplug.errors import ParameterError
    from grainplug.simulation import SimulationParams
    from grainplug.simulation import run as sim_run
    from grainplug.stability import ModelParams

    monkeypatch.setattr(sim_run, "ESTIMATE_AFTER_S", 0.0)
    with pytest.raises(ParameterError, match=r"would take about .* over the limit"):
        sim_run.simulate(ModelParams(), SimulationParams(n_cells=64, duration_tc=5), max_seconds=1e-9)


def test_a_stability_sweep_longer_than_the_limit_is_refused_on_its_first_seconds(monkeypatch):
    from grainplug.errors import ParameterError
    from grainplug.stability import ModelParams, analysis, sweep

    monkeypatch.setattr(analysis, "SWEEP_RECHECK_S", 0.0)
    said: list[float] = []
    with pytest.raises(ParameterError, match=r"measured on the first 1\b"):
        sweep(ModelParams(), "c0", np.linspace(0.45, 0.6, 1000), n_k=10, max_seconds=1e-9)
    rows = sweep(ModelParams(), "c0", np.linspace(0.45, 0.6, 5), n_k=10, on_estimate=said.append)
    assert len(rows) == 5 and len(said) == 2 and all(s > 0 for s in said)


# -- 5. silently wrong (rows 28-30) ---------------------------------------------------------------
def test_overlay_refuses_a_movie_changed_since_the_analysis(tmp_path, movie, frames):
    out = tmp_path / "done"
    assert gp_run("analyze", movie, "--out", out, "--no-figures")[0] == 0
    tifffile.imwrite(movie, frames[::-1][:40], metadata={"fps": 250.0})  # another movie under the same name
    before = snapshot(out)
    code, _, err = gp_run("overlay", out)
    assert code == 2
    one_error(err, "is not the one analysed", "analyse it again")
    assert snapshot(out) == before  # no overlay.mp4


def test_a_moving_background_is_refused(tmp_path, movie, frames):
    out = tmp_path / "out"
    code, _, err = gp_run("analyze", movie, "--out", out, "--no-figures", "--background", movie)
    assert code == 2
    one_error(err, "moves", "nothing moving in it")
    assert not out.exists()
    # a still tube (the same frame with its noise) is a background
    rng = np.random.default_rng(0)
    still = tmp_path / "still.tif"
    tifffile.imwrite(still, np.clip(frames[0][None] + rng.normal(0, 3, (20, *frames[0].shape)), 0, 255)
                     .astype(np.uint8), metadata={"fps": 250.0})
    from grainplug.calibration_files import read_background

    assert read_background(still).n_frames == 20


# -- 6. small ones (rows 31-36) -------------------------------------------------------------------
@pytest.mark.parametrize(("text", "words"), [
    ("this is: not: a: style\nfont.size: huge\n", "line 1 ('this is: not: a: style'): 'this is' is no matplotlib"),
    ("font.size: 40\nlines.linewidth: abc\n", "line 2 ('lines.linewidth: abc'): bad value for lines.linewidth"),
])
def test_a_bad_style_sheet_is_refused_before_the_analysis(tmp_path, movie, text, words):
    style = tmp_path / "bad.mplstyle"
    style.write_text(text)
    code, _, err = gp_run("analyze", movie, "--out", tmp_path / "out", "--style", style)
    assert code == 2
    one_error(err, words)
    assert not (tmp_path / "out").exists()


def test_a_good_style_sheet_passes_the_check(tmp_path):
    import matplotlib

    from grainplug.cli.common import check_style_file

    style = tmp_path / "good.mplstyle"
    style.write_text('# a lab\'s style\naxes.facecolor: "#eeeeee"  # grey\nfont.size : 9\n\nlines.linewidth: 2\n')
    check_style_file(style)
    for sheet in sorted((Path(matplotlib.get_data_path()) / "stylelib").glob("*.mplstyle")):
        check_style_file(sheet)  # matplotlib's own sheets


def test_one_setting_twice_in_a_settings_file_is_refused(tmp_path, movie):
    config = tmp_path / "lab.toml"
    config.write_text("[analyze]\nmm-per-px = 0.2\nmm_per_px = 0.3\n")
    code, _, err = gp_run("analyze", movie, "--out", tmp_path / "out", "--no-figures", "--config", config)
    assert code == 2
    one_error(err, "'mm-per-px' and 'mm_per_px' in [analyze] are the same setting")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("args", [[], ["--debug"]])
def test_no_command_prints_the_usage(args):
    code, out, err = gp_run(*args)
    assert code == 0 and err == ""
    assert out.startswith("Usage: grainplug") and "analyze" in out


def test_every_stderr_line_of_an_analysis_has_a_known_prefix(tmp_path, frames):
    """The statement of what is not measured ("no plugs: ...") and "settings from" are notes, not bare lines."""
    still = tmp_path / "still.tif"
    tifffile.imwrite(still, np.repeat(frames[:1], 30, axis=0), metadata={"fps": 250.0})
    config = tmp_path / "grainplug.toml"
    config.write_text("[analyze]\nfps = 250\n")
    code, _, err = gp_run("analyze", still, "--out", tmp_path / "out", "--no-figures")
    assert code == 0, err
    lines = err.splitlines()
    assert lines and all(ln.startswith(("warning: ", "note: ")) for ln in lines), err
    assert any(ln.startswith("note: settings from") for ln in lines), err


def test_ctrl_c_is_one_line():
    """click writes an empty line before its Abort: the command line reports Ctrl-C itself."""
    import click

    from grainplug.cli.app import LazyGroup
    from grainplug.errors import Interrupted

    @click.group(cls=LazyGroup)
    def group() -> None:
        pass

    @group.command()
    def stop() -> None:
        raise KeyboardInterrupt

    with pytest.raises(Interrupted, match="interrupted"):
        group.main(["stop"], standalone_mode=False)


@pytest.mark.parametrize("command", ["info", "analyze"])
def test_a_text_file_is_not_a_movie(tmp_path, command):
    """FFmpeg reads any text as a terminal's screen (its tty demuxer): `info` called a README a 7-frame 25 fps
    movie, and `analyze` failed with an internal error. Both refuse it in one line."""
    text = tmp_path / "notes.txt"
    text.write_text("Plugs at 0.5 g/s, humidity 45 %.\n" * 200)
    extra = ["--out", tmp_path / "out"] if command == "analyze" else []
    code, _, err = gp_run(command, text, *extra)
    assert code == 2
    one_error(err, "notes.txt", "not a movie")
    assert not (tmp_path / "out").exists()
