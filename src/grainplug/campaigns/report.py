"""The campaign's HTML report: runs, fits and figures in words and rounded numbers."""

from __future__ import annotations

import html
from pathlib import Path

import pandas as pd

from ..reports import images, page, provenance, table
from ..reports.html import number
from .model_panel import ModelPanel, panel_html

#: table columns: (column of the campaign table, header, decimals or None for text)
RUN_COLUMNS = (
    ("run", "run", None), ("status", "status", None), ("mass_flow_rate_g_s", "mass flow rate (g/s)", 3),
    ("surface", "grains", None), ("regime", "regime", None), ("celerity_m_s", "celerity (m/s)", 4),
    ("celerity_ci95_low_m_s", "95 % CI from", 4), ("celerity_ci95_high_m_s", "to", 4),
    ("plug_length_mm", "plug length (mm)", 2), ("bubble_length_mm", "bubble length (mm)", 2),
    ("oscillation_frequency_hz", "oscillation (Hz)", 3), ("scale_source", "scale from", None),
    ("n_corrections", "corrections", 0),
)


def _cell(value: object, decimals: int | None) -> str:
    if decimals is not None:
        return number(value, decimals)  # "—" when missing
    return "—" if value is None or (isinstance(value, float) and pd.isna(value)) else str(value)


def campaign_report(tab: pd.DataFrame, fits: dict, folder: Path, figures: list[str], meta: dict, *,
                    panel: ModelPanel | None = None) -> str:
    """The report of a campaign: one row per run, the fits against mass flow rate, the figures,
    the warnings and errors of each run, and the provenance."""
    cols = [(c, h, d) for c, h, d in RUN_COLUMNS if c in tab]
    rows = [[_cell(r[c], d) for c, _, d in cols] for _, r in tab.iterrows()]
    links = "".join(f'<li><a href="runs/{html.escape(str(r))}/report.html">{html.escape(str(r))}</a></li>'
                    for r, s in zip(tab.run, tab.status, strict=True) if s == "ok")
    fit_rows = []
    for g, f in fits.items():
        c = f.get("celerity") or {}
        ln = f.get("length") or {}
        fit_rows.append([g, number(c.get("slope_m_s_per_g_s"), 4), number(c.get("slope_stderr"), 4),
                         number(c.get("intercept_m_s"), 4), number(c.get("intercept_stderr"), 4),
                         number(c.get("r2"), 3), number(c.get("n")), number(ln.get("mean_mm"), 2),
                         number(ln.get("sd_mm"), 2), number(ln.get("mean_over_diameter"), 2)])
    notes = []
    for _, r in tab.iterrows():
        for what, key in (("error", "error"), ("warning", "warnings")):
            text = r.get(key)
            if isinstance(text, str) and text:
                for line in text.split(" | "):
                    notes.append(f"<li><b>{html.escape(str(r['run']))}</b> ({what}): {html.escape(line)}</li>")
    inputs = {r: {"movie": m, "sha256_sampled": h} for r, m, h in
              zip(tab.run, tab.movie, tab.get("input_sha256_sampled", [None] * len(tab)), strict=True)}
    body = ("<h2>Runs</h2>" + table([h for _, h, _ in cols], rows)
            + "<p>Celerity is positive downstream (plugs climbing the tube are negative); "
              "lengths along the tube; “—”: not measured.</p>"
            + (f'<h2>Warnings and errors</h2><ul class="note">{"".join(notes)}</ul>' if notes else "")
            + f"<p>Per-run reports:</p><ul>{links}</ul>"
            + "<h2>Fits against mass flow rate</h2>"
            + table(["group", "slope (m/s per g/s)", "± se", "intercept (m/s)", "± se", "R²", "n",
                     "mean λ (mm)", "sd λ (mm)", "λ/D"], fit_rows)
            + "<h2>Figures</h2>" + images(folder, figures)
            + ("" if panel is None else panel_html(panel, "model_vs_experiment.png"))
            + provenance({k: v for k, v in meta.items() if k not in ("fits", "model_vs_experiment")}
                         | {"inputs": inputs}))
    return page("grainplug campaign", body)
