"""The campaigns' commands: batch, paper (loaded only when one of them is named)."""

from __future__ import annotations

import contextlib
import dataclasses
import os
from pathlib import Path
from typing import TYPE_CHECKING

import click
from rich.markup import escape

from .._version import __version__
from .common import (
    OVERWRITE_HELP,
    PUBLICATION_HELP,
    echo_json,
    err_console,
    figure_options_of,
    refuse_existing,
    say_warning,
)
from .types import Number

if TYPE_CHECKING:
    from ..campaigns.batch import Campaign


#: the most run warnings ``batch`` prints; the rest are counted, and all are in campaign.csv and the report
MAX_RUN_WARNINGS = 20



def fit_quality(r2: float, n: int) -> str:
    """A line's R² and count, with what they cannot say: a line through two runs always has R² = 1."""
    if n <= 2:
        return f"n {n}: a line through {n} runs fits them exactly, R² says nothing"
    return f"R² {r2:.3f}, n {n}" + ("; few runs, the slope is uncertain" if n < 5 else "")


def _print_run_warnings(camp: Campaign, out: Path) -> None:
    """Each run's warnings, as ``analyze`` prints them (``warning: run X: ...``), the same sentence of several
    runs once (``warning: runs a, b and 5 more: ...``: a misspelt manifest column was said once per run), at most
    :data:`MAX_RUN_WARNINGS` lines."""
    runs_of: dict[str, list[str]] = {}
    for run, w in camp.run_warnings:
        runs_of.setdefault(w, []).append(str(run))
    lines = list(runs_of.items())
    for w, runs in lines[:MAX_RUN_WARNINGS]:
        who = (f"run {runs[0]}" if len(runs) == 1 else
               f"runs {', '.join(runs)}" if len(runs) <= 4 else f"runs {', '.join(runs[:3])} and {len(runs) - 3} more")
        say_warning(w, f"{who}: ")
    if len(lines) > MAX_RUN_WARNINGS:
        err_console.print(f"[yellow]warning:[/] {len(lines) - MAX_RUN_WARNINGS} more run warnings: see the warnings "
                          f"column of {escape(str(out / 'campaign.csv'))} and the report", highlight=False,
                          soft_wrap=True)


# ---------------------------------------------------------------------------
@click.command()
@click.option("--out", "out", type=click.Path(path_type=Path), required=True,
              help="Folder for paper.json, reproduction.md, figures and report.html.")
@click.option("--no-figures", is_flag=True, help="Skip figures and report.")
@click.option("--json", "as_json", is_flag=True, help="Print fits, lengths, stability and checks as JSON.")
@click.option("--no-simulations", is_flag=True,
              help="Compare the measurements with the linear theory only (skip the ~4 s of nonlinear runs).")
@click.option("--publication", is_flag=True, help=PUBLICATION_HELP)
@click.option("--overwrite", is_flag=True, help=OVERWRITE_HELP)
def paper(out: Path, no_figures: bool, as_json: bool, no_simulations: bool, publication: bool,
          overwrite: bool) -> None:
    """Reproduce the paper's numbers and figures from its own Tables 1 and 2, and put the model's
    predictions (linear and simulated) beside the measurements."""
    from .._atomic import check_output_place
    from ..campaigns.paper import reproduce
    from ..campaigns.paper_outputs import write_paper

    check_output_place(out, kind="paper")
    refuse_existing(out, overwrite)
    doing = "reproducing the paper" + ("" if no_simulations else " (its simulations compile once after install, ~15 s)")
    with err_console.status(doing) if err_console.is_terminal else contextlib.nullcontext():
        rep = reproduce(simulate=not no_simulations)
    write_paper(rep, out, figures=not no_figures,
                figure_options=figure_options_of(None, None, publication, None))
    if as_json:
        echo_json({"grainplug_version": __version__, **rep.as_dict()})
        return
    click.echo("plug celerity against the mass flow rate ṁ (g/s), fitted as v_p = a + b ṁ:")
    for g, f in rep.fits.items():
        click.echo(f"  {g:18s} a = {f.intercept:+.4f} m/s, b = {f.slope:+.5f} (m/s)/(g/s)   "
                   f"({fit_quality(f.r2, f.n)})")
    n_ok = sum(c.agrees for c in rep.checks)
    click.echo(f"checks: {n_ok} of {len(rep.checks)} statements agree with the tables and models; "
               f"see {out / 'reproduction.md'}")
    for c in rep.checks:
        if not c.agrees:
            click.echo(f"  disagrees: {c.claim} — {c.note}")
    if rep.model_panel is not None:
        click.echo("model against experiment:")
        for sentence in rep.model_panel.verdict:
            click.echo(f"  {sentence}")


# ---------------------------------------------------------------------------
@click.command()
@click.argument("manifest", type=click.Path(path_type=Path))
@click.option("--out", "out", type=click.Path(path_type=Path), required=True,
              help="Folder for campaign.csv/.parquet, fits.json, figures, report.html and runs/.")
@click.option("--workers", type=Number(1, 1024, integer=True), default=1, show_default=True,
              help="Runs analysed in parallel on this machine.")
@click.option("--scheduler", default=None, help="Address of a Dask distributed scheduler (tcp://host:8786).")
@click.option("--cluster", default=None, metavar="slurm|pbs|sge|lsf|htcondor",
              help="Run the workers as jobs of this queue through dask-jobqueue (settings: Dask's jobqueue.yaml; "
                   "see docs/cluster.md). Every job ends with the batch.")
@click.option("--jobs", type=Number(1, 4096, integer=True), default=1, show_default=True,
              help="With --cluster: jobs kept running (one the queue ends is replaced).")
@click.option("--cluster-timeout", type=Number(0.1, 1e6, unit="s"), default=None,
              help="With --cluster: seconds to wait for the first job to start [default: 600].")
@click.option("--no-figures", is_flag=True, help="Skip figures and HTML reports.")
@click.option("--verify", is_flag=True,
              help="Reuse a finished run only if every byte of its movie is unchanged (reads every movie whole).")
@click.option("--json", "as_json", is_flag=True, help="Print the fits as JSON.")
@click.option("--no-simulations", is_flag=True,
              help="In the report, compare with the model's linear theory only (skip ~4 s of simulations).")
@click.option("--publication", is_flag=True, help=PUBLICATION_HELP)
def batch(manifest: Path, out: Path, workers: int, scheduler: str | None, cluster: str | None, jobs: int,
          cluster_timeout: float | None, no_figures: bool, verify: bool, as_json: bool, no_simulations: bool,
          publication: bool) -> None:
    """Analyse every run of MANIFEST (CSV or TOML), then tabulate, fit and report.

    One row per run: movie (relative to the manifest), fps, mm_per_px or tube_diameter_mm,
    flow_direction, mass_flow_rate_g_s, humidity_pct, surface, group, and any metadata.
    Runs already analysed with the same movie (size and sampled content; every byte with
    --verify) and parameters are reused. Ctrl-C stops at once; every run is then done or not
    started, and the same command finishes the campaign.
    """
    from rich.progress import BarColumn, Progress, TextColumn

    from ..campaigns import run_campaign
    from ..campaigns.cluster import CLUSTER_TIMEOUT_S, check_cluster_kind
    from ..errors import CampaignInterrupted, Interrupted, ParameterError

    if cluster is not None:
        check_cluster_kind(cluster)  # before the manifest is read: the first thing wrong is said
        if scheduler:
            raise ParameterError("give --cluster or --scheduler, not both", param="cluster")
    elif jobs != 1 or cluster_timeout is not None:
        raise ParameterError("--jobs and --cluster-timeout go with --cluster", param="jobs")

    with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total} runs"),
                  console=err_console, transient=True, disable=not err_console.is_terminal) as bar:
        task = bar.add_task("campaign", total=None)

        def progress(done: int, total: int, run: str) -> None:
            last = done == total and not no_simulations  # then the tables, fits and the model's simulations
            bar.update(task, completed=done, total=total,
                       description="fits and model (the simulations compile once after install, ~15 s)" if last
                       else f"run {escape(run)}")

        try:
            camp = run_campaign(manifest, out, workers=workers, scheduler=scheduler, cluster=cluster, jobs=jobs,
                                cluster_timeout_s=cluster_timeout or CLUSTER_TIMEOUT_S, figures=not no_figures,
                                verify=verify, simulate=not no_simulations, progress=progress,
                                figure_options=figure_options_of(None, None, publication, None))
        except CampaignInterrupted as exc:  # before click's own handler, which prints a blank line
            raise Interrupted(str(exc)) from None
    t = camp.table
    if camp.stale_runs:
        names = ", ".join(camp.stale_runs[:5]) + (", ..." if len(camp.stale_runs) > 5 else "")
        err_console.print(f"[yellow]warning:[/] {len(camp.stale_runs)} run folder(s) under {escape(str(out / 'runs'))} "
                          f"are no longer in the manifest ({escape(names)}): kept, but left out of the campaign — "
                          "delete them if they are not needed", highlight=False, soft_wrap=True)
    if camp.worker_deaths:
        fix = "ask for more memory or walltime per job" if cluster else "use fewer --workers"
        err_console.print(f"[yellow]warning:[/] {camp.worker_deaths} worker process(es) died during the batch "
                          f"(killed, or out of memory); their runs were started again — if it repeats, {fix}",
                          highlight=False, soft_wrap=True)
    if as_json:
        from ..campaigns.fits import fit_selection

        _print_run_warnings(camp, out)  # on stderr, as analyze --json prints its warnings
        echo_json({"grainplug_version": __version__, "fits": camp.fits,
                    "runs": t[["run", "status"]].to_dict(orient="records"), "n_reused": camp.n_reused,
                    "n_remeasured": camp.n_remeasured, "left_out_of_fits": fit_selection(t)[1]})
    else:
        counts = t.status.value_counts().to_dict()
        again = f", {camp.n_remeasured} of them measured again with their new corrections" if camp.n_remeasured else ""
        reused = f" ({camp.n_reused} reused from an earlier batch{again})" if camp.n_reused else ""
        n_hosts = len({w.rsplit(":", 1)[0] for w in camp.workers_used})
        spread = (f", on {len(camp.workers_used)} Dask worker(s) on {n_hosts} host(s)" if camp.workers_used else "")
        click.echo(f"{len(t)} runs: " + ", ".join(f"{v} {k}" for k, v in sorted(counts.items())) + reused + spread)
        from ..campaigns.fits import ALL_RUNS, fit_selection

        _print_run_warnings(camp, out)
        for run, why in fit_selection(t)[1].items():
            if run == ALL_RUNS or not why.endswith("no plugs measured"):
                say_warning(why, f"run {run}: " if run else "fits: ")
        fits = {g: f["celerity"] for g, f in camp.fits.items() if f.get("celerity")}
        if fits:
            click.echo("plug celerity against the mass flow rate ṁ (g/s), fitted as v_p = a + b ṁ:")
        for g, c in fits.items():
            click.echo(f"  {g:22s} a = {c['intercept_m_s']:+.4g} m/s, b = {c['slope_m_s_per_g_s']:+.4g} (m/s)/(g/s)"
                       f"   ({fit_quality(c['r2'], c['n'])})")
        click.echo(f"outputs in {out}")
    if camp.n_failed:
        from ..errors import PartialCampaignError

        for row in t[t.status == "failed"].itertuples():
            err_console.print(f"[red]failed:[/] run {escape(str(row.run))}: {escape(str(row.error))}",
                              highlight=False, soft_wrap=True)
        others = "the others are done" if camp.n_failed < len(t) else "none is done"
        raise PartialCampaignError(
            f"{camp.n_failed} of {len(t)} runs failed, each named above ({others}; see {out / 'campaign.csv'})"
        )


@click.command()
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--out", "out", type=click.Path(path_type=Path), default=None,
              help="The manifest to write [default: FOLDER/manifest.csv].")
@click.option("--glob", "glob_", default=None, metavar="PATTERN",
              help="Only the files matching this pattern (e.g. '*.cine') [default: every movie file].")
@click.option("--force", is_flag=True, help="Replace an existing manifest.")
def manifest(folder: Path, out: Path | None, glob_: str | None, force: bool) -> None:
    """Write a campaign manifest for the movies in FOLDER, from their headers.

    One row per movie: the run's name (from the file's), the movie, its saved-frame rate (fps), record rate,
    frames, duration, size, bit depth, camera and trigger time; empty columns for the lab's metadata (mass flow
    rate, humidity, surface, group) to fill in. A file that cannot be read gets a comment row saying why.
    Then: grainplug batch MANIFEST --out DIR.
    """
    from .._atomic import atomic_file
    from ..campaigns.scan import manifest_text, scan_folder
    from ..errors import ParameterError

    target = out if out is not None else folder / "manifest.csv"
    if target.exists() and not force:
        raise ParameterError(f"{target} exists — give --force to replace it, or another --out")
    scanned = scan_folder(folder, glob=glob_)
    if target.resolve().parent != folder.resolve():  # the movies' paths relative to the manifest
        rel = Path(os.path.relpath(folder.resolve(), target.resolve().parent))
        scanned = [dataclasses.replace(s, row={**s.row, "movie": (rel / str(s.row["movie"])).as_posix()})
                   if not s.error else s for s in scanned]
    text = manifest_text(scanned)
    with atomic_file(target, inputs=[s.path for s in scanned]) as tmp:
        tmp.write_text(text, encoding="utf-8")
    read = [s for s in scanned if not s.error]
    click.echo(f"{len(read)} movie{'' if len(read) == 1 else 's'} in {target}"
               + (f"; {len(scanned) - len(read)} not read (comment rows say why)" if len(read) < len(scanned) else ""))
    for s in scanned:
        if s.error:
            say_warning(f"{s.path.name}: not read — {s.error}")
    click.echo(f"fill in the lab's columns, then: grainplug batch {target} --out DIR")
