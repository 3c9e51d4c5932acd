"""Reports open in headless Chromium with no console errors and every image decoded."""

from __future__ import annotations

import shutil

import pytest

from grainplug import AnalysisParams, analyze
from grainplug.campaigns.paper import reproduce
from grainplug.campaigns.paper_outputs import write_paper
from grainplug.outputs import write_outputs
from grainplug.synthetic import SynthConfig, synthesize

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed "
                                "(make test installs it with apt-get when run as root)")


def _check(page_file, *, shot=None):
    sync_api = pytest.importorskip("playwright.sync_api")
    errors: list[str] = []
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=[
            "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
            "--disable-background-networking", "--disable-component-update", "--disable-sync"])
        try:
            page = browser.new_page(viewport={"width": 1366, "height": 768})
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(page_file.resolve().as_uri(), wait_until="load")
            n_images = page.evaluate("document.images.length")
            decoded = page.evaluate(
                "Array.from(document.images).every(i => i.complete && i.naturalWidth > 0)")
            title = page.title()
            scroll = page.evaluate("document.documentElement.scrollWidth")
            text = page.inner_text("body")
            if shot is not None:
                shot(page)
        finally:
            browser.close()
    assert errors == []
    assert n_images > 0 and decoded
    assert title.startswith("grainplug")
    assert scroll <= 1366, "horizontal scrolling at 1366 x 768"
    return text


def test_run_report(tmp_path):
    res = synthesize(SynthConfig(n_frames=120, seed=3, regime="oscillating", celerity_m_s=0.03), tmp_path / "m")
    out = tmp_path / "out"
    write_outputs(analyze(res.movie, AnalysisParams()), out)
    sorted_first = []

    def sort_by_celerity(page):
        page.click("table.sortable th.sort >> nth=4")
        sorted_first.append(page.inner_text("table.sortable tbody tr >> nth=0"))

    text = _check(out / "report.html", shot=sort_by_celerity)
    # headline first, in words, rounded to the uncertainty; no raw keys, no None; provenance folded
    assert text.lstrip().startswith("Plug flow in")
    assert "Oscillating regime: the plugs oscillate at" in text and " ± " in text
    assert "celerity_m_s" not in text and "None" not in text and "null" not in text
    assert "Provenance (version, input, parameters)" in text and '"grainplug_version"' not in text
    assert "Spatiotemporal diagram:" in text  # captions
    assert sorted_first and sorted_first[0].strip()


def test_paper_report(tmp_path):
    write_paper(reproduce(simulate=False), tmp_path / "p")
    _check(tmp_path / "p" / "report.html")


SURFACE = "glass coated with silane (batch 2025-03), dried 24 h at 60 °C"


def test_campaign_report(tmp_path):
    import csv

    from grainplug.campaigns import run_campaign

    rows = []  # every column of the runs table in use (groups, an oscillating run): it still fits the page
    for i, (m, c, regime) in enumerate([(0.4, -0.04, "propagative"), (0.6, -0.058, "propagative"),
                                        (0.8, -0.075, "oscillating")]):
        synthesize(SynthConfig(n_frames=100, celerity_m_s=c, seed=i, regime=regime), tmp_path / f"m{i}", fmt="avi")
        rows.append({"run": f"coated-{m:.1f}-g-s-{i}", "movie": f"m{i}/movie.avi", "mass_flow_rate_g_s": m,
                     "surface": SURFACE,
                     "group": "A" if i < 2 else "B"})
    with open(tmp_path / "manifest.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    run_campaign(tmp_path / "manifest.csv", tmp_path / "out")
    lines, titles, options = [], [], []

    def lines_per_cell(page):  # the line boxes each cell of the runs table takes, and the titles of its texts
        titles.extend(page.evaluate("Array.from(document.querySelectorAll('table.sortable [title]'))"
                                    ".map(e => e.title)"))
        for selector, into in (("table.sortable tbody td", lines), (".warnbox li code", options)):
            into.extend(page.evaluate("""s => Array.from(document.querySelectorAll(s)).map(e => {
                const r = document.createRange(); r.selectNodeContents(e);
                return new Set(Array.from(r.getClientRects()).map(b => Math.round(b.top))).size; })""", selector))

    text = _check(tmp_path / "out" / "report.html", shot=lines_per_cell)
    assert "group" in text and "oscillation (Hz)" in text and " to " in text
    assert len(lines) >= 3 * 10  # 3 runs, 10 columns at least
    assert max(lines) == 1, f"cells of the runs table wrap over {max(lines)} lines: a row reads across"
    assert options and max(options) == 1, "an option in a warning is cut across lines"
    assert SURFACE not in text and SURFACE in titles  # a long text shortened, whole in its tooltip
