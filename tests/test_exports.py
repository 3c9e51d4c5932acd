"""Exports for the tools labs use: the diagram as a calibrated float32 TIFF (Fiji), the edges in trackpy's layout."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import tifffile

import grainplug as gp
from grainplug.synthetic import SynthConfig, synthesize

CELERITY = -0.05


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("x")
    movie = synthesize(SynthConfig(n_frames=120, seed=3, fps=250.0, celerity_m_s=CELERITY), folder / "m", fmt="tiff")
    res = gp.analyze(movie.movie)
    res.save(folder / "out", figures=False, report=False)
    return res, folder / "out"


def test_the_diagram_opens_in_fiji_in_mm_and_seconds(run):
    res, out = run
    with tifffile.TiffFile(out / "diagram.tif") as tif:
        values = tif.asarray()
        meta = tif.imagej_metadata
        page = tif.pages[0]
        x_res = page.tags["XResolution"].value
        y_res = page.tags["YResolution"].value
    assert values.dtype == np.float32
    np.testing.assert_array_equal(values, np.load(out / "diagram.npz")["values"])
    assert meta["unit"] == "mm" and meta["yunit"] == "s"
    assert x_res[1] / x_res[0] == pytest.approx(res.mm_per_px, rel=1e-6)  # mm per pixel along the tube
    assert y_res[1] / y_res[0] == pytest.approx(1 / res.info.fps, rel=1e-6)  # s per row
    assert values.nbytes <= (out / "diagram.tif").stat().st_size < values.nbytes + 10_000  # small: no more than it


def test_the_edges_in_trackpy_s_layout_with_their_velocity(run):
    _, out = run
    long = pd.read_csv(out / "edges_long.csv")
    assert list(long.columns) == ["frame", "time_s", "particle", "edge", "position_mm", "velocity_m_s"]
    wide = pd.read_csv(out / "plug_edges.csv")
    assert len(long) == wide.top_mm.notna().sum() + wide.bottom_mm.notna().sum()
    assert set(long.edge) == {"upstream", "downstream"} and set(long.particle) <= set(wide.plug_id)
    # every edge moves with the train: the median velocity is the celerity
    assert long.velocity_m_s.median() == pytest.approx(CELERITY, rel=0.03)
    one = long[(long.particle == long.particle.iloc[0]) & (long.edge == "upstream")].sort_values("frame")
    inner = one.iloc[1:-1]
    np.testing.assert_allclose(  # a central difference
        inner.velocity_m_s, ((one.position_mm.shift(-1) - one.position_mm.shift(1)) /
                             (one.time_s.shift(-1) - one.time_s.shift(1)) / 1000).iloc[1:-1], rtol=1e-3, atol=1e-5)
