"""A batch you can leave overnight: kills, Ctrl-C, orphaned workers, movies changed in place.

The batch runs as users run it, ``python -m grainplug batch ...`` in its own process
group, and is attacked from outside: SIGKILL at random moments (of the whole group: a
power cut; of the batch's process alone: its workers must not live on), SIGINT to the
group (Ctrl-C in a terminal). After each attack every run folder is complete or absent,
and the batch run again gives a campaign table equal, byte for byte, to that of a batch
never interrupted. ``-m slow`` runs the long variant (more kills).
"""

from __future__ import annotations

import csv
import dataclasses
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import tifffile

from grainplug._atomic import is_complete
from grainplug.campaigns.batch import process_run
from grainplug.campaigns.manifest import read_manifest
from grainplug.provenance import fingerprint
from grainplug.synthetic import SynthConfig, synthesize

N_RUNS = 6


@pytest.fixture(scope="module")
def campaign(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("faults")
    rows = []
    for i in range(N_RUNS):
        synthesize(SynthConfig(n_frames=100, celerity_m_s=-0.04 - 0.008 * i, seed=10 + i, noise_sigma=2),
                   d / f"m{i}", fmt="tiff")
        rows.append({"run": f"r{i}", "movie": f"m{i}/movie.tif", "mass_flow_rate_g_s": 0.4 + 0.08 * i,
                     "mm_per_px": 0.185})
    with open(d / "manifest.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    return d


def _as_in_a_terminal() -> None:
    # a shell that starts the tests in the background ignores SIGINT for them, and children inherit
    # that: give the batch the default disposition a terminal gives it
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start(campaign: Path, out: Path, *args: str) -> subprocess.Popen:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.Popen([sys.executable, "-m", "grainplug", "batch", str(campaign / "manifest.csv"),
                             "--out", str(out), "--no-figures", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            start_new_session=True, preexec_fn=_as_in_a_terminal)


def finish(proc: subprocess.Popen, timeout: float = 120) -> tuple[int, str, str]:
    out, err = proc.communicate(timeout=timeout)
    return proc.returncode, out, err


def group_gone(pgid: int, within_s: float) -> bool:
    """Whether every process of the group has ended within ``within_s``."""
    end = time.monotonic() + within_s
    while time.monotonic() < end:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.05)
    return False


def runs_done(out: Path) -> list[str]:
    runs = out / "runs"
    if not runs.is_dir():
        return []
    return sorted(p.name for p in runs.iterdir() if not p.name.startswith(".") and is_complete(p))


def assert_whole(out: Path) -> None:
    """Every run folder is complete (leftover temporary folders are hidden and cleaned next time)."""
    runs = out / "runs"
    if runs.is_dir():
        for p in runs.iterdir():
            if not p.name.startswith("."):
                assert is_complete(p), f"{p.name} is half-written"


@pytest.fixture(scope="module")
def undisturbed(campaign, tmp_path_factory) -> bytes:
    out = tmp_path_factory.mktemp("undisturbed") / "out"
    code, _, err = finish(start(campaign, out, "--workers", "2"))
    assert code == 0, err
    return (out / "campaign.csv").read_bytes()


def _attack(campaign: Path, out: Path, undisturbed: bytes, *, n_kills: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    kills = 0
    for k in range(n_kills):
        proc = start(campaign, out, "--workers", "2")
        time.sleep(float(rng.uniform(0.2, 2.5)))
        whole_group = k % 2 == 0  # a power cut, or the batch's process alone
        try:
            (os.killpg if whole_group else os.kill)(proc.pid, signal.SIGKILL)
            kills += 1
        except ProcessLookupError:
            pass  # it had finished
        proc.communicate(timeout=60)
        # workers of a killed batch end by themselves (they used to wait for work for ever)
        assert group_gone(proc.pid, within_s=5.0), "workers outlived their batch"
        assert_whole(out)
    code, _, err = finish(start(campaign, out, "--workers", "2"))
    assert code == 0, err
    assert kills >= 1
    assert (out / "campaign.csv").read_bytes() == undisturbed
    assert runs_done(out) == [f"r{i}" for i in range(N_RUNS)]
    assert not [p.name for p in (out / "runs").iterdir() if p.name.startswith(".")], "temporary folders left"


def test_kill_9_at_random_moments_then_rerun_equals_an_undisturbed_batch(campaign, undisturbed, tmp_path):
    _attack(campaign, tmp_path / "out", undisturbed, n_kills=3, seed=1)


@pytest.mark.slow
def test_kill_9_many_times(campaign, undisturbed, tmp_path):
    _attack(campaign, tmp_path / "out", undisturbed, n_kills=10, seed=2)


@pytest.mark.parametrize("workers", ["1", "2"])
def test_ctrl_c_stops_at_once_and_keeps_what_is_done(campaign, undisturbed, tmp_path, workers):
    out = tmp_path / "out"
    proc = start(campaign, out, "--workers", workers)
    end = time.monotonic() + 60
    while not runs_done(out) and time.monotonic() < end:
        time.sleep(0.02)
    assert runs_done(out), "no run finished"
    os.killpg(proc.pid, signal.SIGINT)  # what a terminal sends on Ctrl-C
    t0 = time.monotonic()
    code, _, err = finish(proc, timeout=30)
    stopped_s = time.monotonic() - t0
    lines = err.strip().splitlines()
    assert code == 130 and len(lines) == 1 and lines[0].startswith("error: interrupted: "), err
    assert "runs have a complete result, kept" in lines[0] and "Traceback" not in err
    assert stopped_s < 5.0, f"took {stopped_s:.1f} s to stop"  # not after the queue
    assert len(runs_done(out)) < N_RUNS
    assert group_gone(proc.pid, within_s=5.0)
    assert_whole(out)
    assert not [p.name for p in (out / "runs").iterdir() if p.name.startswith(".")], "temporary folders left"
    kept = runs_done(out)
    assert kept
    code, printed, err = finish(start(campaign, out, "--workers", workers))
    assert code == 0, err
    assert f"({len(kept)} reused from an earlier batch)" in printed
    assert (out / "campaign.csv").read_bytes() == undisturbed


def test_a_half_written_or_damaged_run_is_analysed_again(campaign, tmp_path):
    specs = read_manifest(campaign / "manifest.csv")[:2]
    out = tmp_path / "out"
    for s in specs:
        assert process_run(s, str(out), figures=False)["reused"] is False
    (out / "runs" / "r0" / "diagram.npz").unlink()  # damaged since
    (out / "runs" / "r1" / ".grainplug").unlink()  # no completion marker (an older version, a copy)
    for s in specs:
        rec = process_run(s, str(out), figures=False)
        assert rec["status"] == "ok" and rec["reused"] is False, rec.get("error")
    assert all(process_run(s, str(out), figures=False)["reused"] for s in specs)


def test_sampled_fingerprint_and_full_verify(tmp_path, rng):
    """The sampled hash sees the header, the ends and 32 blocks spread between them; --verify sees every byte."""
    p = tmp_path / "movie.raw"
    data = rng.integers(0, 256, 12 << 20, dtype=np.uint8)
    p.write_bytes(data.tobytes())
    a = fingerprint(p, full=True)
    st = p.stat()

    def rewrite(offset: int) -> dict:
        changed = data.copy()
        changed[offset] ^= 0xFF
        p.write_bytes(changed.tobytes())
        os.utime(p, ns=(st.st_atime_ns, st.st_mtime_ns))  # same size, same time: only the content differs
        return fingerprint(p, full=True)

    block = (1 << 20) + ((12 << 20) - (2 << 20) - (1 << 16)) * 7 // 31  # inside the 8th sampled block
    b = rewrite(block + 100)
    assert b["sha256_sampled"] != a["sha256_sampled"] and b["sha256"] != a["sha256"]
    between = block + (1 << 16) + 1000  # between two blocks: only the full hash sees it
    c = rewrite(between)
    assert c["sha256_sampled"] == a["sha256_sampled"] and c["sha256"] != a["sha256"]
    assert (c["bytes"], c["mtime"]) == (a["bytes"], a["mtime"])


def test_a_movie_changed_in_place_is_analysed_again(campaign, tmp_path):
    """Re-recorded under the same name, same size and time: analysed again; one frame edited between
    the sampled blocks: only with --verify (the documented limit of the sampled hash)."""
    src = read_manifest(campaign / "manifest.csv")[0]
    movie = tmp_path / "movie.tif"
    movie.write_bytes(Path(src.movie).read_bytes())
    spec = dataclasses.replace(src, movie=movie)
    out = tmp_path / "out"
    first = process_run(spec, str(out), figures=False, verify=True)
    assert first["reused"] is False
    st = movie.stat()
    frames = tifffile.imread(movie)
    other = synthesize(SynthConfig(n_frames=100, celerity_m_s=-0.09, seed=99, noise_sigma=2), tmp_path / "new",
                       fmt="tiff")
    new = tifffile.imread(other.movie)
    assert new.shape == frames.shape
    movie.write_bytes(other.movie.read_bytes())  # re-recorded in place
    assert movie.stat().st_size == st.st_size
    os.utime(movie, ns=(st.st_atime_ns, st.st_mtime_ns))
    again = process_run(spec, str(out), figures=False)
    assert again["reused"] is False and again["celerity_m_s"] == pytest.approx(-0.09, rel=0.03)
    # one frame edited where no sampled block lies
    info = fingerprint(movie)
    size = info["bytes"]
    span = size - (2 << 20) - (1 << 16)
    starts = [(1 << 20) + span * k // 31 for k in range(32)]
    frame_bytes = new[0].nbytes
    with tifffile.TiffFile(movie) as tf:
        page_at = [int(p.dataoffsets[0]) for p in tf.pages]
    free = [k for k, off in enumerate(page_at)
            if off > (1 << 20) and off + frame_bytes < size - (1 << 20)
            and all(off + frame_bytes <= s or off >= s + (1 << 16) for s in starts)]
    assert free, "every frame overlaps a sampled block: make the movie longer"
    k = free[0]
    raw = bytearray(movie.read_bytes())
    raw[page_at[k]:page_at[k] + frame_bytes] = bytes(frame_bytes)  # a black frame
    movie.write_bytes(bytes(raw))
    os.utime(movie, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert process_run(spec, str(out), figures=False)["reused"] is True
    assert process_run(spec, str(out), figures=False, verify=True)["reused"] is False
    assert process_run(spec, str(out), figures=False, verify=True)["reused"] is True


@pytest.mark.slow
def test_a_dask_worker_killed_mid_run_costs_only_a_retry(campaign, undisturbed, tmp_path):
    """On a local Dask cluster, a worker killed while it analyses a run: the run is retried on
    another worker; every run is in the table once, and the table is the undisturbed one."""
    import threading

    distributed = pytest.importorskip("distributed")
    from grainplug.campaigns import run_campaign

    out = tmp_path / "out"
    killed: list[int] = []
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        pids = list(client.run(os.getpid).values())

        def kill_one() -> None:
            end = time.monotonic() + 60
            while time.monotonic() < end:  # while a run is being written: its temporary folder exists
                busy = list((out / "runs").glob(".*.grainplug-new-*")) if (out / "runs").is_dir() else []
                writing = [int(p.name.rsplit("-", 2)[-2]) for p in busy]
                victim = next((pid for pid in writing if pid in pids), None)
                if victim is not None and runs_done(out):
                    os.kill(victim, signal.SIGKILL)
                    killed.append(victim)
                    return
                time.sleep(0.005)

        killer = threading.Thread(target=kill_one)
        killer.start()
        camp = run_campaign(campaign / "manifest.csv", out, scheduler=cluster.scheduler_address, figures=False)
        killer.join()
    assert killed, "no worker was killed: the test did not test anything"
    assert list(camp.table.run) == [f"r{i}" for i in range(N_RUNS)] and set(camp.table.status) == {"ok"}
    assert (out / "campaign.csv").read_bytes() == undisturbed
    assert runs_done(out) == [f"r{i}" for i in range(N_RUNS)]
    assert not [p.name for p in (out / "runs").iterdir() if p.name.startswith(".")], "temporary folders left"


def test_a_worker_killed_in_the_local_pool_costs_only_its_run(campaign, undisturbed, tmp_path):
    """The OOM killer takes one worker: the batch goes on with new workers (it used to stop with an
    'unexpected BrokenProcessPool' bug line), says so, and its table is the undisturbed one."""
    out = tmp_path / "out"
    proc = start(campaign, out, "--workers", "2")
    victim = None
    end = time.monotonic() + 60
    while victim is None and time.monotonic() < end and proc.poll() is None:
        kids = set()
        for task in Path(f"/proc/{proc.pid}/task").glob("*"):
            try:
                kids |= {int(x) for x in (task / "children").read_text().split()}
            except OSError:
                pass
        busy = list((out / "runs").glob(".*.grainplug-new-*")) if (out / "runs").is_dir() else []
        victim = next((pid for q in busy if (pid := int(q.name.rsplit("-", 2)[-2])) in kids), None)
        time.sleep(0.005)
    assert victim is not None, "no worker was caught writing a run"
    os.kill(victim, signal.SIGKILL)
    code, _, err = finish(proc)
    assert code == 0, err
    assert err.strip().startswith("warning: 1 worker process(es) died") and "Traceback" not in err
    assert (out / "campaign.csv").read_bytes() == undisturbed
    assert runs_done(out) == [f"r{i}" for i in range(N_RUNS)]
    assert not [p.name for p in (out / "runs").iterdir() if p.name.startswith(".")], "temporary folders left"


def test_a_run_that_kills_its_worker_fails_alone(campaign, tmp_path, monkeypatch):
    import multiprocessing

    from grainplug.campaigns import batch, run_campaign

    if multiprocessing.get_start_method() != "fork":
        pytest.skip("the worker's crash is planted in the parent, which only fork passes on")
    real = batch.process_run

    def crashes_on_r2(spec, *args, **kwargs):
        if spec.run == "r2":
            os._exit(9)  # a segfault in a decoder, the OOM killer: the process is gone
        return real(spec, *args, **kwargs)

    monkeypatch.setattr(batch, "process_run", crashes_on_r2)
    camp = run_campaign(campaign / "manifest.csv", tmp_path / "out", workers=2, figures=False)
    status = dict(zip(camp.table.run, camp.table.status, strict=True))
    assert status == {f"r{i}": "failed" if i == 2 else "ok" for i in range(N_RUNS)}
    assert "died twice" in camp.table.set_index("run").loc["r2", "error"]
    assert camp.n_failed == 1 and camp.worker_deaths >= 3


def _workers_of(pid: int) -> list[int]:
    """The batch's worker processes (forked: the same command line as the batch)."""
    cmd = Path(f"/proc/{pid}/cmdline").read_bytes()
    kids = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    return [int(k) for k in kids if Path(f"/proc/{k}/cmdline").read_bytes() == cmd]


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux /proc")
def test_workers_stopped_again_and_again_mid_run_leave_nothing_behind(campaign, undisturbed, tmp_path):
    """The executor terminates every worker again when one ends: a worker hit by SIGTERM while it
    removes its temporary folder must still remove it whole (the batch itself, paused, cannot)."""
    out = tmp_path / "out"
    proc = start(campaign, out, "--workers", "2")

    def writing() -> list[str]:
        runs = out / "runs"
        return [p.name for p in runs.iterdir() if ".grainplug-new-" in p.name] if runs.is_dir() else []

    end = time.monotonic() + 60
    while time.monotonic() < end and not writing():
        time.sleep(0.005)
    workers = _workers_of(proc.pid)
    assert workers and writing(), "no worker process found writing"
    os.kill(proc.pid, signal.SIGSTOP)  # the batch cannot clean up after them nor start new workers
    try:
        storm_end = time.monotonic() + 0.5
        while time.monotonic() < storm_end:  # SIGTERM again and again, as from the executor and the batch
            for w in workers:
                try:
                    os.kill(w, signal.SIGTERM)
                except ProcessLookupError:
                    pass
        for w in workers:
            end = time.monotonic() + 10
            while Path(f"/proc/{w}/status").exists() and "zombie" not in Path(f"/proc/{w}/status").read_text() \
                    and time.monotonic() < end:
                time.sleep(0.01)
        left = writing()
    finally:
        os.kill(proc.pid, signal.SIGCONT)
    assert not left, "a stopped worker left its temporary folder"
    code, _, err = finish(proc)
    assert code == 0, err
    assert (out / "campaign.csv").read_bytes() == undisturbed


#: ``python -m grainplug`` with the campaign's report stage made slow: writing ``campaign.parquet`` (in the
#: campaign's temporary folder, after ``campaign.csv``) leaves a mark, then waits for the Ctrl-C
_SLOW_REPORT = """
import os, runpy, sys, time
import pyarrow.parquet

def _slow(*args, **kwargs):
    open(os.environ["GRAINPLUG_TEST_STAGE"], "w").close()
    time.sleep(120)

pyarrow.parquet.write_table = _slow
sys.argv = ["grainplug", *sys.argv[1:]]
runpy.run_module("grainplug", run_name="__main__", alter_sys=True)
"""


def test_ctrl_c_while_the_report_is_written_keeps_the_campaign_s_files(campaign, undisturbed, tmp_path):
    """Ctrl-C while the campaign's tables and report are written (every run done): one line that says so, status
    130, the runs kept, the campaign's files of the batch before left as they were (none half-written, no
    temporary folder left); the same command then writes them all."""
    out = tmp_path / "out"
    code, _, err = finish(start(campaign, out, "--workers", "1"))
    assert code == 0, err
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert before["campaign.csv"] == undisturbed and "campaign.parquet" in before
    stage = tmp_path / "report-stage"
    env = {**os.environ, "MPLBACKEND": "Agg", "GRAINPLUG_TEST_STAGE": str(stage)}
    proc = subprocess.Popen([sys.executable, "-c", _SLOW_REPORT, "batch", str(campaign / "manifest.csv"),
                             "--out", str(out), "--no-figures", "--workers", "1"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            start_new_session=True, preexec_fn=_as_in_a_terminal)
    try:
        end = time.monotonic() + 90
        while not stage.exists() and proc.poll() is None and time.monotonic() < end:
            time.sleep(0.02)
        assert stage.exists(), "the report stage was not reached"
        os.killpg(proc.pid, signal.SIGINT)  # what a terminal sends on Ctrl-C
        code, _, err = finish(proc, timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    lines = err.strip().splitlines()
    assert code == 130 and len(lines) == 1, err
    assert lines[0].startswith("error: interrupted while writing the campaign's tables and report: "
                               f"{N_RUNS} of {N_RUNS} runs have a complete result, kept"), err
    assert "run the same command again" in lines[0] and "Traceback" not in err
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before  # the batch before's, whole
    assert not [p.name for p in out.iterdir() if p.name.startswith(".") and p.name != ".grainplug"], \
        "temporary folders left"
    assert_whole(out)
    assert runs_done(out) == [f"r{i}" for i in range(N_RUNS)]
    code, printed, err = finish(start(campaign, out, "--workers", "1"))
    assert code == 0, err
    assert f"({N_RUNS} reused from an earlier batch)" in printed
    assert (out / "campaign.csv").read_bytes() == undisturbed
