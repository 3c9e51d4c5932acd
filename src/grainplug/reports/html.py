"""One self-contained HTML page per run: figures embedded as data URIs, tables, provenance."""

from __future__ import annotations

import base64
import datetime as _dt
import html
import json
import re
from pathlib import Path
from typing import TYPE_CHECKING

from .._format import duration, oscillation_phrase
from ..measures.shake import shake_line
from ..params import with_options

if TYPE_CHECKING:
    from ..measures.motion import Motion
    from ..result import AnalysisResult

_CSS = """
body{font-family:system-ui,sans-serif;max-width:1000px;margin:2em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:1em 0;max-width:100%}td,th{border:1px solid #ccc;padding:3px 8px;text-align:left}
th{background:#f3f3f3}img{max-width:100%;border:1px solid #ddd;margin:.5em 0}
code,pre{background:#f6f6f6}pre{padding:.6em;overflow:auto;font-size:12px;white-space:pre-wrap;word-break:break-all}
.note{color:#a33}li code{white-space:nowrap}
.headline{display:flex;flex-wrap:wrap;gap:.8em;margin:1em 0}
.card{border:1px solid #ccc;border-radius:6px;padding:.5em .9em;min-width:10em;background:#fafafa}
.card .v{font-size:1.5em;font-variant-numeric:tabular-nums}.card .k{color:#555;font-size:.85em}
.warnbox{border:2px solid #d9a400;background:#fff8e1;border-radius:6px;padding:.3em 1em;margin:1em 0}
.fixbox{border:2px solid #3b7dd8;background:#eef4fd;border-radius:6px;padding:.3em 1em;margin:1em 0}
figure{margin:1.2em 0}figcaption{color:#444;font-size:.9em}
td.n,th.n{text-align:right;font-variant-numeric:tabular-nums}td.n{white-space:nowrap}th.sort{cursor:pointer}
td:not(.n){overflow-wrap:anywhere}.wide{overflow-x:auto;max-width:100%}.wide td{white-space:nowrap;overflow-wrap:normal}
.sentence{font-size:1.1em}
"""


def _img(path: Path) -> str:
    data = base64.b64encode(path.read_bytes()).decode()
    mime = "image/svg+xml" if path.suffix == ".svg" else "image/png"
    return f'<img alt="{html.escape(path.stem)}" src="data:{mime};base64,{data}">'


def _table(rows: list[tuple[str, object]]) -> str:
    body = "".join(f"<tr><th>{html.escape(str(k))}</th><td>{html.escape(str(v))}</td></tr>" for k, v in rows)
    return f"<table>{body}</table>"


def warning_html(text: str) -> str:
    """A warning for a page: escaped, each analysis keyword followed by its command-line option
    (:func:`grainplug.params.with_options`), the option in ``<code>`` kept on one line."""
    return re.sub(r"\((--[a-z0-9-]+)\)", r"(<code>\1</code>)", html.escape(with_options(text)))


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

    if value is None or type(value).__name__ == "NAType" or (isinstance(value, float) and not math.isfinite(value)):
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


def provenance(data: dict, *, folded: str | None = None) -> str:
    """The provenance as JSON with the time it was written; ``folded``: inside a closed ``<details>``
    with this summary line instead of under a heading."""
    data = {**data, "generated": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")}
    text = f"<pre>{html.escape(json.dumps(data, indent=2, default=str))}</pre>"
    if folded:
        return f"<details><summary>{html.escape(folded)}</summary>{text}</details>"
    return f"<h2>Provenance</h2>{text}"


def with_uncertainty(value: float | None, lo: float | None, hi: float | None, *, scale: float = 1.0) -> str:
    """``value ± half-width`` rounded to the uncertainty (two significant digits when it starts with 1 or 2,
    else one), times ``scale``; the value alone when there is no interval; "—" when missing."""
    import math

    if value is None or not math.isfinite(value):
        return "—"
    v = value * scale
    u = 0.0 if lo is None or hi is None or not (math.isfinite(lo) and math.isfinite(hi)) else abs(hi - lo) * scale / 2
    if u <= 0:
        return f"{v:.4g}".replace("-", "−")  # four significant digits
    exp = math.floor(math.log10(u))
    lead = u / 10**exp
    digits = -exp + (1 if lead < 3 else 0)
    d = max(digits, 0)
    lo, hi = min(lo, hi), max(lo, hi)
    below, above = v - lo * scale, hi * scale - v
    if abs(above - below) > 0.1 * max(above, below):  # an interval not centred on the value (clipped at 0)
        return (f"{number(round(v, digits), d)} ({number(round(lo * scale, digits), d)} to "
                f"{number(round(hi * scale, digits), d)})")
    return f"{number(round(v, digits), d)} ± {number(round(u, digits), d)}"


_SORT_JS = """<script>
document.querySelectorAll('table.sortable th.sort').forEach((th, i) => th.addEventListener('click', () => {
  const tb = th.closest('table').tBodies[0], rows = Array.from(tb.rows), up = th.dataset.dir !== 'up';
  const key = (r) => { const t = r.cells[i].dataset.v ?? r.cells[i].textContent; const x = parseFloat(t);
                       return isNaN(x) ? t : x; };
  rows.sort((a, b) => (key(a) > key(b) ? 1 : key(a) < key(b) ? -1 : 0) * (up ? 1 : -1));
  th.dataset.dir = up ? 'up' : 'down'; rows.forEach((r) => tb.appendChild(r));
}));
</script>"""


def _regime_sentence(res: AnalysisResult) -> str:
    m = res.motion
    if m is None:
        return res.statement or "No plug could be followed over time."
    lo, hi = m.celerity_ci95_m_s
    vertical = res.tube.orientation != "horizontal"
    if m.celerity_m_s < 0:
        way = "climb the tube (against the flow)" if vertical else "move against the flow"
    else:
        way = "move down the tube (with the flow)" if vertical else "move with the flow"
    if m.regime == "static":
        return (f"Static: the plugs did not move by a pixel over the record (mean velocity "
                f"{with_uncertainty(m.celerity_m_s, lo, hi)} m/s, 95 % interval) — a jammed tube, or a scene "
                "where nothing flows.")
    if lo is not None and hi is not None and lo <= 0 <= hi:  # no direction can be told
        speed = (f"their mean velocity, {with_uncertainty(m.celerity_m_s, lo, hi)} m/s (95 % interval), "
                 "cannot be told from zero: no direction of travel is measured")
        if m.regime == "oscillating" and m.oscillation_frequency_hz:
            return f"Oscillating regime: the plugs oscillate at {_oscillation(m)}; {speed}."
        return f"The plugs do not measurably travel: {speed}."
    rng = with_uncertainty(abs(m.celerity_m_s), abs(lo), abs(hi))
    if m.regime == "oscillating" and m.oscillation_frequency_hz:
        return (f"Oscillating regime: the plugs oscillate at {_oscillation(m)}, while they {way} at {rng} m/s "
                "on average.")
    return f"Propagative regime: the plugs {way} at a steady {rng} m/s."


def _oscillation(m: Motion) -> str:
    """The oscillation with its intervals and kind, as the CLI and summary.json give them."""
    o = m.oscillation
    return oscillation_phrase(m.oscillation_frequency_hz, o.frequency_ci95_hz if o else None,
                              m.oscillation_amplitude_mm, o.amplitude_ci95_mm if o else None,
                              o.kind if o else None, o.stick_fraction if o else None)


def _cards(res: AnalysisResult) -> str:
    m, ln = res.motion, res.lengths
    D = res.params.tube_diameter_mm
    cards = []
    if m is not None:
        cards.append(("celerity c (m s⁻¹)", with_uncertainty(m.celerity_m_s, *m.celerity_ci95_m_s),
                      "95 % interval; positive downstream"))
        if m.oscillation_frequency_hz:
            o = m.oscillation
            cards.append(("oscillation f (Hz)", number(m.oscillation_frequency_hz, 2) if o is None else
                          with_uncertainty(m.oscillation_frequency_hz, *o.frequency_ci95_hz),
                          f"amplitude {number(m.oscillation_amplitude_mm, 2)} mm" if o is None else
                          f"amplitude {with_uncertainty(m.oscillation_amplitude_mm, *o.amplitude_ci95_mm)} mm "
                          f"(half peak-to-peak; 95 % intervals), {o.kind}"))
    if ln is not None and ln.plug_length_mm is not None:
        ci = ln.plug_length_ci95_mm or (None, None)
        cards.append(("plug length λ (mm)", with_uncertainty(ln.plug_length_mm, *ci),
                      # rounded to its interval as λ is: "30 (0 to 80)" beside λ/D = 11.12 read as a contradiction
                      f"λ/D = {with_uncertainty(ln.plug_length_mm, *ci, scale=1 / D)}, "
                      f"{ln.n_plugs_measured} plugs"))
    if ln is not None and ln.bubble_length_mm is not None:
        ci = ln.bubble_length_ci95_mm or (None, None)
        cards.append(("bubble length (mm)", with_uncertainty(ln.bubble_length_mm, *ci),
                      f"{ln.n_bubbles_measured} bubbles"))
    comp = res.compactness
    if comp is not None and comp.plug is not None:
        ci = comp.plug_ci95 or (None, None)
        bubbles = ("" if comp.bubble is None else
                   f"bubbles {with_uncertainty(comp.bubble, *(comp.bubble_ci95 or (None, None)))}, ")
        cards.append(("compactness in plugs", with_uncertainty(comp.plug, *ci),
                      f"{bubbles}packed reference {res.params.packed_compactness:g}"))
    q = res.mass_flow
    if q.rate_g_s is not None:
        cards.append(("grains' mass flow rate (g/s)", with_uncertainty(q.rate_g_s, *(q.ci95_g_s or (None, None))),
                      f"from the movie, grains at {res.params.grain_density_kg_m3:g} kg/m³"))
    return '<div class="headline">' + "".join(
        f'<div class="card"><div class="k">{html.escape(k)}</div><div class="v">{html.escape(v)}</div>'
        f'<div class="k">{html.escape(n)}</div></div>' for k, v, n in cards) + "</div>"


def _plug_table(res: AnalysisResult) -> str:
    from ..summary import track_rows  # plain rows: pandas is not needed (nor imported) to write a report

    rows = track_rows(res)
    if not rows:
        return "<p>No plug tracks.</p>"
    head = ("<tr><th class='sort n'>plug</th><th class='sort n'>first seen (s)</th><th class='sort n'>last seen (s)"
            "</th><th class='sort n'>frames</th><th class='sort n'>celerity (m/s)</th>"
            "<th class='sort n'>length (mm)</th><th>note</th></tr>")
    body = []
    for r in rows:
        note = "two plugs joined (not in the mean length)" if r["composite"] else ""
        cells = [(r["plug_id"], number(int(r["plug_id"]))), (r["first_time_s"], number(r["first_time_s"], 3)),
                 (r["last_time_s"], number(r["last_time_s"], 3)), (r["n_frames"], number(int(r["n_frames"]))),
                 (r["celerity_m_s"], number(r["celerity_m_s"], 4)),
                 (r["median_length_mm"], number(r["median_length_mm"], 2))]
        body.append("<tr>" + "".join(f'<td class="n" data-v="{v}">{t}</td>' for v, t in cells)
                    + f"<td>{html.escape(note)}</td></tr>")
    return f'<table class="sortable"><thead>{head}</thead><tbody>{"".join(body)}</tbody></table>'


def _kept_note(res: AnalysisResult, s: dict) -> str:
    """What the corrections keep of the record, when not all of it."""
    if res.corrections is None:
        return ""
    t = res.diagram.time_s
    half = 0.5 / res.info.fps  # the times are rounded in the summary: half a frame tells them apart
    window = s.get("kept_window_s", [float(t[0]), float(t[-1])])
    spans = s.get("not_plugs_s") or []
    parts = []
    if window is None:
        parts.append("the corrections' time window holds none of them")
    elif window[0] > float(t[0]) + half or window[1] < float(t[-1]) - half:
        parts.append(f"the corrections keep {number(window[0], 3)}–{number(window[1], 3)} s")
    if spans:
        parts.append(f"{sum(b - a for a, b in spans):.3g} s marked as not plugs")
    return "; " + ", ".join(parts) if parts else ""


def _details(res: AnalysisResult, s: dict) -> str:
    D = res.params.tube_diameter_mm
    rows = [
        ("scale", f"{number(res.mm_per_px, 5)} mm/px ± {number(100 * res.scale_rel_sd, 2)} % (one standard "
                  "deviation)"),
        ("scale from", res.scale_source),
        ("frames", f"{s['n_frames']} at {number(res.info.fps, 6 if res.info.fps % 1 else 0)} fps "
                   f"({'—' if s['duration_s'] is None else duration(s['duration_s'])})" + _kept_note(res, s)),
        ("tube", f"{number(D, 2)} mm bore = {number(s['tube_diameter_px'], 2)} px, "
                 f"{res.tube.orientation}, tilt {number(res.tube.tilt_deg, 2)}°"),
        ("flow", f"{res.flow_direction} in the image ({res.flow_direction_source})"),
        ("view", f"{number(s['view_length_mm'], 1)} mm of tube"),
    ]
    if res.falling_grain_speed_m_s is not None:
        rows.append(("grains in the bubbles fall at", f"{number(res.falling_grain_speed_m_s, 2)} m/s"))
    if shake_line(s.get("shake")):
        rows.append(("camera shake", shake_line(s.get("shake"))))
    return _table(rows)


#: figure captions: file, caption
CAPTIONS = (
    ("diagram.png", "Spatiotemporal diagram: the grey level along the tube (vertical, from the top of the view, "
                    "with the flow) against time. Vermillion: upper edges of the plugs, blue: lower edges; the "
                    "dashed green line has the mean celerity."),
    ("spectrum.png", "Displacement of the plug train about its mean drift, and its spectrum (oscillating regime)."),
    ("frame.png", "One frame with the detected tube (inner walls, axis) and the plug edges."),
)


def _captions(res: AnalysisResult) -> tuple[tuple[str, str], ...]:
    """:data:`CAPTIONS`, the diagram's told what this run's diagram shows (its tube's orientation, edges and
    mean-celerity line only when drawn)."""
    along = ("horizontal, from the upstream end of the view" if res.tube.orientation == "horizontal"
             else "vertical, from the top of the view" if res.flow_direction != "up"
             else "vertical, from the bottom of the view, the upstream end")
    drawn = []
    if len(res.runs):
        drawn.append("Vermillion: upper (upstream) edges of the plugs, blue: lower (downstream) edges")
    if res.motion is not None:
        drawn.append("the dashed green line has the mean celerity")
    extra = ("; ".join(drawn) + ".") if drawn else "No plug edge is drawn: none was detected."
    diagram = (f"Spatiotemporal diagram: the grey level along the tube ({along}, with the flow) against time. "
               + extra[0].upper() + extra[1:])
    return tuple((f, diagram if f == "diagram.png" else c) for f, c in CAPTIONS)


def run_report(res: AnalysisResult, folder: Path, *, summary: dict | None = None) -> str:
    """HTML text of the report of one analysis (figures read from ``folder``): headline numbers rounded to
    their uncertainty, the regime in a sentence, warnings and corrections in boxes, a sortable table of the
    plugs, captioned figures, details, and the provenance folded at the end."""
    s = summary if summary is not None else res.summary
    name = Path(res.info.path).name if res.info.path else "frames in memory"
    warnings = "".join(f"<li>{warning_html(w)}</li>" for w in res.warnings)
    if warnings:
        warnings = f'<div class="warnbox" role="note"><h2>Warnings</h2><ul>{warnings}</ul></div>'
    corrections = ""
    if res.corrections is not None and res.corrections.edits:
        from ..corrections import applied_edits

        done = applied_edits(res)
        items = "".join(f"<li>{html.escape(e.describe())}"
                        + (f" <small>({html.escape(e.at)})</small>" if e.at else "") + "</li>" for e in done)
        left = len(res.corrections.edits) - len(done)
        corrections = (f'<div class="fixbox"><h2>Corrections applied ({len(done)})</h2>'
                       + (f"<ul>{items}</ul>" if items else "")
                       + "<p>The measures are recomputed from the detected plugs with these corrections "
                       "(corrections.json; <code>grainplug remeasure</code>)."
                       + (f" {left} more in the file were not applied: the warnings say why." if left else "")
                       + "</p></div>")
    figs = []
    for f, c in _captions(res):  # the PNG, else the SVG (figures written in those formats only), else a link
        shown = next((p for p in (folder / f, (folder / f).with_suffix(".svg")) if p.exists()), None)
        pdf = (folder / f).with_suffix(".pdf")
        if shown is not None:
            figs.append(f"<figure>{_img(shown)}<figcaption>{html.escape(c)}</figcaption></figure>")
        elif pdf.exists():
            figs.append(f'<p><a href="{html.escape(pdf.name)}">{html.escape(pdf.name)}</a>: {html.escape(c)}</p>')
    prov = provenance({"grainplug_version": s["grainplug_version"], "input": s["input"],
                       "parameters": s["parameters"], "movie": s["movie"]},
                      folded="Provenance (version, input, parameters)")
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>grainplug: {html.escape(name)}</title>
<style>{_CSS}</style></head><body>
<h1>Plug flow in <code>{html.escape(name)}</code></h1>
<p class="sentence">{html.escape(_regime_sentence(res))}</p>
{_cards(res)}
{warnings}
{corrections}
<h2>Figures</h2>{"".join(figs) or "<p>No figures were drawn (--no-figures).</p>"}
<h2>Plugs</h2>
<p>One row per plug followed over time; click a column to sort. Celerity: the slope of its upper edge (of its lower
edge where fewer than two upper edges are seen); length: the median over the frames where both edges are in view.</p>
{_plug_table(res)}
<h2>How it was measured</h2>{_details(res, s)}
<p>Positions in mm along the tube from the upstream end of the view, increasing with the flow;
celerity positive downstream (plugs climbing the tube are negative).</p>
{prov}
{_SORT_JS}
</body></html>"""
