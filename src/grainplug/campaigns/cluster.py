"""Workers as jobs of a cluster's queue (SLURM, PBS, SGE, LSF, HTCondor) through dask-jobqueue.

grainplug adds no settings of its own: the queue, account, cores, memory, walltime,
network interface and extra directives of the jobs come from Dask's configuration
(``~/.config/dask/jobqueue.yaml``, or ``DASK_JOBQUEUE__SLURM__CORES``-style variables),
as dask-jobqueue documents them. This module starts the jobs, waits for the first
worker, and ends every job when the campaign ends, fails, is interrupted (Ctrl-C) or is
terminated (SIGTERM). See docs/cluster.md.
"""

from __future__ import annotations

import contextlib
import logging
import shutil
import signal
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ..errors import GrainplugError, ParameterError

log = logging.getLogger(__name__)

#: the cluster kinds ``--cluster`` takes: dask-jobqueue's class of each, and the command that submits its jobs
CLUSTER_KINDS: dict[str, tuple[str, str]] = {
    "slurm": ("SLURMCluster", "sbatch"),
    "pbs": ("PBSCluster", "qsub"),
    "sge": ("SGECluster", "qsub"),
    "lsf": ("LSFCluster", "bsub"),
    "htcondor": ("HTCondorCluster", "condor_submit"),
}

#: how long, by default, to wait for the first job to start and its worker to join
CLUSTER_TIMEOUT_S = 600.0

#: the one line that says how to get dask-jobqueue
INSTALL_HINT = "pip install 'grainplug[cluster]'"


def check_cluster_kind(kind: str) -> tuple[str, str]:
    """dask-jobqueue's class name and the submit command of ``kind``; a :class:`ParameterError` if unknown."""
    try:
        return CLUSTER_KINDS[kind.lower()]
    except KeyError:
        raise ParameterError(f"unknown cluster kind {kind!r}: one of {', '.join(CLUSTER_KINDS)}",
                             param="cluster") from None


@contextlib.contextmanager
def job_cluster(kind: str, *, jobs: int = 1, timeout_s: float = CLUSTER_TIMEOUT_S) -> Iterator[Any]:
    """A Dask client whose workers are ``jobs`` jobs of the queue ``kind``; every job ends on exit.

    The jobs are kept at ``jobs``: one that the queue ends (walltime, pre-emption) is
    replaced, and the runs it held go to the other workers. On exit, whatever the reason
    (the campaign done, an exception, Ctrl-C, or SIGTERM of this process, turned into
    ``KeyboardInterrupt`` while the cluster is up), the client is closed and every job
    cancelled with the queue's own command (``scancel`` ...).

    Parameters
    ----------
    kind : str
        One of :data:`CLUSTER_KINDS`.
    jobs : int
        Jobs to keep running (each one Dask worker process, with the cores and memory
        of Dask's ``jobqueue.<kind>`` configuration).
    timeout_s : float
        How long to wait for the first worker to join (a job queued longer is a
        :class:`GrainplugError`, and the jobs are cancelled).

    Raises
    ------
    GrainplugError
        dask-jobqueue not installed, the queue's submit command not found, the
        configuration incomplete, or no job started within ``timeout_s``.
    """
    cls_name, submit = check_cluster_kind(kind)
    if jobs < 1:
        raise ParameterError("must be at least 1", param="jobs")
    if not timeout_s > 0:
        raise ParameterError("must be more than 0 s", param="cluster_timeout")
    ctrl_c = signal.getsignal(signal.SIGINT)
    try:
        import dask_jobqueue
        from dask.distributed import Client
    except ImportError:
        raise GrainplugError(f"--cluster needs dask-jobqueue, which is not installed: {INSTALL_HINT}") from None
    finally:
        if threading.current_thread() is threading.main_thread() and ctrl_c is not None:
            # dask-jobqueue's import makes Ctrl-C exit quietly with status 0 (its runner module's handler):
            # it would skip the campaign's message and status 130
            signal.signal(signal.SIGINT, ctrl_c)
    if shutil.which(submit) is None:
        raise GrainplugError(f"cannot find {submit}, the command that submits {kind} jobs, on PATH — run the "
                             f"batch on the cluster's login node (or load the module that provides {submit})")
    try:
        cluster = getattr(dask_jobqueue, cls_name)(**_private(kind))
    except ValueError as exc:  # cores/memory not configured, or a setting it does not take
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise GrainplugError(f"dask-jobqueue cannot set up {kind} jobs ({first}) — set jobqueue.{kind}.cores "
                             f"and .memory (and any queue, account, walltime) in ~/.config/dask/jobqueue.yaml or "
                             f"DASK_JOBQUEUE__{kind.upper()}__CORES=... variables; see docs/cluster.md") from None
    client = None
    restore = _sigterm_interrupts()
    try:
        log.info("job script for %s:\n%s", kind, cluster.job_script())
        cluster.adapt(minimum_jobs=jobs, maximum_jobs=jobs)  # a job that ends is replaced
        client = Client(cluster)
        try:
            client.wait_for_workers(1, timeout=timeout_s)
        except (TimeoutError, OSError):
            raise GrainplugError(f"no {kind} job started within {timeout_s:g} s (queued, or failing at start: "
                                 f"see the queue's job logs) — the jobs were cancelled; try again later, ask for "
                                 f"less (cores, memory, walltime), or give a longer --cluster-timeout") from None
        yield client
    finally:
        if restore is not _nothing:  # a second SIGTERM while the jobs are being cancelled does not cut that short
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
        try:
            if client is not None:
                client.close()
            cluster.close()
            # the certificate's worker half, written for the jobs: closed, so deleted (dask-jobqueue keeps them open)
            for name, held in list(vars(cluster).items()):
                if name.startswith("_job_") and hasattr(held, "close"):
                    held.close()
        finally:
            restore()


def _private(kind: str) -> dict[str, object]:
    """The scheduler answers its own user only: TLS with a certificate made for this campaign
    (``Security.temporary``; a worker proves it holds it, given in files only the user can read, in Dask's
    ``jobqueue.<kind>.shared-temp-directory`` or else ``~/.grainplug-dask``, which the jobs must see), and the
    dashboard on this machine's loopback only (``127.0.0.1``, a free port), unless Dask's configuration says
    otherwise for either."""
    import dask

    opts = dict(dask.config.get(f"jobqueue.{kind}.scheduler-options", {}) or {})
    if not opts.get("dashboard_address"):  # None is Dask's default, every interface's port 8787
        opts["dashboard_address"] = "127.0.0.1:0"
    shared = dask.config.get(f"jobqueue.{kind}.shared-temp-directory", None)
    if not shared:
        folder = Path.home() / ".grainplug-dask"
        folder.mkdir(mode=0o700, exist_ok=True)
        folder.chmod(0o700)
        shared = str(folder)
    return {"security": True, "shared_temp_directory": shared, "scheduler_options": opts}


def _sigterm_interrupts() -> Any:
    """While the cluster is up, SIGTERM of this process (a ``kill``, a job's end) unwinds as Ctrl-C does,
    so the jobs are cancelled; returns what puts the previous handler back. Only in the main thread."""
    if threading.current_thread() is not threading.main_thread():
        return _nothing
    previous = signal.getsignal(signal.SIGTERM)

    def interrupt(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, interrupt)
    return lambda: signal.signal(signal.SIGTERM, previous)


def _nothing() -> None:
    """What there is to restore outside the main thread."""
