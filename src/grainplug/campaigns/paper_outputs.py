"""Files of ``grainplug paper``: JSON, the reproduction text, figures and a report."""

from __future__ import annotations

import html
import json
from pathlib import Path
from typing import TYPE_CHECKING

from .. import datasets
from .._atomic import atomic_directory
from .._version import __version__
from ..jsonio import dumps
from ..plotting.files import save_figure
from ..plotting.options import FigureOptions
from .model_panel import panel_html
from .paper import D_MM, PaperReproduction, reproduction_text

if TYPE_CHECKING:
    from matplotlib.figure import Figure

MODEL_FIGURE = "model_vs_experiment.png"


#: the paper's groups of runs, by regime
PAPER_GROUPS = {"propagative": ["propagative/rough", "propagative/smooth"], "oscillating": ["oscillating"]}


def celerity_figure(rep: PaperReproduction, regime: str) -> Figure:
    """The celerity of the paper's runs of ``regime`` against the mass flow rate, with the fits.

    Signed, as every celerity of grainplug (positive downstream: the climbing plugs below zero), so that the
    legend's slope is the table's (the paper plots ``|v_p|``; the fits are of the signed ``v_p``)."""
    from ..plotting.campaign import plot_vs_mass_flow

    runs = datasets.paper_runs()
    groups = PAPER_GROUPS[regime]
    data = {g: (runs[runs.group == g].mass_flow_rate_g_s.to_numpy(),
                runs[runs.group == g].celerity_m_s.to_numpy()) for g in groups}
    return plot_vs_mass_flow(data, {g: rep.fits[g] for g in groups}, ylabel="v_p (m/s, positive downstream)",
                             title=f"celerity of plugs, {regime} regime (paper's tables)")


def paper_figures(rep: PaperReproduction, folder: Path, options: FigureOptions | None = None) -> list[str]:
    """Celerity and length against mass flow rate (both regimes) and the growth-rate figures (the PNG
    names; other formats of ``options`` are written beside them)."""
    import matplotlib.pyplot as plt

    from ..plotting.campaign import plot_vs_mass_flow
    from ..plotting.stability import plot_growth_rates
    from ..stability import ModelParams, analyze_stability

    runs = datasets.paper_runs()
    names = []
    for regime, groups in PAPER_GROUPS.items():
        fig = celerity_figure(rep, regime)
        name = f"celerity_{regime}.png"
        save_figure(fig, folder, name, options)
        plt.close(fig)
        names.append(name)
        from .fits import fit_line

        ldata = {g: (runs[runs.group == g].mass_flow_rate_g_s.to_numpy(),
                     runs[runs.group == g].plug_length_mm.to_numpy()) for g in groups}
        lfits = {g: fit_line(*ldata[g]) for g in groups}
        fig = plot_vs_mass_flow(ldata, lfits, ylabel="λ (mm)", title=f"plug length, {regime} regime",
                                hline=10 * D_MM, hline_label="10 D")
        name = f"length_{regime}.png"
        save_figure(fig, folder, name, options)
        plt.close(fig)
        names.append(name)
    for variant in ("printed", "frozen-friction"):
        fig = plot_growth_rates(analyze_stability(ModelParams(variant=variant), k_min=1e-3, k_max=3.0, n_k=1500))
        name = f"growth_rates_{variant.replace('-', '_')}.png"
        save_figure(fig, folder, name, options)
        plt.close(fig)
        names.append(name)
    if rep.model_panel is not None:
        from ..plotting.model_panel import plot_model_panel

        fig = plot_model_panel(rep.model_panel.measured, rep.model_panel.predictions, diameter_mm=D_MM)
        save_figure(fig, folder, MODEL_FIGURE, options)
        plt.close(fig)
        names.append(MODEL_FIGURE)
    return names


def write_paper(rep: PaperReproduction, out_dir: str | Path, *, figures: bool = True,
                figure_options: FigureOptions | None = None) -> dict[str, Path]:
    """Write ``paper.json``, ``reproduction.md``, the figures and ``report.html`` into ``out_dir``."""
    from ..reports import images, page, provenance, table

    written: dict[str, Path] = {}
    with atomic_directory(out_dir, written, replace=True, kind="paper") as tmp:
        data = {"grainplug_version": __version__, **rep.as_dict()}
        (tmp / "paper.json").write_text(dumps(data))
        text = reproduction_text(rep)
        (tmp / "reproduction.md").write_text(text)
        names = paper_figures(rep, tmp, figure_options) if figures else []
        rows = [[c.claim, c.where, json.dumps(c.paper, default=str), json.dumps(c.reproduced, default=str),
                 "yes" if c.agrees else "NO", c.note] for c in rep.checks]
        fit_rows = [[g, f"{f.slope:+.4f} ± {f.slope_stderr:.4f}", f"{f.intercept:+.4f} ± {f.intercept_stderr:.4f}",
                     f"{f.r2:.3f}", f.n] for g, f in rep.fits.items()]
        body = (f"<p>{html.escape(rep.source.get('citation', ''))}, doi:{html.escape(rep.source.get('doi', ''))}</p>"
                "<h2>Fits of celerity against mass flow rate</h2>"
                + table(["group", "slope (m/s per g/s)", "intercept (m/s)", "R²", "n"], fit_rows)
                + "<h2>Checks against the text</h2>"
                + table(["claim", "where", "paper", "reproduced", "agrees", "note"], rows)
                + ("" if rep.model_panel is None else
                   panel_html(rep.model_panel, MODEL_FIGURE if MODEL_FIGURE in names else None))
                + "<h2>Figures</h2>" + images(tmp, [n for n in names if n != MODEL_FIGURE])
                + provenance({"grainplug_version": __version__, "source": rep.source}))
        if figures:
            (tmp / "report.html").write_text(page("grainplug: reproduction of the paper", body))
    return written
