"""What a user needs to reuse and cite grainplug ships with it, and stays in step with the code."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import grainplug as gp

ROOT = Path(__file__).resolve().parent.parent


def test_the_declared_licence_is_shipped():
    """The licence is declared as PEP 639 has it (an SPDX expression and the file shipped): the table form
    (``{ text = "MIT" }``) makes setuptools print a deprecation notice at every install (``make demo``)."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    project = config["project"]
    assert project["license"] == "MIT" and project["license-files"] == ["LICENSE"]
    # setuptools reads an SPDX string from 77.0 on (older ones refuse it)
    assert any(re.fullmatch(r"setuptools\s*>=\s*(\d+)(\.\d+)*", r) and int(re.findall(r"\d+", r)[0]) >= 77
               for r in config["build-system"]["requires"])
    assert not any(c.startswith("License ::") for c in project.get("classifiers", []))  # PEP 639: not both
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("MIT License") and "WITHOUT WARRANTY" in text


def test_the_citation_file_names_this_version_and_the_paper():
    cff = (ROOT / "CITATION.cff").read_text()
    assert re.search(r"^cff-version: 1\.2\.0$", cff, re.M)
    assert re.search(rf'^version: "{re.escape(gp.__version__)}"$', cff, re.M), "CITATION.cff's version lags"
    assert re.search(r'^license: MIT$', cff, re.M)
    assert 'doi: "10.1016/j.physa.2016.08.071"' in cff  # the paper the methods come from
