"""Campaigns on a cluster's queue (issue 36), without a cluster: stand-in SLURM commands.

``tests/fake_slurm/`` holds ``sbatch``, ``squeue`` and ``scancel`` that run the job script
dask-jobqueue writes on this machine, in the background, each job in a process group of its own,
and answer as SLURM does. The batch runs as users run it, ``python -m grainplug batch ...
--cluster slurm``, with its settings in ``DASK_JOBQUEUE__SLURM__*`` variables.
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

import pytest
from test_cli_basics import assert_one_line_error, run

from grainplug._atomic import is_complete
from grainplug.synthetic import SynthConfig, synthesize

pytest.importorskip("dask_jobqueue")

FAKE_SLURM = Path(__file__).parent / "fake_slurm"
N_RUNS = 5


@pytest.fixture(scope="module")
def campaign(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("cluster")
    rows = []
    for i in range(N_RUNS):
        synthesize(SynthConfig(n_frames=80, celerity_m_s=-0.04 - 0.008 * i, seed=20 + i, noise_sigma=2),
                   d / f"m{i}", fmt="tiff")
        rows.append({"run": f"r{i}", "movie": f"m{i}/movie.tif", "mass_flow_rate_g_s": 0.4 + 0.08 * i,
                     "mm_per_px": 0.185})
    with open(d / "manifest.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    return d


@pytest.fixture(scope="module")
def one_worker_table(campaign, tmp_path_factory) -> bytes:
    out = tmp_path_factory.mktemp("serial") / "out"
    proc = subprocess.run([sys.executable, "-m", "grainplug", "batch", str(campaign / "manifest.csv"), "--out",
                           str(out), "--no-figures", "--workers", "1"], capture_output=True, text=True,
                          env={**os.environ, "MPLBACKEND": "Agg"}, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return (out / "campaign.csv").read_bytes()


def job_groups(queue: Path) -> list[int]:
    """The process group of every job the stand-in sbatch started."""
    return [int(p.read_text()) for p in queue.glob("*.pid")]


def alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


@pytest.fixture
def slurm(tmp_path):
    """The stand-in SLURM's environment (its commands first on PATH, its state in a folder); afterwards, every
    job it started must have ended (and is ended here if not, so a failure leaves nothing running)."""
    queue = tmp_path / "queue"
    env = {**os.environ, "MPLBACKEND": "Agg", "PATH": f"{FAKE_SLURM}{os.pathsep}{os.environ['PATH']}",
           "FAKE_SLURM_DIR": str(queue), "DASK_JOBQUEUE__SLURM__CORES": "1",
           "DASK_JOBQUEUE__SLURM__MEMORY": "1GB", "DASK_JOBQUEUE__SLURM__DEATH_TIMEOUT": "20",
           "DASK_JOBQUEUE__SLURM__SCHEDULER_OPTIONS": "{'dashboard_address': None}"}
    yield queue, env
    left = [g for g in job_groups(queue) if alive(g)]
    for g in left:
        os.killpg(g, signal.SIGKILL)
    assert not left, f"jobs still running after the batch: process groups {left}"


def batch(campaign: Path, out: Path, env: dict, *args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "grainplug", "batch", str(campaign / "manifest.csv"),
                             "--out", str(out), "--no-figures", "--cluster", "slurm", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)


def finish(proc: subprocess.Popen, timeout: float) -> tuple[str, str]:
    """The batch's stdout and stderr once it ends; killed (and the test failed) if it outlives ``timeout``."""
    try:
        return proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        raise


def ended_within(groups: list[int], seconds: float) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if not any(alive(g) for g in groups):
            return True
        time.sleep(0.1)
    return False


def test_two_jobs_give_the_one_worker_table_and_end(campaign, one_worker_table, slurm, tmp_path):
    queue, env = slurm
    out = tmp_path / "out"
    proc = batch(campaign, out, env, "--jobs", "2")
    stdout, stderr = finish(proc, 300)
    assert proc.returncode == 0, stderr
    assert f"{N_RUNS} runs: {N_RUNS} ok" in stdout and "on 2 Dask worker(s)" in stdout, stdout
    assert (out / "campaign.csv").read_bytes() == one_worker_table
    assert len(list(queue.glob("*.sh"))) == 2 and "#SBATCH" in (queue / "1.sh").read_text()
    assert ended_within(job_groups(queue), 10), "a job outlived the batch"


def test_a_job_killed_mid_run_costs_only_that_runs_retry(campaign, one_worker_table, slurm, tmp_path):
    """Pre-emption without grace (SIGKILL of the job's whole process group) while a run is written: that run is
    analysed again on another worker, the runs finished before are not touched, the table is the one-worker one."""
    queue, env = slurm
    out = tmp_path / "out"
    proc = batch(campaign, out, env, "--jobs", "2")
    killed, before = None, {}
    end = time.monotonic() + 120
    while killed is None and time.monotonic() < end and proc.poll() is None:
        runs = out / "runs"
        busy = list(runs.glob(".*.grainplug-new-*")) if runs.is_dir() else []
        done = [p for p in runs.iterdir() if not p.name.startswith(".") and is_complete(p)] if runs.is_dir() else []
        for tmp in busy:
            try:
                group = os.getpgid(int(tmp.name.rsplit("-", 2)[-2]))
            except (ProcessLookupError, ValueError):
                continue
            if group in job_groups(queue) and done:
                before = {p.name: (p / "summary.json").stat().st_mtime_ns for p in done}
                os.killpg(group, signal.SIGKILL)
                killed = group
                break
        time.sleep(0.005)
    stdout, stderr = finish(proc, 300)
    assert killed is not None, "no job was killed mid-run: the test did not test anything"
    assert proc.returncode == 0, stderr
    assert f"{N_RUNS} runs: {N_RUNS} ok," in stdout and "reused" not in stdout, stdout  # none was there before
    assert "1 worker process(es) died" in stderr, stderr
    assert (out / "campaign.csv").read_bytes() == one_worker_table
    assert {name: (out / "runs" / name / "summary.json").stat().st_mtime_ns for name in before} == before
    assert not [p.name for p in (out / "runs").iterdir() if p.name.startswith(".")], "temporary folders left"
    assert ended_within(job_groups(queue), 10), "a job outlived the batch"


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["kill", "ctrl-c"])
def test_a_kill_or_ctrl_c_of_the_batch_cancels_its_jobs(campaign, slurm, tmp_path, sig):
    """A kill of the batch (as a login node's session end sends), or Ctrl-C, ends its jobs: none holds the queue."""
    queue, env = slurm
    proc = batch(campaign, tmp_path / "out", env, "--jobs", "2")
    end = time.monotonic() + 60
    while len(job_groups(queue)) < 2 and time.monotonic() < end:
        time.sleep(0.05)
    assert len(job_groups(queue)) == 2, "the jobs did not start"
    proc.send_signal(sig)
    _, stderr = finish(proc, 60)
    assert proc.returncode != 0 and "Traceback" not in stderr, stderr
    assert ended_within(job_groups(queue), 10), "a job outlived the batch"


def test_a_job_that_never_starts_is_one_line_and_nothing_written(campaign, slurm, tmp_path):
    queue, env = slurm
    out = tmp_path / "out"
    proc = batch(campaign, out, {**env, "FAKE_SLURM_HOLD": "1"}, "--cluster-timeout", "2")
    _, stderr = finish(proc, 120)
    assert_one_line_error(proc.returncode, stderr, "no slurm job started within 2 s", "--cluster-timeout")
    assert not out.exists()
    assert list(queue.glob("*.sh")) and not list(queue.glob("*.pending")), "the pending job was not cancelled"


def test_no_worker_left_ends_the_batch_in_one_line_keeping_the_runs_done(campaign, slurm, tmp_path):
    """Every job killed and the queue full (the replacement stays pending): after --cluster-timeout with no
    worker the batch stops in one line, the runs done are complete and kept, no campaign table is written,
    the pending job is cancelled; the same command then finishes the campaign, reusing them."""
    queue, env = slurm
    out = tmp_path / "out"
    proc = batch(campaign, out, env, "--jobs", "1", "--cluster-timeout", "4")
    end = time.monotonic() + 120
    done: list[Path] = []
    while not done and time.monotonic() < end and proc.poll() is None:
        runs = out / "runs"
        done = [p for p in runs.iterdir() if not p.name.startswith(".") and is_complete(p)] if runs.is_dir() else []
        time.sleep(0.01)
    assert done, "no run was done before the job was to be killed"
    (queue / "HOLD").touch()
    for g in job_groups(queue):
        os.killpg(g, signal.SIGKILL)
    _, stderr = finish(proc, 120)
    assert_one_line_error(proc.returncode, stderr, "no worker left for 4 s", "run the same command again")
    complete = [p.name for p in (out / "runs").iterdir() if not p.name.startswith(".") and is_complete(p)]
    assert 1 <= len(complete) < N_RUNS, complete
    assert not (out / "campaign.csv").exists()
    assert not list(queue.glob("*.pending")), "the pending job was not cancelled"
    (queue / "HOLD").unlink()
    again = batch(campaign, out, env, "--jobs", "1")
    stdout, stderr = finish(again, 300)
    assert again.returncode == 0, stderr
    assert f"{len(complete)} reused" in stdout, stdout


def test_unknown_cluster_kind(campaign, tmp_path, capsys):
    code, _, err = run(capsys, "batch", campaign / "manifest.csv", "--out", tmp_path / "o", "--cluster", "kubes")
    assert_one_line_error(code, err, "unknown cluster kind", "slurm, pbs, sge, lsf, htcondor")
    assert not (tmp_path / "o").exists()


def test_queue_command_not_found(campaign, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    code, _, err = run(capsys, "batch", campaign / "manifest.csv", "--out", tmp_path / "o", "--cluster", "pbs")
    assert_one_line_error(code, err, "cannot find qsub")
    assert not (tmp_path / "o").exists()


def test_without_dask_jobqueue_says_how_to_install_it(campaign, tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "dask_jobqueue", None)  # import fails as if not installed
    code, _, err = run(capsys, "batch", campaign / "manifest.csv", "--out", tmp_path / "o", "--cluster", "slurm")
    assert_one_line_error(code, err, "pip install 'grainplug[cluster]'")
    assert not (tmp_path / "o").exists()


def test_jobs_without_cluster_is_refused(campaign, tmp_path, capsys):
    code, _, err = run(capsys, "batch", campaign / "manifest.csv", "--out", tmp_path / "o", "--jobs", "3")
    assert_one_line_error(code, err, "--cluster")
    assert not (tmp_path / "o").exists()


def test_run_campaign_takes_any_client_and_leaves_it_open(campaign, one_worker_table, tmp_path):
    distributed = pytest.importorskip("distributed")
    from grainplug.campaigns import run_campaign

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as lc, \
            distributed.Client(lc) as client:
        camp = run_campaign(campaign / "manifest.csv", tmp_path / "out", client=client, figures=False)
        assert client.status == "running"  # the caller's client: not closed by the campaign
        assert client.submit(sum, [1, 2]).result() == 3
    assert camp.n_failed == 0 and len(camp.workers_used) >= 1
    assert (tmp_path / "out" / "campaign.csv").read_bytes() == one_worker_table


def test_a_worker_that_cannot_see_the_movie_names_its_host(campaign, tmp_path):
    """What a node without the shared filesystem returns: the run failed, the host named, the fix said."""
    import socket

    from grainplug.campaigns.batch import _remote_run
    from grainplug.campaigns.manifest import read_manifest

    spec = read_manifest(campaign / "manifest.csv")[0]
    (tmp_path / "out").mkdir()
    gone = dataclasses.replace(spec, movie=tmp_path / "not-mounted" / "movie.tif")
    rec = _remote_run(gone, str(tmp_path / "out"), figures=False)
    assert rec["status"] == "failed"
    assert f"on host {socket.gethostname()}" in rec["error"] and "filesystem" in rec["error"]
    rec = _remote_run(spec, str(tmp_path / "not-mounted-out"), figures=False)
    assert rec["status"] == "failed" and f"on host {socket.gethostname()}" in rec["error"]


def test_the_scheduler_answers_its_own_user_only(slurm, monkeypatch):
    """The campaign's scheduler listens for the cluster's nodes: it speaks TLS with a certificate made for the
    campaign (a client with another is refused), and its dashboard is on this machine's loopback only."""
    import dask
    import distributed

    from grainplug.campaigns.cluster import job_cluster

    _, env = slurm
    for key in ("PATH", "FAKE_SLURM_DIR"):
        monkeypatch.setenv(key, env[key])
    with dask.config.set({"jobqueue.slurm.cores": 1, "jobqueue.slurm.memory": "1GB",
                          "jobqueue.slurm.death-timeout": 20}), job_cluster("slurm", jobs=1, timeout_s=120) as client:
        address = client.scheduler.address
        assert address.startswith("tls://")
        import socket
        from urllib.parse import urlsplit

        link = urlsplit(client.dashboard_link)
        socket.create_connection(("127.0.0.1", link.port), timeout=5).close()  # on the loopback
        if link.hostname not in ("127.0.0.1", "localhost"):
            with pytest.raises(OSError):  # not on the network
                socket.create_connection((link.hostname, link.port), timeout=5).close()
        assert client.submit(sum, [1, 2]).result(timeout=60) == 3  # its own workers hold the certificate
        with pytest.raises((OSError, TimeoutError)):  # a client with a certificate of its own: refused (unknown CA)
            distributed.Client(address, security=distributed.security.Security.temporary(), timeout="3s")
