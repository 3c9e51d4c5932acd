"""Issue 17's target for batches: many short runs with a worker killed every so often.

    .venv/bin/python benchmarks/batch_faults.py [--runs 200] [--frames 300] [--workers 2]
        [--kill-every-s 30] [--dir /tmp/grainplug-batch-faults] [--cluster slurm]

Renders ``--runs`` short synthetic movies (cached in ``--dir``), runs one undisturbed
batch, then the same batch into another folder while a killer sends SIGKILL to one of
the batch's worker processes (one that is writing a run, if any) every
``--kill-every-s`` seconds. The batch is not restarted by hand: it must finish by
itself. It reports how many workers were killed, whether every run is in the table once
with status ok, and whether the campaign table equals the undisturbed one byte for
byte. Nothing here is a test (it takes minutes); ``tests/test_batch_faults.py`` runs
the same attack on six runs.

With ``--cluster slurm`` (issue 36), the attacked batch runs ``--cluster slurm --jobs
WORKERS`` on the stand-in SLURM of ``tests/fake_slurm`` (each job a process group of this
machine), and the killer ends a whole job with SIGKILL (pre-emption without grace; the job
writing a run, if any) every ``--kill-every-s``; afterwards it checks that no job's process
is left. The undisturbed batch is ``--workers WORKERS`` on this machine: the tables must be
equal. ``tests/test_cluster.py`` runs one such kill on five runs.
"""

from __future__ import annotations

import argparse
import csv
import logging
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from grainplug.synthetic import SynthConfig, synthesize

log = logging.getLogger("batch_faults")


def children(pid: int) -> list[int]:
    """Child processes of ``pid`` (Linux /proc)."""
    out: list[int] = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            out += [int(x) for x in (task / "children").read_text().split()]
        except OSError:
            pass
    return out


def make_campaign(folder: Path, n: int, n_frames: int) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    for i in range(n):
        movie = folder / f"m{i:03d}-{n_frames}" / "movie.tif"
        if not movie.exists():
            synthesize(SynthConfig(n_frames=n_frames, celerity_m_s=-0.03 - 0.0003 * i, seed=i, noise_sigma=2),
                       movie.parent, fmt="tiff")
        rows.append({"run": f"r{i:03d}", "movie": f"m{i:03d}-{n_frames}/movie.tif",
                     "mass_flow_rate_g_s": 0.3 + 0.003 * i, "mm_per_px": 0.185})
    manifest = folder / "manifest.csv"
    with open(manifest, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    return manifest


#: the stand-in SLURM commands (sbatch, squeue, scancel) of the tests
FAKE_SLURM = Path(__file__).resolve().parent.parent / "tests" / "fake_slurm"


def slurm_env(queue: Path) -> dict[str, str]:
    """The environment of a batch on the stand-in SLURM: its commands on PATH, its jobs' state in ``queue``."""
    return {"PATH": f"{FAKE_SLURM}{os.pathsep}{os.environ['PATH']}", "FAKE_SLURM_DIR": str(queue),
            "DASK_JOBQUEUE__SLURM__CORES": "1", "DASK_JOBQUEUE__SLURM__MEMORY": "2GB",
            "DASK_JOBQUEUE__SLURM__SCHEDULER_OPTIONS": "{'dashboard_address': None}"}


def job_groups(queue: Path) -> list[int]:
    """The process groups of the stand-in SLURM's jobs still running."""
    alive = []
    for f in queue.glob("*.pid"):
        try:
            os.killpg(int(f.read_text()), 0)
            alive.append(int(f.read_text()))
        except (ProcessLookupError, ValueError):
            pass
    return alive


def batch(manifest: Path, out: Path, workers: int, *, queue: Path | None = None,
          cluster_timeout_s: float | None = None) -> subprocess.Popen:
    where = ["--cluster", "slurm", "--jobs", str(workers)] if queue else ["--workers", str(workers)]
    if queue and cluster_timeout_s:
        where += ["--cluster-timeout", f"{cluster_timeout_s:g}"]
    return subprocess.Popen([sys.executable, "-m", "grainplug", "batch", str(manifest), "--out", str(out),
                             *where, "--no-figures"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "MPLBACKEND": "Agg", **(slurm_env(queue) if queue else {})})


def kill_a_job(queue: Path, out: Path, kills: list[float], t0: float) -> None:
    """SIGKILL of one stand-in job's whole process group: the one writing a run, if any."""
    groups = job_groups(queue)
    if not groups:
        return
    runs = out / "runs"
    writing = []
    for q in runs.glob(".*.grainplug-new-*") if runs.is_dir() else []:
        try:
            writing.append(os.getpgid(int(q.name.rsplit("-", 2)[-2])))
        except (ProcessLookupError, ValueError):
            pass
    victim = next((g for g in writing if g in groups), groups[0])
    try:
        os.killpg(victim, signal.SIGKILL)
        kills.append(time.monotonic() - t0)
    except ProcessLookupError:
        pass


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--kill-every-s", type=float, default=30.0)
    ap.add_argument("--frames", type=int, default=300, help="frames per movie (the runs' length)")
    ap.add_argument("--dir", type=Path, default=Path("/tmp/grainplug-batch-faults"))
    ap.add_argument("--cluster", choices=["slurm"], default=None,
                    help="attack a batch on the stand-in SLURM (jobs killed) instead of the local pool")
    ap.add_argument("--cluster-timeout", type=float, default=None,
                    help="with --cluster: the batch's --cluster-timeout (how long it may go without a worker)")
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    manifest = make_campaign(args.dir / "campaign", args.runs, args.frames)
    quiet, noisy = args.dir / "undisturbed", args.dir / "attacked"
    queue = args.dir / "slurm-queue" if args.cluster else None
    for d in (quiet, noisy, *([queue] if queue else [])):
        subprocess.run(["rm", "-rf", str(d)], check=True)
    t0 = time.monotonic()
    p = batch(manifest, quiet, args.workers)
    out, err = p.communicate()
    log.info("undisturbed: exit %d in %.1f s: %s", p.returncode, time.monotonic() - t0, out.splitlines()[:1])
    t0 = time.monotonic()
    p = batch(manifest, noisy, args.workers, queue=queue, cluster_timeout_s=args.cluster_timeout)
    kills: list[float] = []
    stop = threading.Event()

    def killer() -> None:
        while not stop.wait(args.kill_every_s):
            if queue is not None:
                kill_a_job(queue, noisy, kills, t0)
                continue
            workers = children(p.pid)
            if not workers:
                continue
            runs = noisy / "runs"
            writing = [int(q.name.rsplit("-", 2)[-2]) for q in runs.glob(".*.grainplug-new-*")] if runs.is_dir() else []
            victim = next((w for w in writing if w in workers), workers[0])
            try:
                os.kill(victim, signal.SIGKILL)
                kills.append(time.monotonic() - t0)
            except ProcessLookupError:
                pass

    th = threading.Thread(target=killer)
    th.start()
    out, err = p.communicate()
    stop.set()
    th.join()
    elapsed = time.monotonic() - t0
    if p.returncode != 0 and "no worker left" in err:  # the batch gave up without a worker: the same command again
        log.info("attacked: exit %d after %.1f s, %d jobs killed: %s", p.returncode, elapsed, len(kills), err.strip())
        t1 = time.monotonic()
        again = batch(manifest, noisy, args.workers, queue=queue, cluster_timeout_s=args.cluster_timeout)
        out, err2 = again.communicate()
        log.info("run again, undisturbed: exit %d in %.1f s: %s", again.returncode, time.monotonic() - t1,
                 out.splitlines()[:1])
        err = err + err2
    same = (quiet / "campaign.csv").exists() and (noisy / "campaign.csv").exists() and (
        (quiet / "campaign.csv").read_bytes() == (noisy / "campaign.csv").read_bytes())
    import pandas as pd

    table = pd.read_csv(noisy / "campaign.csv") if (noisy / "campaign.csv").exists() else None
    once = table is not None and table.run.is_unique and len(table) == args.runs
    all_ok = table is not None and set(table.status) == {"ok"}
    log.info("attacked: exit %d in %.1f s, %d %s killed (at %s s)", p.returncode, elapsed, len(kills),
             "jobs" if queue else "workers", ", ".join(f"{k:.0f}" for k in kills))
    if queue is not None:
        time.sleep(2)
        log.info("jobs submitted: %d; jobs left running after the batch: %d", len(list(queue.glob("*.sh"))),
                 len(job_groups(queue)))
    log.info("stderr: %s", err.strip() or "(nothing)")
    log.info("every run once: %s; all ok: %s; table equal to the undisturbed one byte for byte: %s", once, all_ok,
             same)


if __name__ == "__main__":
    main()
