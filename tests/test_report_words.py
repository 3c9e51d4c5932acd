"""The report names each setting a warning advises both as the library's keyword and as the command line's
option (issue 34: the CLI's report showed ``tube_outer_diameter_mm=`` only)."""

from __future__ import annotations

import re

import grainplug as gp
from grainplug.params import with_options


def test_the_report_gives_the_option_beside_the_keyword(tmp_path):
    truth = gp.datasets.sample_truth()["config"]
    res = gp.analyze(gp.datasets.sample_movie(), fps=truth["fps"])
    assert any("tube_outer_diameter_mm=" in w for w in res.warnings)  # the advice this is about
    res.save(tmp_path / "o", figures=False)
    page = re.sub(r"<[^>]+>", "", (tmp_path / "o" / "report.html").read_text())  # the text read
    assert "tube_outer_diameter_mm= (--tube-outer-diameter-mm)" in page



def test_the_command_line_s_report_names_the_option(tmp_path, capsys):
    """What `grainplug analyze` writes: the report's advice gives the flag the user types."""
    from test_cli_basics import run

    code, _, err = run(capsys, "analyze", gp.datasets.sample_movie(), "--out", tmp_path / "o")
    assert code == 0, err
    assert "--tube-outer-diameter-mm" in err  # the terminal's advice, as flags
    page = re.sub(r"<[^>]+>", "", (tmp_path / "o" / "report.html").read_text())
    assert "(--tube-outer-diameter-mm)" in page


def test_only_the_analysis_keywords_get_an_option():
    assert with_options("give start_s= or mm_per_px=") == "give start_s= (--start) or mm_per_px= (--mm-per-px)"
    # a function's argument, a dotted name and a comparison are left as they are
    for text in ("Calibration.plane_mm(points)", "frames=5 in grainplug.scale.axis_mm=", "a == b"):
        assert with_options(text) == text
