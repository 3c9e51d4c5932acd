"""Writing an analysis: the figure worker draws what in-process drawing draws, and survives failure."""

from __future__ import annotations

import json

import numpy as np
import pytest

import grainplug as gp
from grainplug.outputs import draw_figures, write_outputs
from grainplug.plotting.worker import FigureWorker
from grainplug.synthetic import SynthConfig, synthesize


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    movie = synthesize(SynthConfig(n_frames=90, seed=5, regime="oscillating"), tmp_path_factory.mktemp("m"),
                       fmt="tiff")
    return gp.analyze(movie.movie)


def _pngs(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.glob("*.png"))}


def test_worker_draws_the_same_figures_as_in_process(result, tmp_path):
    here, there = tmp_path / "here", tmp_path / "there"
    here.mkdir()
    draw_figures(result, here)
    with FigureWorker() as fw:
        assert fw.running
        write_outputs(result, there, report=False, figure_worker=fw)
    assert not fw.running  # stopped and reaped when the block ends
    assert set(_pngs(here)) == {"diagram.png", "frame.png", "spectrum.png"}
    assert _pngs(there) == _pngs(here)


@pytest.mark.parametrize("when", ["before the job", "during the job"])
def test_a_dead_worker_falls_back_to_drawing_here(result, tmp_path, caplog, when):
    with FigureWorker() as fw:
        if when == "before the job":
            fw._proc.kill()
            fw._proc.wait()
            wait = fw.submit(result, tmp_path)
        else:
            wait = fw.submit(result, tmp_path)
            fw._proc.kill()
        paths = wait()
    assert {p.name for p in paths} == {"diagram.png", "frame.png", "spectrum.png"}
    assert all(p.stat().st_size > 10_000 for p in paths)
    if when == "during the job":
        assert "drawing in this process" in caplog.text


@pytest.mark.parametrize(("ci", "words"), [
    ((-1.5e-5, 1.8e-5), "cannot be told from zero"),
    ((-0.0530, -0.0490), "against the flow) at 0.0510 ± 0.0020 m/s"),
])
def test_the_report_sentence_keeps_the_interval_and_the_unit_of_the_card(result, tmp_path, ci, words):
    """An interval that holds zero is said so (it used to collapse to ±0.0013 mm/s of a stationary object), and
    the sentence's celerity has the card's unit and width."""
    import dataclasses
    import html

    value = 1e-6 if ci[0] < 0 < ci[1] else -0.0510
    motion = dataclasses.replace(result.motion, celerity_m_s=value, celerity_ci95_m_s=ci)
    out = tmp_path / "r"
    write_outputs(dataclasses.replace(result, motion=motion), out, figures=False)
    sentence = html.unescape((out / "report.html").read_text()).split('<p class="sentence">')[1].split("</p>")[0]
    assert words in sentence, sentence
    assert "mm/s" not in sentence


def test_the_frame_figure_has_a_scale_bar_of_a_round_length(result):
    """The annotated frame carries a bar of 1, 2 or 5 x 10^n mm, as long as that many millimetres at the scale."""
    from grainplug.plotting.figures import plot_annotated_frame

    fig = plot_annotated_frame(result)
    ax = fig.axes[0]
    [label] = [t.get_text() for t in ax.texts if t.get_text().endswith(" mm")]
    mm = float(label.split()[0])
    assert mm / 10 ** np.floor(np.log10(mm)) in (1, 2, 5)
    lengths = [float(np.hypot(*np.ptp(line.get_xydata(), axis=0))) for line in ax.lines]
    assert any(abs(n - mm / result.mm_per_px) < 1e-6 for n in lengths)
    assert "-0.00" not in fig.axes[0].get_title()


def test_outputs_are_as_readable_as_any_file_the_user_makes(result, tmp_path):
    """A result folder and a single output file get the permissions of the user's umask (a lab shares
    them on a server), not the private 0700/0600 of a temporary file."""
    import os
    import stat

    from grainplug._atomic import atomic_file

    old = os.umask(0o022)
    try:
        result.save(tmp_path / "run", figures=False)
        with atomic_file(tmp_path / "one.txt") as tmp:
            tmp.write_text("x")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "run").stat().st_mode) == 0o755
    assert {stat.S_IMODE(f.stat().st_mode) for f in (tmp_path / "run").iterdir()} == {0o644}
    assert stat.S_IMODE((tmp_path / "one.txt").stat().st_mode) == 0o644


def test_a_short_record_has_its_time_axis_in_ms(result):
    """Under 0.1 s the diagram's time ticks read in ms (0.25, not 0.00025); the data stay in seconds."""
    import dataclasses

    from grainplug.plotting.figures import plot_diagram

    fast = dataclasses.replace(result, diagram=dataclasses.replace(result.diagram,
                                                                   time_s=result.diagram.time_s / 100))
    for res, unit in ((result, "s"), (fast, "ms")):
        fig = plot_diagram(res)
        ax = fig.axes[0]
        fig.canvas.draw()
        assert ax.get_xlabel() == f"time t ({unit})"
        labels = [t.get_text() for t in ax.get_xticklabels() if t.get_text()]
        assert labels and all(len(lab.replace("−", "")) <= 5 for lab in labels), labels
        assert ax.get_xlim()[1] == res.diagram.time_s[-1]


def test_the_diagram_legend_covers_no_data(result):
    """The diagram's own figure keeps its legend between the axes and the title (inside the axes it hid plug
    edges), with the title above it and both inside the figure."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from grainplug.plotting.figures import plot_diagram

    fig = plot_diagram(result)
    renderer = FigureCanvasAgg(fig).get_renderer()
    ax = fig.axes[0]
    axes_box = ax.get_window_extent(renderer)
    legend = ax.get_legend().get_window_extent(renderer)
    title = ax.title.get_window_extent(renderer)
    assert legend.y0 >= axes_box.y1 - 1e-6
    assert title.y0 >= legend.y1 - 1e-6
    assert title.y1 <= fig.bbox.y1 and legend.x0 >= 0 and legend.x1 <= fig.bbox.x1


def test_the_report_shows_figures_written_as_svg_only(result, tmp_path):
    """Figures in SVG only: the report shows them (it said "No figures were drawn"); in PDF only, it links them."""
    from grainplug.outputs import FigureOptions

    svg, pdf = tmp_path / "svg", tmp_path / "pdf"
    write_outputs(result, svg, figure_options=FigureOptions(formats=("svg",)))
    page = (svg / "report.html").read_text()
    assert page.count('src="data:image/svg+xml;base64,') == 3 and "No figures were drawn" not in page
    write_outputs(result, pdf, figure_options=FigureOptions(formats=("pdf",)))
    page = (pdf / "report.html").read_text()
    assert '<a href="diagram.pdf">diagram.pdf</a>' in page and "No figures were drawn" not in page


def test_save_returns_every_file_it_wrote(result, tmp_path):
    """Every figure format under its own key (diagram.svg and diagram.pdf used to overwrite diagram.npz's)."""
    from grainplug.outputs import PUBLICATION

    paths = result.save(tmp_path / "o", figure_options=PUBLICATION)
    assert {"diagram", "fig_diagram", "fig_diagram_svg", "fig_diagram_pdf", "fig_spectrum_pdf"} <= set(paths)
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert set(summary["outputs"]) <= set(paths)  # the same keys (plug_edges.csv is "edges")
    assert paths["diagram"].name == "diagram.npz" and paths["fig_diagram_svg"].name == "diagram.svg"
    assert sorted(p.name for p in paths.values()) == sorted(p.name for p in (tmp_path / "o").iterdir()
                                                           if not p.name.startswith("."))


def test_a_rising_flow_s_captions_say_where_the_flow_comes_from(result, tmp_path):
    """Flow up the tube: the diagram runs from the bottom of the view (the upstream end), and the edges are
    named upstream and downstream (the "upper" edge is the lower one in the image)."""
    import dataclasses

    out = tmp_path / "up"
    write_outputs(dataclasses.replace(result, flow_direction="up"), out)  # captions go with figures
    page = (out / "report.html").read_text()
    assert "from the bottom of the view, the upstream end" in page
    assert "upper (upstream) edges of the plugs, blue: lower (downstream) edges" in page


def test_the_report_says_what_the_corrections_keep_of_the_record(result, tmp_path):
    from grainplug.corrections import Corrections, apply_corrections

    t_end = float(result.diagram.time_s[-1])
    fixed = apply_corrections(result, Corrections().add("window", start_s=0.25 * t_end)
                              .add("no_plugs", start_s=0.5 * t_end, end_s=0.6 * t_end))
    write_outputs(fixed, tmp_path / "o", figures=False)
    page = (tmp_path / "o" / "report.html").read_text()
    assert f"the corrections keep {0.25 * t_end:.3f}–{t_end:.3f} s" in page and "marked as not plugs" in page


def test_what_the_corrections_keep_is_said_within_the_record(result, tmp_path):
    """A window beyond the record keeps nothing (it said "0.796–0.796 s"), spans are clipped to the record and
    joined (three overlapping ones summed past its length); an uncorrected run says nothing (a 30 fps record's
    rounded end time read as a window)."""
    import dataclasses

    from grainplug.corrections import Corrections, apply_corrections

    t_end = float(result.diagram.time_s[-1])
    none = apply_corrections(result, Corrections().add("window", start_s=t_end + 5))
    assert none.summary["kept_window_s"] is None
    spans = apply_corrections(result, Corrections().add("no_plugs", start_s=0.1 * t_end, end_s=0.3 * t_end)
                              .add("no_plugs", start_s=0.2 * t_end, end_s=0.3 * t_end)
                              .add("no_plugs", start_s=0.5 * t_end, end_s=t_end + 5))
    assert spans.summary["not_plugs_s"] == [[pytest.approx(0.1 * t_end), pytest.approx(0.3 * t_end)],
                                            [pytest.approx(0.5 * t_end), pytest.approx(t_end)]]
    write_outputs(spans, tmp_path / "s", figures=False)
    assert f"{0.7 * t_end:.3g} s marked as not plugs" in (tmp_path / "s" / "report.html").read_text()
    odd = dataclasses.replace(result, info=dataclasses.replace(result.info, fps=30.0))
    write_outputs(odd, tmp_path / "o", figures=False)
    assert "the corrections keep" not in (tmp_path / "o" / "report.html").read_text()


def test_figure_options_recorded_and_given_as_paths(tmp_path):
    """A record without formats gives the default formats (not all three); a style given as a Path is recorded as
    the string summary.json holds (a PosixPath never equalled it, and batch rewrote every reused run)."""
    from pathlib import Path

    from grainplug.outputs import FigureOptions

    assert FigureOptions.recorded({"figures": {"dpi": 150}}) == FigureOptions(dpi=150)
    sheet = tmp_path / "my.mplstyle"
    sheet.write_text("font.size: 7\n")
    given = FigureOptions(style=Path(sheet))
    assert given.as_record()["style"] == str(sheet) and FigureOptions.recorded({"figures": given.as_record()}) == given


def test_the_report_rounds_lambda_over_d_as_it_rounds_lambda(result, tmp_path):
    """A plug length known to ±40 mm reads "30 (0 to 80)": its λ/D beside it is rounded alike, not 11.12."""
    import dataclasses
    import html
    import re

    L = result.lengths.plug_length_mm
    wide = dataclasses.replace(result.lengths, plug_length_ci95_mm=(0.0, 2.3 * L))
    write_outputs(dataclasses.replace(result, lengths=wide), tmp_path / "r", figures=False)
    page = html.unescape((tmp_path / "r" / "report.html").read_text())
    ratio = re.search(r"λ/D = ([^,]+),", page).group(1)
    D = result.params.tube_diameter_mm
    value = ratio.split(" (")[0]
    assert " to " in ratio and value.isdigit() and abs(int(value) - L / D) <= 0.5, ratio
