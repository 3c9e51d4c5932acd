"""The campaign's HTML report."""

from __future__ import annotations

import html
from pathlib import Path

import pandas as pd

from ..reports import images, page, provenance, table


def campaign_report(tab: pd.DataFrame, fits: dict, folder: Path, figures: list[str], meta: dict) -> str:
    cols = [c for c in ("run", "status", "mass_flow_rate_g_s", "surface", "regime", "celerity_m_s",
                        "plug_length_mm", "oscillation_frequency_hz", "scale_source", "warnings", "error") if c in tab]
    rows = [[("" if pd.isna(v) else v) if not isinstance(v, (list, dict)) else v for v in r]
            for r in tab[cols].itertuples(index=False)]
    links = "".join(f'<li><a href="runs/{html.escape(str(r))}/report.html">{html.escape(str(r))}</a></li>'
                    for r, s in zip(tab.run, tab.status, strict=True) if s == "ok")
    fit_rows = []
    for g, f in fits.items():
        c = f.get("celerity") or {}
        ln = f.get("length") or {}
        fit_rows.append([g, c.get("slope_m_s_per_g_s"), c.get("slope_stderr"), c.get("intercept_m_s"),
                         c.get("intercept_stderr"), c.get("r2"), c.get("n"), ln.get("mean_mm"),
                         ln.get("sd_mm"), ln.get("mean_over_diameter")])
    inputs = {r: {"movie": m, "sha256_sampled": h} for r, m, h in
              zip(tab.run, tab.movie, tab.get("input_sha256_sampled", [None] * len(tab)), strict=True)}
    body = ("<h2>Runs</h2>" + table(cols, rows) + f"<p>Per-run reports:</p><ul>{links}</ul>"
            + "<h2>Fits against mass flow rate</h2>"
            + table(["group", "slope (m/s per g/s)", "± se", "intercept (m/s)", "± se", "R²", "n",
                     "mean λ (mm)", "sd λ (mm)", "λ/D"], fit_rows)
            + "<h2>Figures</h2>" + images(folder, figures)
            + provenance({k: v for k, v in meta.items() if k != "fits"} | {"inputs": inputs}))
    return page("grainplug campaign", body)
