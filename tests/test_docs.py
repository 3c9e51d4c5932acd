"""The docs against the code: the README's Python examples, run as written, in order, in one namespace;
the tables documented."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def python_blocks(path: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", path.read_text(), flags=re.S)


def test_readme_has_python_examples():
    assert len(python_blocks(ROOT / "README.md")) >= 3


def test_readme_python_examples_run(tmp_path, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")  # the test's choice, as a notebook's would be its own
    import matplotlib.pyplot as plt

    monkeypatch.chdir(tmp_path)
    namespace: dict[str, object] = {}
    for k, block in enumerate(python_blocks(ROOT / "README.md")):
        try:
            exec(compile(block, f"README.md python block {k + 1}", "exec"), namespace)
        except Exception as exc:  # name the block that broke
            pytest.fail(f"README python block {k + 1} failed: {type(exc).__name__}: {exc}\n{block}")
    plt.close("all")
    assert (tmp_path / "out" / "sample" / "result.npz").exists()
    res = namespace["res"]
    assert res.info.format.startswith("array") and res.has_plugs


def test_the_tables_documented_are_the_tables_written():
    from grainplug.summary import EDGE_SCHEMA, TRACK_SCHEMA

    text = (ROOT / "docs" / "analysis.md").read_text()
    for name, schema in (("plug_edges.csv", EDGE_SCHEMA), ("tracks.csv", TRACK_SCHEMA)):
        section = text.split(f"`{name}`:\n\n", 1)[1].split("\n\n", 1)[0]
        documented = [line.split("|")[1:4] for line in section.splitlines()[2:]]
        assert [(c.strip().strip("`"), d.strip(), m.strip()) for c, d, m in documented] == \
            [(c, d, m) for c, (d, m) in schema.items()], name


def test_the_corrections_file_documented_is_read():
    """docs/review.md's example of a hand-written corrections.json is a file grainplug reads."""
    import json

    from grainplug.corrections import Corrections

    blocks = re.findall(r"```json\n(.*?)```", (ROOT / "docs" / "review.md").read_text(), flags=re.S)
    assert len(blocks) == 1
    corr = Corrections.from_dict(json.loads(blocks[0]))
    assert [e.describe() for e in corr.edits] == [
        "kept the frames from 0.2 s on", "excluded track 4", "split track 2 at analysed frame 150"]


def test_the_warning_codes_documented_are_the_codes():
    """docs/analysis.md's table of warning codes is grainplug.warning_codes.CODES: every code, in order, with its
    meaning and fix."""
    from grainplug.warning_codes import CODES

    text = (ROOT / "docs" / "analysis.md").read_text()
    section = text.split("## Warning codes\n", 1)[1].split("\n## ", 1)[0]
    rows = [line.strip().strip("|").split("|") for line in section.splitlines() if line.startswith("| `")]
    assert [tuple(cell.strip() for cell in row) for row in rows] == [
        (f"`{code}`", meaning, fix) for code, (meaning, fix) in CODES.items()]


#: codes of CODES that no warning site gives, and why
NOT_GIVEN_AT_A_SITE = {
    "legacy.uncoded": "code_of's answer for a warning read from a result.npz saved before codes",
    "movie.other": "a catch-all for what a camera file says of itself; no reader uses it yet",
    "scale.calibration_varies_along_tube": "kept to read results saved when it was given; positions are now mapped",
}


def test_every_warning_code_is_given_somewhere_and_every_code_given_is_known():
    """Each code is given by a ``coded("code", ...)`` or ``all_coded("code", ...)`` in src/ (a code no warning
    carries is a row of the table that means nothing), and each code given there is in CODES (a misspelt one
    would fail only when its warning is made)."""
    from grainplug.warning_codes import CODES

    given = {m for path in (ROOT / "src" / "grainplug").rglob("*.py") if path.name != "warning_codes.py"  # its example
             for m in re.findall(r"\b(?:all_)?coded\(\s*\"([^\"]+)\"", path.read_text())}
    assert given <= set(CODES), sorted(given - set(CODES))
    assert set(CODES) - given == set(NOT_GIVEN_AT_A_SITE), sorted(set(CODES) - given)


def test_the_readme_counts_the_paper_s_checks_right():
    """The README's "checks N statements" is the number `grainplug paper` checks (it said 26 of 25)."""
    from grainplug.campaigns.paper import reproduce

    said = re.search(r"checks (\d+) statements", (ROOT / "README.md").read_text())
    assert said, "the README no longer counts the paper's checks"
    assert int(said.group(1)) == len(reproduce(simulate=False).checks)
