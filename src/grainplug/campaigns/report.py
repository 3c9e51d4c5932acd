"""The campaign's HTML report: runs, fits and figures in words and rounded numbers."""

from __future__ import annotations

import html
from pathlib import Path

import pandas as pd

from ..reports import images, page, provenance, table
from ..reports.html import _SORT_JS as SORT_JS
from ..reports.html import number, warning_html
from .fits import ALL_RUNS, fit_selection
from .model_panel import ModelPanel, panel_html

#: table columns: (column of the campaign table, header, decimals or None for text)
RUN_COLUMNS = (
    ("run", "run", None), ("status", "status", None), ("group", "group", None),
    ("mass_flow_rate_g_s", "mass flow rate (g/s)", 3), ("surface", "surface", None), ("regime", "regime", None),
    ("celerity_m_s", "celerity (m/s)", 4),
    ("celerity_ci95_low_m_s", "95 % CI (m/s)", 4),  # written "low to high", sorted by its low end
    ("plug_length_mm", "plug length (mm)", 2), ("bubble_length_mm", "bubble length (mm)", 2),
    ("oscillation_frequency_hz", "oscillation (Hz)", 3), ("scale_source", "scale from", None),
    ("n_corrections", "corrections", 0),
)


#: characters of a text cell shown in the runs table; longer texts are cut, whole in their tooltip
SHORT_TEXT = 24


def _cell(value: object, decimals: int | None) -> str:
    if decimals is not None:
        return number(value, decimals)  # "—" when missing
    return "—" if value is None or pd.isna(value) else str(value)


def _to_uncertainty(value: object, se: object) -> tuple[str, str]:
    """A fitted value and its standard error as people read them: the error to two significant figures
    (0.0000012, not 0.0000) and the value to the same decimal place; in powers of ten below 1e-9."""
    import math

    if not isinstance(value, (int, float)) or not math.isfinite(value):
        return "—", "—"
    if not isinstance(se, (int, float)) or not math.isfinite(se) or se <= 0:
        return number(float(value), 4), "—"
    decimals = max(0, 1 - math.floor(math.log10(se)))
    if decimals <= 10:
        return number(float(value), decimals), number(float(se), decimals)
    exponent = math.floor(math.log10(se)) - 1  # both as multiples of the error's second figure's place
    scale = 10.0 ** exponent
    return (f"{value / scale:.0f}e{exponent}".replace("-", "−"), f"{se / scale:.0f}e{exponent}".replace("-", "−"))


def campaign_report(tab: pd.DataFrame, fits: dict, folder: Path, figures: list[str], meta: dict, *,
                    panel: ModelPanel | None = None) -> str:
    """The report of a campaign, for people: the campaign in a sentence, the fits against mass flow
    rate, the runs (each linking to its own report; sortable), the warnings and errors in a box,
    captioned figures, the model against the measurements, the provenance folded at the end."""
    # columns with nothing in them (no run oscillates, no group given) are left out: the table fits the page
    cols = [(c, h, d) for c, h, d in RUN_COLUMNS
            if c in tab and (c in ("run", "status") or (tab[c].notna().any()
                                                         and not (tab[c].astype(str).str.strip() == "").all()))]
    head = "".join(f"<th class='sort{' n' if d is not None else ''}'>{html.escape(h)}</th>" for _, h, d in cols)
    body_rows = []
    for _, r in tab.iterrows():
        cells = []
        for c, _, d in cols:
            text = html.escape(_cell(r[c], d))
            if c == "celerity_ci95_low_m_s" and "celerity_ci95_high_m_s" in tab and text != "—":
                text = f"{text} to {html.escape(_cell(r['celerity_ci95_high_m_s'], d))}"
            if c == "scale_source" and ":" in text:  # the kind in the table, the whole sentence on hover
                text = f'<span title="{text}">{text.split(":")[0]}</span>'
            elif d is None and len(_cell(r[c], d)) > SHORT_TEXT:  # a row reads on one line: long texts cut
                whole = _cell(r[c], d)
                text = f'<span title="{html.escape(whole)}">{html.escape(whole[:SHORT_TEXT - 1].rstrip())}…</span>'
            if c == "run" and r.get("status") == "ok":
                text = f'<a href="runs/{html.escape(str(r[c]))}/report.html">{text}</a>'
            v = r[c]
            sort = "" if d is None or pd.isna(v) else f' data-v="{float(v)}"'
            klass = ' class="n"' if d is not None else ""
            cells.append(f"<td{klass}{sort}>{text}</td>")
        body_rows.append("<tr>" + "".join(cells) + "</tr>")
    runs_table = (f'<div class="wide"><table class="sortable"><thead><tr>{head}</tr></thead>'
                  f'<tbody>{"".join(body_rows)}</tbody></table></div>')  # scrolls sideways, rows on one line
    notes = [f"<li><b>{html.escape(run) or 'fits'}</b>: {html.escape(why)}</li>"
             for run, why in fit_selection(tab)[1].items() if run == ALL_RUNS or not why.endswith("no plugs measured")]
    fit_rows = []
    for g, f in fits.items():
        c = f.get("celerity") or {}
        ln = f.get("length") or {}
        slope, slope_se = _to_uncertainty(c.get("slope_m_s_per_g_s"), c.get("slope_stderr"))
        icpt, icpt_se = _to_uncertainty(c.get("intercept_m_s"), c.get("intercept_stderr"))
        one = (ln.get("n") or c.get("n") or 0) < 2  # one run: no spread
        through = c.get("n") == 2  # a line through two runs fits them exactly: its R² says nothing
        if through:
            notes.append(f"<li><b>{html.escape(g)}</b>: a line through 2 runs fits them exactly: no R² and no "
                         "standard error can be given; more runs are needed to judge the line</li>")
        fit_rows.append([g, slope, slope_se, icpt, icpt_se, "—" if through else number(c.get("r2"), 3),
                         number(c.get("n")),
                         number(ln.get("mean_mm"), 2), "—" if one else number(ln.get("sd_mm"), 2),
                         number(ln.get("mean_over_diameter"), 2)])
    said: dict[tuple[str, str], list[str]] = {}  # a warning several runs share (a misspelt column) said once
    for _, r in tab.iterrows():
        for what, key in (("error", "error"), ("warning", "warnings")):
            text = r.get(key)
            if isinstance(text, str) and text:
                for line in dict.fromkeys(text.split(" | ")):
                    said.setdefault((what, line), []).append(str(r["run"]))
    notes += [f"<li><b>{html.escape(', '.join(runs))}</b> ({what}): {warning_html(line)}</li>"
              for (what, line), runs in said.items()]
    inputs = {r: {"movie": m, "sha256_sampled": h} for r, m, h in
              zip(tab.run, tab.movie, tab.get("input_sha256_sampled", [None] * len(tab)), strict=True)}
    n_ok = int((tab.status == "ok").sum())
    n_fail = len(tab) - n_ok
    regimes = tab[tab.status == "ok"].regime.value_counts() if "regime" in tab else pd.Series(dtype=int)
    said = ", ".join(f"{int(n)} {k}" for k, n in regimes.items()) or "none measured"
    sentence = (f"{len(tab)} runs: {n_ok} analysed ({said})"
                + (f", {n_fail} failed (see below)" if n_fail else "") + ".")
    captions = {"celerity_vs_mass_flow.png": "Celerity of the plugs against the mass flow rate, each run with its "
                "95 % interval, each group's least-squares line and its 95 % band.",
                "length_vs_mass_flow.png": "Mean plug length against the mass flow rate, with each run's 95 % "
                "interval; the dotted line is 10 D."}
    figs = "".join(f"<figure>{images(folder, [n])}<figcaption>{html.escape(captions.get(n, ''))}"
                   "</figcaption></figure>" for n in figures)
    prov = provenance({k: v for k, v in meta.items() if k not in ("fits", "model_vs_experiment")}
                      | {"inputs": inputs}, folded="Provenance (version, manifest, inputs)")
    body = (f'<p class="sentence">{html.escape(sentence)}</p>'
            + (f'<div class="warnbox"><h2>Warnings and errors</h2><ul>{"".join(notes)}</ul></div>' if notes else "")
            + "<h2>Fits against mass flow rate</h2>"
            + table(["group", "slope (m/s per g/s)", "± se", "intercept (m/s)", "± se", "R²", "n",
                     "mean λ (mm)", "sd λ (mm)", "λ/D"], fit_rows)
            + "<h2>Figures</h2>" + (figs or "<p>No figures.</p>")
            + "<h2>Runs</h2><p>Click a run for its own report, a column to sort. Celerity is positive downstream "
              "(plugs climbing the tube are negative); lengths along the tube; “—”: not measured.</p>"
            + runs_table
            + ("" if panel is None else panel_html(panel, "model_vs_experiment.png"))
            + prov
            + SORT_JS)
    return page("grainplug campaign", body)
