"""Run a campaign: analyse every run of a manifest, then tabulate, fit and report.

Each run is analysed as ``grainplug analyze`` would, into ``OUT/runs/<run>/``.
A run's key is a SHA-256 of its movie's identity, its analysis parameters and
the grainplug version; a run whose ``summary.json`` holds the same key is not
analysed again. A run that fails is recorded (status ``failed`` with the error)
and the others go on.

Runs are independent, so they can be spread over processes of this machine
(``workers``) or over a Dask distributed cluster (``scheduler``): the same
function :func:`process_run` is called for each, and the results do not depend
on where it ran.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import socket
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .._atomic import atomic_directory, is_complete
from .._version import __version__
from ..corrections import Corrections, apply_corrections
from ..errors import CampaignInterrupted, GrainplugError, ParameterError
from ..jsonio import dumps
from ..outputs import write_outputs
from ..pipeline import analyze
from ..plotting.files import save_figure
from ..plotting.options import FigureOptions
from ..provenance import fingerprint
from ..result import load_result
from ..store import read_corrections
from ..warning_codes import codes_of
from .cluster import CLUSTER_TIMEOUT_S, job_cluster
from .fits import campaign_fits, fit_line, fit_selection, wide_and_still
from .manifest import RunSpec, read_manifest, run_folder_name
from .model_panel import ModelPanel, measured_from, model_panel
from .schema import SCHEMA_VERSION, schema_json, typed

log = logging.getLogger(__name__)

SUMMARY_COLUMNS = [
    "celerity_m_s", "plug_length_mm", "plug_length_over_diameter", "plug_length_sd_mm",
    "bubble_length_mm", "oscillation_frequency_hz", "oscillation_amplitude_mm", "regime", "has_plugs",
    "n_plugs", "n_frames", "fps", "duration_s", "mm_per_px", "scale_source", "scale_rel_sd", "tube_diameter_px",
    "tube_axis_angle_deg", "flow_direction",
]


def run_key(spec: RunSpec, *, identity: dict[str, object] | None = None) -> str:
    """Identity of a run's result: the movie's content, the parameters, the grainplug version.

    The movie enters by its size and sampled content hash (:func:`grainplug.provenance.fingerprint`),
    not its path or modification time: a campaign copied to another drive is still done.
    """
    ident = identity if identity is not None else fingerprint(spec.movie)
    content = {k: ident.get(k) for k in ("bytes", "files", "sha256_sampled")}
    params = spec.params.as_record()
    if isinstance(params.get("calibration"), dict):  # its content counts, not where its file is
        params["calibration"] = {k: v for k, v in params["calibration"].items() if k != "source"}
    blob = json.dumps({"input": content, "params": params, "version": __version__},
                      sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()


def process_run(spec: RunSpec, out_dir: str, *, figures: bool = True, threads: int | None = None,
                verify: bool = False, figure_options: FigureOptions | None = None) -> dict[str, object]:
    """Analyse one run into ``out_dir/runs/<run>`` (or reuse it); a record for the table.

    A run is reused only when its folder is complete (its completion marker lists every file,
    :func:`grainplug._atomic.is_complete`) and its summary holds the same :func:`run_key`; with
    ``verify``, also the same SHA-256 of every byte of the movie (a run analysed without it is
    analysed again, once). ``threads``: reading threads of the analysis (see
    :func:`grainplug.analyze`); 1 where runs already go in parallel. The record's ``reused``
    says whether the run was taken from an earlier batch (it is not a column of the table).
    """
    run_dir = Path(out_dir) / "runs" / run_folder_name(spec.run)
    record: dict[str, object] = {"run": spec.run, "movie": str(spec.movie), **spec.meta}
    try:
        ident = fingerprint(spec.movie, full=verify)
        key = run_key(spec, identity=ident)
    except OSError as exc:
        fix = ("no such file or folder — check the movie column (relative to the manifest's folder)"
               if isinstance(exc, FileNotFoundError) else f"{exc.strerror or exc} — check that it can be read")
        return {**record, "status": "failed", "error": f"cannot read {spec.movie}: {fix}"}
    except GrainplugError as exc:
        return {**record, "status": "failed", "error": str(exc)}
    record["run_key"] = key
    extra = {"batch": {"run": spec.run, "run_key": key, "meta": spec.meta, "input_sha256": ident.get("sha256")}}
    try:
        corr = read_corrections(run_dir)  # a reviewer's corrections of this run, honoured below
    except GrainplugError as exc:
        return {**record, "status": "failed", "error": str(exc)}
    if is_complete(run_dir):
        try:
            old = json.loads((run_dir / "summary.json").read_text())
        except (OSError, json.JSONDecodeError):
            old = {}
        done = old.get("batch") or {}
        if done.get("run_key") == key and (not verify or done.get("input_sha256") == ident["sha256"]):
            wanted = corr.as_dict()["edits"] if corr is not None else []
            same_figures = not figures or old.get("figures") == (figure_options or FigureOptions()).as_record()
            same_meta = done.get("meta") == json.loads(dumps(spec.meta))  # as the summary holds it
            changed = (old.get("corrections_applied") or []) != wanted
            if not changed and same_figures and same_meta:
                return {**record, "status": "ok", "reused": True, **_flat(old)}
            try:  # the corrections, the figures' options or the manifest's metadata changed since: written again
                # from the saved result (measured again from the detected plugs if the corrections changed)
                res = load_result(run_dir)
                if changed:
                    res = apply_corrections(res, corr or Corrections())
                # a batch without figures keeps those the run has, drawn again as they were
                draw = figures or isinstance(old.get("figures"), dict)
                write_outputs(res, run_dir, figures=draw, report=draw, extra=extra,
                              figure_options=figure_options if figures else FigureOptions.recorded(old))
                return {**record, "status": "ok", "reused": True, "remeasured": changed, **_flat(res.summary)}
            except GrainplugError:
                pass  # an unreadable result: analyse again below
    try:
        res = analyze(spec.movie, spec.params, threads=threads)
        if corr is not None:  # edits that keep where their tracks were are checked there; the file is kept
            res = apply_corrections(res, corr, reanalysed=True)
        write_outputs(res, run_dir, figures=figures, report=figures, extra=extra, figure_options=figure_options)
        return {**record, "status": "ok", "reused": False, **_flat(res.summary)}
    except GrainplugError as exc:
        return {**record, "status": "failed", "error": str(exc)}
    except Exception as exc:  # a bug in one run must not stop the campaign
        log.exception("run %s failed", spec.run)
        return {**record, "status": "failed", "error": f"unexpected {type(exc).__name__}: {exc}"}


def weighed_disagrees(rec: dict) -> list[str]:
    """A warning when a run's weighed mass flow rate (the manifest's ``mass_flow_rate_g_s``) lies outside the 95 %
    interval of the one measured from its movie: the frame rate, the scale, the bore, the references' compactness
    or the grains' density given may be wrong, or the flow was not steady while it was weighed."""
    weighed, lo, hi = (rec.get(k) for k in ("mass_flow_rate_g_s", "mass_flow_rate_images_ci95_low_g_s",
                                            "mass_flow_rate_images_ci95_high_g_s"))
    try:
        weighed, lo, hi = float(weighed), float(lo), float(hi)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return []
    if not all(np.isfinite([weighed, lo, hi])) or lo <= weighed <= hi:
        return []
    from ..warning_codes import coded

    mid = 0.5 * (lo + hi)
    return [coded("mass_flow.disagrees",
                  f"the weighed mass flow rate ({weighed:.3g} g/s) is outside the 95 % interval of the one measured "
                  f"from the movie ({lo:.3g} to {hi:.3g} g/s, {100.0 * (mid / weighed - 1.0):+.0f} %): check the "
                  "frame rate, the scale, the bore, the packed reference's compactness and the grains' density "
                  "given, and that the flow was steady while it was weighed")]


def _flat(summary: dict) -> dict[str, object]:
    out = {k: summary.get(k) for k in SUMMARY_COLUMNS}
    ci = summary.get("celerity_ci95_m_s") or [None, None]
    lci = summary.get("plug_length_ci95_mm") or [None, None]
    qci = summary.get("mass_flow_rate_ci95_g_s") or [None, None]
    out.update(mass_flow_rate_images_g_s=summary.get("mass_flow_rate_g_s"),
               mass_flow_rate_images_ci95_low_g_s=qci[0], mass_flow_rate_images_ci95_high_g_s=qci[1])
    out.update(celerity_ci95_low_m_s=ci[0], celerity_ci95_high_m_s=ci[1],
               plug_length_ci95_low_mm=lci[0], plug_length_ci95_high_mm=lci[1],
               input_sha256_sampled=(summary.get("input") or {}).get("sha256_sampled"),
               input_bytes=(summary.get("input") or {}).get("bytes"),
               grainplug_version=summary.get("grainplug_version"),
               warnings=" | ".join(summary.get("warnings") or []) or None,
               warning_codes=" | ".join(summary.get("warning_codes") or []) or None,
               n_corrections=len(summary.get("corrections") or []))
    return out


@dataclass(frozen=True)
class Campaign:
    """The campaign table, its fits and where it was written."""

    table: pd.DataFrame
    fits: dict[str, dict]
    out_dir: Path
    n_failed: int
    n_reused: int = 0
    #: of the reused runs, those measured again from their saved detection (their corrections changed)
    n_remeasured: int = 0
    #: worker processes that died (of this machine's pool, or a Dask client's workers lost while they held runs,
    #: such as a cluster's job killed by its queue); their runs were started again
    worker_deaths: int = 0
    #: folders under ``runs/`` of runs the manifest no longer lists (kept, not in the campaign)
    stale_runs: tuple[str, ...] = ()
    #: with a Dask client: the workers (``host:pid``) that analysed the runs, across every job
    workers_used: tuple[str, ...] = ()

    @property
    def run_warnings(self) -> list[tuple[str, str]]:
        """``(run, warning)`` for every warning of every run (its analysis's, its manifest row's), in order."""
        if "warnings" not in self.table:
            return []
        return [(str(run), w) for run, ws in zip(self.table["run"], self.table["warnings"], strict=True)
                if isinstance(ws, str) for w in ws.split(" | ") if w]

    @property
    def warnings(self) -> list[str]:
        """What the campaign cannot vouch for, a line each: failed runs and why, every run's warnings, run
        folders left out; what ``grainplug batch`` prints."""
        out = []
        if "error" in self.table:
            failed = self.table[self.table.status == "failed"]
            out += [f"run {run} failed: {err}" for run, err in zip(failed["run"], failed["error"], strict=True)]
        out += [f"run {run}: {w}" for run, w in self.run_warnings]
        if self.stale_runs:
            out.append(f"{len(self.stale_runs)} run folder(s) under {self.out_dir / 'runs'} are no longer in the "
                       f"manifest ({', '.join(self.stale_runs)}): kept, but left out of the campaign")
        if self.worker_deaths:
            out.append(f"{self.worker_deaths} worker process(es) died during the batch (killed, or out of memory); "
                       "their runs were started again")
        return out


def run_campaign(manifest: str | Path, out_dir: str | Path, *, workers: int = 1, scheduler: str | None = None,
                 client: Any = None, cluster: str | None = None, jobs: int = 1,
                 cluster_timeout_s: float = CLUSTER_TIMEOUT_S,
                 figures: bool = True, verify: bool = False, simulate: bool = True,
                 figure_options: FigureOptions | None = None,
                 progress: Callable[[int, int, str], None] | None = None) -> Campaign:
    """Analyse every run of ``manifest`` and write the campaign's table, fits, figures and report.

    Parameters
    ----------
    manifest : path
        CSV or TOML manifest (:mod:`grainplug.campaigns.manifest`).
    out_dir : path
        Destination; runs go to ``out_dir/runs/<run>/``.
    workers : int
        Processes on this machine (1: in this process).
    scheduler : str, optional
        Address of a Dask distributed scheduler (``tcp://host:8786``); overrides ``workers``.
    client : dask.distributed.Client, optional
        Any Dask client (a ``LocalCluster``'s, Kubernetes, a cloud cluster, dask-jobqueue's): the runs
        go to its workers. It is left open: whoever made it closes it. Overrides ``workers``.
    cluster : {'slurm', 'pbs', 'sge', 'lsf', 'htcondor'}, optional
        Start the workers as ``jobs`` jobs of this queue through dask-jobqueue, with the settings of
        Dask's ``jobqueue.<cluster>`` configuration (:func:`grainplug.campaigns.cluster.job_cluster`);
        every job is cancelled when the campaign ends, fails or is interrupted.
    jobs : int
        With ``cluster``, the jobs kept running (one that the queue ends is replaced).
    cluster_timeout_s : float
        With ``cluster``, how long to wait for the first job to start.
    figures : bool
        Figures and HTML reports, per run and for the campaign.
    verify : bool
        Reuse a run only if every byte of its movie hashes as when it was analysed
        (reads every movie whole); otherwise its size and sampled content must match.
    simulate : bool
        With figures, the report's model-against-experiment panel includes the
        nonlinear simulations (about 4 s); otherwise linear theory only.
    figure_options : FigureOptions, optional
        Resolution and formats of every figure (by default PNG at 200 dpi;
        ``grainplug.outputs.PUBLICATION`` adds SVG and PDF).
    progress : callable, optional
        ``progress(done, total, run)`` after each run.

    Raises
    ------
    CampaignInterrupted
        On Ctrl-C: queued runs are not started, running ones are stopped (their
        temporary folders are removed, now or by the next batch), finished ones stay.

    Notes
    -----
    Every run is done or not started whatever happens to the batch: a run's folder is
    swapped in whole with a completion marker, and only a complete folder with the same
    key is reused, so a batch killed at any point and run again gives the same table as one
    never interrupted. Worker processes ignore Ctrl-C (the batch stops them) and end when
    the batch's process ends, even if it was killed.
    """
    from .._atomic import check_output_place

    specs = read_manifest(manifest)
    inputs = [Path(manifest), *(f for s in specs for f in _spec_inputs(s))]
    out = check_output_place(out_dir, inputs=inputs, replace=False, kind="campaign")
    _refuse_inputs_in_campaign(out, inputs)
    if workers < 1:
        raise ParameterError("must be at least 1", param="workers")
    if sum(x is not None for x in (scheduler, client, cluster)) > 1:
        raise ParameterError("give one of scheduler, client and cluster", param="cluster" if cluster else "client")
    with contextlib.ExitStack() as stack:
        # refuse an unreachable scheduler, or a queue that starts no job, before writing
        if cluster is not None:
            client = stack.enter_context(job_cluster(cluster, jobs=jobs, timeout_s=cluster_timeout_s))
        elif scheduler:
            client = _dask_client(scheduler)
            stack.callback(client.close)
        return _run_campaign(specs, Path(manifest), out, client=client, workers=workers, figures=figures,
                             idle_limit_s=cluster_timeout_s if cluster else None,
                             verify=verify, simulate=simulate, figure_options=figure_options, progress=progress,
                             release=stack.close)
    raise AssertionError("unreachable")  # pragma: no cover  (for type checkers: the with returns)


def _run_campaign(specs: list[RunSpec], manifest: Path, out: Path, *, client: Any, workers: int, figures: bool,
                  verify: bool, simulate: bool, figure_options: FigureOptions | None,
                  progress: Callable[[int, int, str], None] | None,
                  release: Callable[[], object] = lambda: None, idle_limit_s: float | None = None) -> Campaign:
    """:func:`run_campaign` once its inputs are checked and its workers are there (``client``, or ``workers``);
    ``release`` lets the workers go (a cluster's jobs end) once every run is done, before the tables and report;
    with ``idle_limit_s``, a client left with no worker for that long (its jobs killed and not started again)
    ends the batch, the runs done kept."""
    from .._atomic import OutputPlaceError, mark_campaign

    try:
        out.mkdir(parents=True, exist_ok=True)
        mark_campaign(out)
    except OSError as exc:
        raise OutputPlaceError(f"cannot create {out}: {exc.strerror or exc} — choose another output folder") from None
    records: dict[str, dict] = {}
    total = len(specs)

    def done(rec: dict) -> None:
        records[str(rec["run"])] = rec
        if progress:
            progress(len(records), total, str(rec["run"]))

    kw = {"figures": figures, "verify": verify, "figure_options": figure_options}
    deaths = 0
    hosts: set[str] = set()
    try:
        if client is not None:
            deaths = _on_client(client, specs, str(out), done=done, hosts=hosts, idle_limit_s=idle_limit_s, **kw)
        elif workers > 1:
            deaths = _in_pool(specs, str(out), workers=workers, done=done, **kw)
        else:
            for s in specs:
                done(process_run(s, str(out), **kw))
    except NoWorkerLeft as exc:
        n_done = sum(is_complete(out / "runs" / run_folder_name(s.run)) for s in specs)
        raise NoWorkerLeft(f"{exc} — {n_done} of {total} runs have a complete result, kept; run the same command "
                           "again to finish (complete, current runs are reused)") from None
    except KeyboardInterrupt:
        n_done = sum(is_complete(out / "runs" / run_folder_name(s.run)) for s in specs)
        raise CampaignInterrupted(
            f"interrupted: {n_done} of {total} runs have a complete result, kept; the others were not started "
            "or were stopped — run the same command again to finish (complete, current runs are reused)") from None
    release()  # no job holds the queue while the tables, fits and report are written
    for s in specs:  # the manifest's own doubts about a row come first among the run's warnings
        rec = records[s.run]
        more = [*s.warnings, *weighed_disagrees(rec)]
        if more:
            rec["warnings"] = " | ".join([*more, *filter(None, [rec.get("warnings")])])
            rec["warning_codes"] = " | ".join([*codes_of(more), *filter(None, [rec.get("warning_codes")])])
    n_reused = sum(bool(records[s.run].get("reused")) for s in specs)
    n_remeasured = sum(bool(records[s.run].get("remeasured")) for s in specs)
    table = typed(pd.DataFrame([{k: v for k, v in records[s.run].items() if k not in ("reused", "remeasured")}
                                for s in specs]))
    try:
        fits = campaign_fits(table)
        _write_campaign(table, fits, out, manifest=manifest, figures=figures, simulate=simulate,
                        figure_options=figure_options)
    except KeyboardInterrupt:  # the campaign's files are renamed into place one by one: some may be new
        n_done = sum(is_complete(out / "runs" / run_folder_name(s.run)) for s in specs)
        raise CampaignInterrupted(
            f"interrupted while writing the campaign's tables and report: {n_done} of {total} runs have a complete "
            "result, kept; the campaign's own files may be part of this batch and part of the one before — run the "
            "same command again to write them all (complete, current runs are reused)") from None
    listed = {run_folder_name(s.run) for s in specs}
    runs_dir = out / "runs"
    stale = tuple(sorted(q.name for q in runs_dir.iterdir()
                         if q.is_dir() and not q.name.startswith(".") and q.name not in listed)
                  if runs_dir.is_dir() else ())
    return Campaign(table, fits, out, int((table.status == "failed").sum()), n_reused, n_remeasured, deaths,
                    stale, tuple(sorted(hosts)))


#: how long to wait for a Dask scheduler before saying it cannot be reached
SCHEDULER_TIMEOUT_S = 3


def _dask_client(address: str):
    try:
        from dask.distributed import Client
    except ImportError:
        raise GrainplugError("scheduler= needs Dask: pip install 'grainplug[dask]'") from None
    import socket
    from urllib.parse import urlsplit

    where = urlsplit(address if "://" in address else f"tcp://{address}")
    try:
        if where.scheme in ("tcp", "tls") and where.hostname and where.port:
            # dask retries a refused connection until its timeout, and waits for ever on a service
            # that never answers (a web server): ask the port once first; a scheduler speaks first
            with socket.create_connection((where.hostname, where.port), timeout=SCHEDULER_TIMEOUT_S) as sock:
                if where.scheme == "tcp" and not sock.recv(1):
                    raise ConnectionResetError("closed at once")
    except (OSError, TimeoutError, ValueError) as exc:
        raise GrainplugError(f"cannot reach the Dask scheduler at {address} within {SCHEDULER_TIMEOUT_S} s "
                             f"({type(exc).__name__}) — check the address and that the scheduler is running") from None
    try:
        return Client(address, timeout=f"{SCHEDULER_TIMEOUT_S}s")
    except Exception as exc:  # something answers there, but not a Dask scheduler (a web page, another service)
        raise GrainplugError(f"no Dask scheduler answered at {address} ({type(exc).__name__}) — check the "
                             "address and port (the scheduler's, usually 8786, not its dashboard's)") from None


def _remote_run(spec: RunSpec, out_dir: str, **kw: object) -> dict[str, object]:
    """:func:`process_run` on a Dask worker: the record, with which worker ran it (``_worker``, not a column);
    a movie or output folder this worker's machine cannot see fails the run with its host named."""
    import os.path

    host = socket.gethostname()
    if not Path(out_dir).is_dir():
        return {"run": spec.run, "movie": str(spec.movie), **spec.meta, "status": "failed",
                "_worker": f"{host}:{os.getpid()}",
                "error": f"the campaign's folder {out_dir} cannot be seen on host {host} — the output folder must be "
                         "on a filesystem every worker's machine mounts, at the same path"}
    record = process_run(spec, out_dir, threads=1, **kw)
    if record.get("status") == "failed" and not os.path.exists(spec.movie):
        record["error"] = (f"cannot see {spec.movie} on host {host} — the movies must be on a filesystem every "
                           "worker's machine mounts, at the same path as in the manifest")
    return {**record, "_worker": f"{host}:{os.getpid()}"}


def _on_client(client: Any, specs: list[RunSpec], out: str, *, done: Callable[[dict], None], hosts: set[str],
               idle_limit_s: float | None = None, **kw: object) -> int:
    """The runs on a Dask client's workers; returns how many workers died while they held runs.

    A worker lost during a run (its job killed by the queue, its machine gone) has its runs
    started again on another worker by Dask itself (``distributed.scheduler.allowed-failures``
    times); a run whose workers keep dying is failed with the reason, and the others go on. A
    result is let go of as soon as it is read, so a worker lost later costs no finished run.
    With ``idle_limit_s``, the client having had no worker at all for that long (every job
    killed and none started again: the queue full, or the jobs failing at start) is a
    :class:`NoWorkerLeft`, the runs not done cancelled.
    """
    from dask.distributed import as_completed as dask_completed
    from distributed import KilledWorker

    futures = {client.submit(_remote_run, s, out, pure=False, key=f"grainplug-run-{i}-{s.run}", **kw): s
               for i, s in enumerate(specs)}
    keys = {str(f.key) for f in futures}
    before = {s.run: _sealed_at(Path(out) / "runs" / run_folder_name(s.run)) for s in specs}
    try:
        idle = _Idle(client, idle_limit_s)
        for fut in _completed(dask_completed(list(futures)), idle):
            spec = futures.pop(fut)
            try:
                rec = _result(fut, idle)
            except KilledWorker:
                rec = {"run": spec.run, "movie": str(spec.movie), **spec.meta, "status": "failed",
                       "error": "every worker that analysed this run died during it (its jobs killed, out of "
                                "memory, or a crash in a reader) — try this movie alone with grainplug analyze "
                                "--debug, or ask for more memory per job"}
            except Exception as exc:  # the worker's side failed outside the run (cannot unpickle, ...)
                rec = {"run": spec.run, "movie": str(spec.movie), **spec.meta, "status": "failed",
                       "error": f"the Dask worker failed: {type(exc).__name__}: {exc}"}
            fut.release()
            del fut
            if rec.get("reused") and before[spec.run] is None:
                rec["reused"] = False  # done in this batch by a worker lost before its result was read, then found
            worker = rec.pop("_worker", None)
            if worker:
                hosts.add(str(worker))
            done(rec)
    except BaseException:
        client.cancel(list(futures), force=True)
        raise
    from .._atomic import recover

    for s in specs:  # what workers killed mid-run left (a retry that started before the dead one was reaped
        recover(Path(out) / "runs" / run_folder_name(s.run))  # keeps it): every run is done, none is writing
    return _workers_lost(client, keys)


class NoWorkerLeft(GrainplugError):
    """A cluster's client had no worker for longer than the batch allows."""


#: how often the futures and the client's workers are looked at while waiting for results (s)
_POLL_S = 0.2


class _Idle:
    """Watches a Dask client's workers: :meth:`check` raises :class:`NoWorkerLeft` once the client has had no
    worker for longer than ``limit_s`` (never with ``limit_s`` None)."""

    def __init__(self, client: Any, limit_s: float | None) -> None:
        self.client, self.limit_s = client, limit_s
        self.since: float | None = None
        self.checked = -np.inf

    def check(self) -> None:
        now = time.monotonic()
        if self.limit_s is None or now - self.checked < 1.0:  # the scheduler is asked at most once a second
            return
        self.checked = now
        if self.client.nthreads():
            self.since = None
        elif self.since is None:
            self.since = now
        elif now - self.since > self.limit_s:
            raise NoWorkerLeft(f"no worker left for {self.limit_s:g} s: every job ended and none started again "
                               "(the queue full or the jobs failing at start: see the queue's job logs)")


def _completed(pending: Any, idle: _Idle) -> Iterator[Any]:
    """The futures of Dask's ``as_completed`` ``pending`` as they finish, ``idle`` checked while none is."""
    if idle.limit_s is None:
        yield from pending
        return
    while not pending.is_empty():
        if pending.has_ready():
            yield from pending.next_batch(block=False)
            continue
        idle.check()
        time.sleep(_POLL_S)


def _result(fut: Any, idle: _Idle) -> Any:
    """``fut``'s result, ``idle`` checked while it is awaited (a finished run whose worker died before its
    result was read is run again, and waits for a worker)."""
    if idle.limit_s is None:
        return fut.result()
    while True:
        try:
            return fut.result(timeout=1.0)
        except TimeoutError:  # Dask's is Python's
            idle.check()


def _sealed_at(run_dir: Path) -> int | None:
    """When ``run_dir``'s completion marker was written (ns), or None: tells a run done by this batch from one
    reused from an earlier batch."""
    from .._atomic import MARKER

    try:
        return (run_dir / MARKER).stat().st_mtime_ns
    except OSError:
        return None


def _workers_lost(client: Any, keys: set[str]) -> int:
    """How many workers the scheduler lost, unexpectedly, while they held some of ``keys`` (0 if it cannot say)."""
    try:
        events = client.get_events("all")
    except Exception:  # a scheduler that keeps no such log
        return 0
    lost = set()
    for _, ev in events:
        if isinstance(ev, dict) and ev.get("action") == "remove-worker" and not ev.get("expected"):
            held = {str(k) for k in ev.get("processing-tasks") or ()}
            if held & keys:
                lost.add(ev.get("worker"))
    return len(lost)


class _Stop(SystemExit):
    """Raised in a worker by SIGTERM during a run: unwinds (temporary folders removed), then the worker ends."""


class _StopOnTerm:
    """A worker's SIGTERM handler, and the state of its stop.

    Idle (between runs, or in the executor's own code), the worker ends at once: it has
    nothing to clean, and an exception raised there would be caught by the executor and
    sent to the batch as a run's result. During a run, :class:`_Stop` unwinds it so the
    run's temporary folder is removed. Only the first SIGTERM acts: the executor terminates
    every worker again when one of them ends, and a second exception raised while the
    first unwinds would cut the removal short.
    """

    def __init__(self) -> None:
        self.in_run = False
        self.stopping = False

    def __call__(self, signum: int, frame: object) -> None:
        if self.stopping:
            return
        self.stopping = True
        if not self.in_run:
            os._exit(143)
        raise _Stop(143)


def _worker_start(parent_pid: int) -> None:
    """In each worker process: ignore Ctrl-C (the batch decides), stop cleanly on SIGTERM, and
    end when the batch's process is gone (killed: its workers must not wait for work forever)."""
    import signal
    import threading
    import time

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _StopOnTerm())

    def watch() -> None:  # ends with the worker's main thread, or stops the worker when orphaned
        main = threading.main_thread()
        while main.is_alive():
            if os.getppid() != parent_pid:
                os.kill(os.getpid(), signal.SIGTERM)
                return
            time.sleep(0.5)

    threading.Thread(target=watch, name="grainplug-parent-watch").start()


def _worker_run(spec: RunSpec, out_dir: str, **kw: object) -> dict[str, object]:
    import signal

    stop = signal.getsignal(signal.SIGTERM)
    if not isinstance(stop, _StopOnTerm):  # not in a worker started by _worker_start
        return process_run(spec, out_dir, threads=1, **kw)
    try:  # the flag inside the try: a stop caught at any point of the run is handled here, not by the pool
        stop.in_run = True
        record = process_run(spec, out_dir, threads=1, **kw)
        stop.in_run = False  # before the finally: a stop from here on finds the worker idle
        return record
    except _Stop:
        from .._atomic import recover

        # the run unwound (its temporary folder removed); also what a stop between the folder's
        # creation and its cleanup block left
        recover(Path(out_dir) / "runs" / run_folder_name(spec.run))
        os._exit(143)
    finally:
        stop.in_run = False
        if stop.stopping:  # a stop swallowed on the way (by a library's handler): end now all the same
            os._exit(143)


def _in_pool(specs: list[RunSpec], out: str, *, workers: int, done: Callable[[dict], None],
             **kw: object) -> int:
    """Runs in a pool of processes; returns how many worker processes died.

    A worker that dies (killed, out of memory, a crash in a decoder) breaks the pool: the
    runs not finished go to a new pool. If pools keep breaking with no run finished in
    between, a run is taking its worker down: the rest go one process each, and a run whose
    process dies twice is failed with the reason. On Ctrl-C, queued runs are dropped and
    running ones stopped.
    """
    remaining, deaths, stalled = list(specs), 0, 0
    while remaining:
        if stalled >= 2:  # find the run that kills its worker: one process per run, two tries each
            for spec in remaining:
                for _ in range(2):
                    finished, broken = _pool_pass([spec], out, workers=1, done=done, **kw)
                    deaths += broken
                    if finished:
                        break
                else:
                    done({"run": spec.run, "movie": str(spec.movie), **spec.meta, "status": "failed",
                          "error": "the process analysing this run died twice (out of memory, or a crash in a "
                                   "reader) — try this movie alone with grainplug analyze --debug"})
            return deaths
        finished, broken = _pool_pass(remaining, out, workers=workers, done=done, **kw)
        remaining = [s for s in remaining if s.run not in finished]
        if not broken:
            break
        deaths += 1
        stalled = 0 if finished else stalled + 1
        log.warning("a worker process died; %d runs left go to new workers", len(remaining))
    return deaths


def _pool_pass(specs: list[RunSpec], out: str, *, workers: int, done: Callable[[dict], None],
               **kw: object) -> tuple[set[str], bool]:
    """One pool over ``specs``: the runs finished, and whether a worker died (the pool broke)."""
    from concurrent.futures.process import BrokenProcessPool

    pool = ProcessPoolExecutor(max_workers=workers, initializer=_worker_start, initargs=(os.getpid(),))
    finished: set[str] = set()
    try:
        futures = {pool.submit(_worker_run, s, out, **kw): s for s in specs}
        for fut in as_completed(futures):
            try:
                rec = fut.result()
            except BrokenProcessPool:
                _stop(pool)
                return finished, True
            finished.add(futures[fut].run)
            done(rec)
    except BaseException:
        _stop(pool)
        raise
    pool.shutdown(wait=True)
    return finished, False


#: the files a campaign writes at its folder's top, replaced one by one at each batch (its figures too)
CAMPAIGN_FILES = ("campaign.csv", "campaign.parquet", "campaign.schema.json", "fits.json", "report.html")
#: suffixes of the campaign's figures (written at the folder's top)
FIGURE_SUFFIXES = (".png", ".svg", ".pdf")


def _spec_inputs(spec: RunSpec) -> list[Path]:
    """The files one run reads: its movie, calibration file and background."""
    from ..outputs import input_files

    return [Path(f) for f in input_files(spec.movie, spec.params)]


def _refuse_inputs_in_campaign(out: Path, inputs: list[Path]) -> None:
    """A campaign replaces ``runs/*`` whole and its own files at the top: no input may be among them."""
    top = out.expanduser().resolve()
    for src in inputs:
        s = src.expanduser().resolve()
        written = (s.parent == top and (s.name in CAMPAIGN_FILES or s.suffix.lower() in FIGURE_SUFFIXES))
        if written or (top / "runs") in s.parents:
            from .._atomic import OutputPlaceError

            raise OutputPlaceError(f"{src} is where the campaign writes its own outputs in {out} — move it out of "
                                   "the way, or give another --out (nothing was written)")


def _stop(pool: ProcessPoolExecutor) -> None:
    """End a pool's workers now (SIGTERM: a run in progress removes its temporary folder).

    The workers are stopped before anything else: the executor then fails the queued runs
    itself (cancelling them here as well races with it, and its thread prints a traceback
    on Python 3.11).
    """
    procs = list((getattr(pool, "_processes", None) or {}).values())  # no public way to stop them
    for proc in procs:
        if proc.is_alive():
            proc.terminate()
    for proc in procs:
        proc.join(timeout=10)
    pool.shutdown(wait=False, cancel_futures=True)


def _write_campaign(table: pd.DataFrame, fits: dict, out: Path, *, manifest: Path, figures: bool,
                    simulate: bool = True, figure_options: FigureOptions | None = None) -> None:
    with atomic_directory(out, kind="campaign") as tmp:
        table = typed(table)
        table.to_csv(tmp / "campaign.csv", index=False)
        (tmp / "campaign.schema.json").write_text(schema_json(table))
        pq = table.copy()
        for col in pq.columns:  # parquet needs one type per column (manifest metadata of mixed types)
            if pq[col].dtype == object:
                pq[col] = pq[col].map(lambda v: None if v is None or (isinstance(v, float) and np.isnan(v)) else str(v))
        import pyarrow as pa
        import pyarrow.parquet as pq_io

        arrow = pa.Table.from_pandas(pq, preserve_index=False)
        arrow = arrow.replace_schema_metadata({**(arrow.schema.metadata or {}),
                                               b"grainplug_schema_version": str(SCHEMA_VERSION).encode()})
        pq_io.write_table(arrow, tmp / "campaign.parquet")
        meta = {"grainplug_version": __version__, "schema_version": SCHEMA_VERSION, "manifest": str(manifest.resolve()),
                "manifest_sha256": hashlib.sha256(manifest.read_bytes()).hexdigest(), "fits": fits}
        panel = _model_panel(table, simulate=simulate) if figures else None
        if panel is not None:
            meta["model_vs_experiment"] = panel.as_dict()
        (tmp / "fits.json").write_text(dumps(meta))
        names: list[str] = []
        if figures:
            names = _campaign_figures(table, tmp, figure_options)
            if panel is not None:
                import matplotlib.pyplot as plt

                from ..plotting.model_panel import plot_model_panel

                fig = plot_model_panel(panel.measured, panel.predictions, diameter_mm=panel.diameter_mm)
                save_figure(fig, tmp, MODEL_FIGURE, figure_options)
                plt.close(fig)
            from .report import campaign_report

            (tmp / "report.html").write_text(campaign_report(table, fits, tmp, names, meta, panel=panel))


#: the model-against-experiment figure of a campaign
MODEL_FIGURE = "model_vs_experiment.png"


def _model_panel(table: pd.DataFrame, *, simulate: bool) -> ModelPanel | None:
    """The campaign's measurements against the model (with the pipe diameter of its runs), or None
    without a measured celerity."""
    ok = table[table.status == "ok"] if "status" in table else table
    ok = ok[~wide_and_still(ok)]  # celerities that say nothing of the speed: left out, as from the fits
    if "celerity_m_s" not in ok or not np.isfinite(ok.celerity_m_s.to_numpy(float)).any():
        return None
    d = ok["tube_diameter_mm"].to_numpy(float) if "tube_diameter_mm" in ok else np.array([])
    d = d[np.isfinite(d)]
    diameter_mm = float(np.median(d)) if len(d) else 3.0
    bubbles = ok["bubble_length_mm"].to_numpy(float) if "bubble_length_mm" in ok else None
    measured = measured_from(ok.celerity_m_s.to_numpy(float), ok.plug_length_mm.to_numpy(float), bubbles,
                             source=f"this campaign, {diameter_mm:g} mm pipe")
    return model_panel(measured, diameter_mm=diameter_mm, simulate=simulate)


def _campaign_figures(table: pd.DataFrame, folder: Path, options: FigureOptions | None = None) -> list[str]:
    import matplotlib.pyplot as plt

    from ..plotting.campaign import plot_vs_mass_flow

    ok, _ = fit_selection(table)
    if ok.empty:
        return []
    names = []
    for y, label, fname, ref, ci in (
            ("celerity_m_s", "celerity c (m s⁻¹)", "celerity_vs_mass_flow.png", None,
             ("celerity_ci95_low_m_s", "celerity_ci95_high_m_s")),
            ("plug_length_mm", "plug length λ (mm)", "length_vs_mass_flow.png", 30.0,
             ("plug_length_ci95_low_mm", "plug_length_ci95_high_mm"))):
        rows = ok[ok.fit_celerity] if y == "celerity_m_s" else ok

        def col(frame: pd.DataFrame, name: str) -> np.ndarray:
            return frame[name].to_numpy(dtype=float, na_value=np.nan)

        data = {g: (col(s, "mass_flow_rate_g_s"), col(s, y)) for g, s in rows.groupby("fit_group")}
        errs = {g: (col(s, ci[0]), col(s, ci[1])) for g, s in rows.groupby("fit_group") if ci[0] in s and ci[1] in s}
        fits = {g: fit_line(*xy) for g, xy in data.items()}
        what = "celerity" if y.startswith("celerity") else "plug length"
        fig = plot_vs_mass_flow(data, fits, ylabel=label, title=f"{what} against mass flow rate (95 % intervals)",
                                hline=ref, hline_label="10 D" if ref else "", errors=errs)
        save_figure(fig, folder, fname, options)
        plt.close(fig)
        names.append(fname)
    return names
