"""Data shipped with grainplug: a sample movie with its truth, and the paper's Tables 1 and 2.

:func:`sample_movie` is a short synthetic movie of propagative plug flow (H.264,
400 frames at 250 fps, 0.185 mm/px), rendered with known truth (:func:`sample_truth`):
what the README and the tutorial analyse.

Source: C. A. Alvarez, E. M. Franklin, *Intermittent gravity-driven flow of
grains through narrow pipes*, Physica A 465 (2017) 725-741,
doi:10.1016/j.physa.2016.08.071 — Table 1 (17 runs, propagative regime,
grains of 106-212 um) and Table 2 (15 runs, oscillating regime at low
amplitude, rough grains of 212-300 um). Values as printed; the loaders add
``plug_length_mm``, ``regime``, ``surface`` (Table 2: rough, from the text) and
``group`` (``propagative/rough``, ``propagative/smooth``, ``oscillating``).
"""

from __future__ import annotations

import json
from functools import cache
from importlib import resources
from pathlib import Path

import pandas as pd

_PKG = "grainplug.data"


@cache
def source() -> dict:
    """Citation, DOI, captions and conditions of the shipped tables."""
    return json.loads(resources.files(_PKG).joinpath("alvarez_franklin_2017.json").read_text())


def sample_movie() -> Path:
    """Path of the bundled sample movie (``plugflow_sample.mp4``)."""
    return Path(str(resources.files(_PKG).joinpath("sample").joinpath("plugflow_sample.mp4")))


def sample_truth() -> dict:
    """What the sample movie holds (celerity, plug and bubble lengths, scale...), as rendered."""
    return json.loads(resources.files(_PKG).joinpath("sample").joinpath("plugflow_sample_truth.json").read_text())


def _read(name: str) -> pd.DataFrame:
    with resources.files(_PKG).joinpath(name).open() as fh:
        return pd.read_csv(fh)


def table1() -> pd.DataFrame:
    """The paper's Table 1 (propagative regime), one row per run."""
    df = _read(source()["tables"]["table1"]["file"])
    df["plug_length_mm"] = df["plug_length_cm"] * 10.0
    df["regime"] = "propagative"
    df["group"] = "propagative/" + df["surface"]
    df["table"] = 1
    return df


def table2() -> pd.DataFrame:
    """The paper's Table 2 (oscillating regime, low amplitude), one row per run."""
    df = _read(source()["tables"]["table2"]["file"])
    df["plug_length_mm"] = df["plug_length_cm"] * 10.0
    df["surface"] = "rough"
    df["regime"] = "oscillating"
    df["group"] = "oscillating"
    df["table"] = 2
    return df


def paper_runs() -> pd.DataFrame:
    """Tables 1 and 2 stacked, with ``table``, ``regime`` and ``group`` columns."""
    cols = ["table", "run", "regime", "group", "surface", "mass_flow_rate_g_s", "humidity_pct",
            "celerity_m_s", "plug_length_cm", "plug_length_mm"]
    return pd.concat([table1()[cols], table2()[cols]], ignore_index=True)


__all__ = ["paper_runs", "sample_movie", "sample_truth", "source", "table1", "table2"]
