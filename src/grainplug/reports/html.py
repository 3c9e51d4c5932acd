"""One self-contained HTML page per run: figures embedded as data URIs, tables, provenance."""

from __future__ import annotations

import base64
import datetime as _dt
import html
import json
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..result import AnalysisResult

_CSS = """
body{font-family:system-ui,sans-serif;max-width:1000px;margin:2em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;padding:3px 8px;text-align:left}
th{background:#f3f3f3}img{max-width:100%;border:1px solid #ddd;margin:.5em 0}
code,pre{background:#f6f6f6}pre{padding:.6em;overflow:auto;font-size:12px}.note{color:#a33}
"""


def _img(path: Path) -> str:
    data = base64.b64encode(path.read_bytes()).decode()
    return f'<img alt="{html.escape(path.stem)}" src="data:image/png;base64,{data}">'


def _table(rows: list[tuple[str, object]]) -> str:
    body = "".join(f"<tr><th>{html.escape(str(k))}</th><td>{html.escape(str(v))}</td></tr>" for k, v in rows)
    return f"<table>{body}</table>"


def page(title: str, body: str) -> str:
    """A complete, self-contained HTML page."""
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>{_CSS}</style></head><body>
<h1>{html.escape(title)}</h1>
{body}
</body></html>
"""


def images(folder: Path, names: list[str]) -> str:
    """Embedded PNGs of ``folder`` (those that exist)."""
    return "".join(_img(folder / n) for n in names if (folder / n).exists())


def number(value: object, decimals: int = 3) -> str:
    """A number as people read it in a table: fixed decimals, a minus sign, "—" when missing."""
    import math

    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return str(value)
    if isinstance(value, int):
        return str(value)
    text = f"{value:.{decimals}f}"
    if float(text) == 0:
        text = text.lstrip("-")  # no "−0.0000"
    return text.replace("-", "−")


def table(header: list[str], rows: list[list[object]]) -> str:
    """An HTML table with a header row."""
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape('' if v is None else str(v))}</td>" for v in r) + "</tr>"
                   for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def provenance(data: dict) -> str:
    data = {**data, "generated": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")}
    return f"<h2>Provenance</h2><pre>{html.escape(json.dumps(data, indent=2, default=str))}</pre>"


def run_report(res: AnalysisResult, folder: Path) -> str:
    """HTML text of the report of one analysis (figures read from ``folder``)."""
    s = res.summary
    keys = ["celerity_m_s", "celerity_ci95_m_s", "plug_length_mm", "plug_length_ci95_mm",
            "plug_length_over_diameter", "bubble_length_mm", "oscillation_frequency_hz",
            "oscillation_amplitude_mm", "regime", "n_plugs", "n_frames", "fps", "mm_per_px",
            "scale_source", "scale_rel_sd", "tube_diameter_px", "tube_axis_angle_deg", "flow_direction",
            "flow_direction_source"]
    figs = "".join(_img(folder / name) for name in ("diagram.png", "spectrum.png", "frame.png")
                   if (folder / name).exists())
    statement = f'<p class="note">{html.escape(res.statement)}</p>' if res.statement else ""
    warnings = "".join(f"<li>{html.escape(w)}</li>" for w in res.warnings)
    if warnings:
        warnings = f'<h2 class="note">Warnings</h2><ul class="note">{warnings}</ul>'
    corrections = ""
    if res.corrections is not None and res.corrections.edits:
        items = "".join(f"<li>{html.escape(e.describe())} <small>({html.escape(e.at)})</small></li>"
                        for e in res.corrections.edits)
        corrections = (f'<h2 class="note">Corrections applied ({len(res.corrections.edits)})</h2>'
                       f'<ul class="note">{items}</ul><p>The measures below are recomputed from the detected '
                       "plugs with these corrections (corrections.json; <code>grainplug remeasure</code>).</p>")
    prov = {"grainplug_version": s["grainplug_version"], "input": s["input"],
            "parameters": s["parameters"], "movie": s["movie"],
            "generated": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")}
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>grainplug: {html.escape(Path(res.info.path).name)}</title>
<style>{_CSS}</style></head><body>
<h1>grainplug analysis of <code>{html.escape(Path(res.info.path).name)}</code></h1>
{statement}
{warnings}
{corrections}
<h2>Results</h2>{_table([(k, s.get(k)) for k in keys])}
<h2>Figures</h2>{figs}
<h2>Provenance</h2><pre>{html.escape(json.dumps(prov, indent=2, default=str))}</pre>
<p>Positions in mm along the tube from the upstream end of the view, increasing with the flow;
celerity positive downstream.</p>
</body></html>
"""
