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

import hashlib
import json
import logging
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .._atomic import atomic_directory
from .._version import __version__
from ..errors import GrainplugError
from ..jsonio import dumps
from ..outputs import write_outputs
from ..pipeline import analyze, fingerprint
from .fits import fit_line, summarize_lengths
from .manifest import RunSpec, read_manifest, run_folder_name

log = logging.getLogger(__name__)

SUMMARY_COLUMNS = [
    "celerity_m_s", "plug_length_mm", "plug_length_over_diameter", "plug_length_sd_mm",
    "bubble_length_mm", "oscillation_frequency_hz", "oscillation_amplitude_mm", "regime", "has_plugs",
    "n_plugs", "n_frames", "fps", "duration_s", "mm_per_px", "scale_source", "scale_rel_sd", "tube_diameter_px",
    "tube_axis_angle_deg", "flow_direction",
]


def run_key(spec: RunSpec) -> str:
    """Identity of a run's result: movie identity, parameters, grainplug version."""
    ident = fingerprint(spec.movie)
    ident.pop("path", None)
    blob = json.dumps({"input": ident, "params": spec.params.as_record(), "version": __version__},
                      sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()


def process_run(spec: RunSpec, out_dir: str, *, figures: bool = True,
                threads: int | None = None) -> dict[str, object]:
    """Analyse one run into ``out_dir/runs/<run>`` (or reuse it); a record for the table.

    ``threads``: reading threads of the analysis (see :func:`grainplug.analyze`);
    1 where runs already go in parallel.
    """
    run_dir = Path(out_dir) / "runs" / run_folder_name(spec.run)
    record: dict[str, object] = {"run": spec.run, "movie": str(spec.movie), **spec.meta}
    try:
        key = run_key(spec)
    except OSError as exc:
        return {**record, "status": "failed", "error": f"cannot read {spec.movie}: {exc.strerror or exc}"}
    except GrainplugError as exc:
        return {**record, "status": "failed", "error": str(exc)}
    record["run_key"] = key
    summary_path = run_dir / "summary.json"
    if summary_path.exists():
        try:
            old = json.loads(summary_path.read_text())
        except (OSError, json.JSONDecodeError):
            old = {}
        if old.get("batch", {}).get("run_key") == key:
            return {**record, "status": "cached", **_flat(old)}
    try:
        res = analyze(spec.movie, spec.params, threads=threads)
        write_outputs(res, run_dir, figures=figures, report=figures,
                      extra={"batch": {"run": spec.run, "run_key": key, "meta": spec.meta}})
        return {**record, "status": "ok", **_flat(res.summary)}
    except GrainplugError as exc:
        return {**record, "status": "failed", "error": str(exc)}
    except Exception as exc:  # a bug in one run must not stop the campaign
        log.exception("run %s failed", spec.run)
        return {**record, "status": "failed", "error": f"unexpected {type(exc).__name__}: {exc}"}


def _flat(summary: dict) -> dict[str, object]:
    out = {k: summary.get(k) for k in SUMMARY_COLUMNS}
    ci = summary.get("celerity_ci95_m_s") or [None, None]
    lci = summary.get("plug_length_ci95_mm") or [None, None]
    out.update(celerity_ci95_low_m_s=ci[0], celerity_ci95_high_m_s=ci[1],
               plug_length_ci95_low_mm=lci[0], plug_length_ci95_high_mm=lci[1],
               input_sha256_ends=(summary.get("input") or {}).get("sha256_ends"),
               input_bytes=(summary.get("input") or {}).get("bytes"),
               grainplug_version=summary.get("grainplug_version"),
               warnings=" | ".join(summary.get("warnings") or []) or None)
    return out


@dataclass(frozen=True)
class Campaign:
    """The campaign table, its fits and where it was written."""

    table: pd.DataFrame
    fits: dict[str, dict]
    out_dir: Path
    n_failed: int


def _group(row: pd.Series) -> str | None:
    if isinstance(row.get("group"), str) and row["group"]:
        return row["group"]
    regime = row.get("regime")
    if not isinstance(regime, str) or regime == "none":
        return None
    surface = row.get("surface")
    return f"{regime}/{surface}" if isinstance(surface, str) and surface else regime


def campaign_fits(table: pd.DataFrame, *, diameter_mm: float = 3.0) -> dict[str, dict]:
    """Celerity and length against mass flow rate, per group and over all runs."""
    ok = table[table.status.isin(["ok", "cached"])].copy() if "status" in table else table.copy()
    if "mass_flow_rate_g_s" not in ok or ok.empty:
        return {}
    ok["fit_group"] = ok.apply(_group, axis=1)
    ok = ok[ok.fit_group.notna() & ok.mass_flow_rate_g_s.notna()]
    out: dict[str, dict] = {}
    for name, sub in [*ok.groupby("fit_group"), ("all", ok)]:
        x = sub.mass_flow_rate_g_s.to_numpy(float)
        fc = fit_line(x, sub.celerity_m_s.to_numpy(float))
        ls = summarize_lengths(x, sub.plug_length_mm.to_numpy(float), diameter_mm=diameter_mm)
        out[str(name)] = {"celerity": fc.as_dict("g_s", "m_s") if fc else None,
                          "length": ls.as_dict() if ls else None, "runs": sub.run.tolist()}
    return out


def run_campaign(manifest: str | Path, out_dir: str | Path, *, workers: int = 1, scheduler: str | None = None,
                 figures: bool = True,
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
    progress : callable, optional
        ``progress(done, total, run)`` after each run.
    """
    from .._atomic import OutputPlaceError, check_output_place

    specs = read_manifest(manifest)
    out = check_output_place(out_dir, inputs=[manifest, *(s.movie for s in specs)], replace=False)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputPlaceError(f"cannot create {out}: {exc.strerror or exc} — choose another --out") from None
    if workers < 1:
        raise GrainplugError("--workers must be at least 1")
    records: dict[str, dict] = {}
    total = len(specs)

    def done(rec: dict) -> None:
        records[str(rec["run"])] = rec
        if progress:
            progress(len(records), total, str(rec["run"]))

    if scheduler:
        try:
            from dask.distributed import Client
            from dask.distributed import as_completed as dask_completed
        except ImportError:
            raise GrainplugError("--scheduler needs Dask: pip install 'grainplug[dask]'") from None
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as exc:
            raise GrainplugError(f"cannot reach the Dask scheduler at {scheduler} ({exc})") from None
        try:
            futures = [client.submit(process_run, s, str(out), figures=figures, threads=1, pure=False)
                       for s in specs]
            for fut in dask_completed(futures):
                done(fut.result())
        finally:
            client.close()
    elif workers > 1:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            futures = [pool.submit(process_run, s, str(out), figures=figures, threads=1) for s in specs]
            for fut in as_completed(futures):
                done(fut.result())
    else:
        for s in specs:
            done(process_run(s, str(out), figures=figures))
    table = pd.DataFrame([records[s.run] for s in specs])
    fits = campaign_fits(table)
    _write_campaign(table, fits, out, manifest=Path(manifest), figures=figures)
    return Campaign(table, fits, out, int((table.status == "failed").sum()))


def _write_campaign(table: pd.DataFrame, fits: dict, out: Path, *, manifest: Path, figures: bool) -> None:
    with atomic_directory(out) as tmp:
        table.to_csv(tmp / "campaign.csv", index=False)
        pq = table.copy()
        for col in pq.columns:  # parquet needs one type per column
            if pq[col].dtype == object:
                pq[col] = pq[col].map(lambda v: None if v is None or (isinstance(v, float) and np.isnan(v)) else str(v))
        pq.to_parquet(tmp / "campaign.parquet", index=False)
        meta = {"grainplug_version": __version__, "manifest": str(manifest.resolve()),
                "manifest_sha256": hashlib.sha256(manifest.read_bytes()).hexdigest(), "fits": fits}
        (tmp / "fits.json").write_text(dumps(meta))
        names: list[str] = []
        if figures:
            names = _campaign_figures(table, tmp)
            from .report import campaign_report

            (tmp / "report.html").write_text(campaign_report(table, fits, tmp, names, meta))


def _campaign_figures(table: pd.DataFrame, folder: Path) -> list[str]:
    import matplotlib.pyplot as plt

    from ..plotting.campaign import plot_vs_mass_flow

    ok = table[table.status.isin(["ok", "cached"])].copy()
    if ok.empty or "mass_flow_rate_g_s" not in ok:
        return []
    ok["fit_group"] = ok.apply(_group, axis=1)
    ok = ok[ok.fit_group.notna() & ok.mass_flow_rate_g_s.notna()]
    if ok.empty:
        return []
    names = []
    for y, label, fname, ref in (("celerity_m_s", "v_p (m/s)", "celerity_vs_mass_flow.png", None),
                                 ("plug_length_mm", "λ (mm)", "length_vs_mass_flow.png", 30.0)):
        data = {g: (s.mass_flow_rate_g_s.to_numpy(float), s[y].to_numpy(float)) for g, s in ok.groupby("fit_group")}
        fits = {g: fit_line(*xy) for g, xy in data.items()}
        fig = plot_vs_mass_flow(data, fits, ylabel=label, title=f"{y} against mass flow rate",
                                hline=ref, hline_label="10 D" if ref else "")
        fig.savefig(folder / fname, dpi=110)
        plt.close(fig)
        names.append(fname)
    return names
