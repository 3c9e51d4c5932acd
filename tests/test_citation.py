"""What a user needs to reuse and cite grainplug ships with it, and stays in step with the code."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import grainplug as gp

ROOT = Path(__file__).resolve().parent.parent


def test_the_declared_licence_is_shipped():
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["license"]["text"]
    text = (ROOT / "LICENSE").read_text()
    assert declared == "MIT" and text.startswith("MIT License") and "WITHOUT WARRANTY" in text


def test_the_citation_file_names_this_version_and_the_paper():
    cff = (ROOT / "CITATION.cff").read_text()
    assert re.search(r"^cff-version: 1\.2\.0$", cff, re.M)
    assert re.search(rf'^version: "{re.escape(gp.__version__)}"$', cff, re.M), "CITATION.cff's version lags"
    assert re.search(r'^license: MIT$', cff, re.M)
    assert 'doi: "10.1016/j.physa.2016.08.071"' in cff  # the paper the methods come from
