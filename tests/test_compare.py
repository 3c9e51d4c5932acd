"""gp.compare: a movie's analysis and a simulation reduced to the same figures and units."""

from __future__ import annotations

import json

import numpy as np
import pytest
from compactness_render import Contents, movie

import grainplug as gp
from grainplug.calibration.background import grey_background
from grainplug.errors import ParameterError
from grainplug.simulation import SimulationParams
from grainplug.simulation.state import SimulationResult
from grainplug.stability import ModelParams


def _train(speed_vc: float, *, c_plug: float = 0.55, c_bubble: float = 0.05, v_grains_vc: float = 0.02,
           plug_D: float = 12.0, period_D: float = 30.0) -> SimulationResult:
    """Model fields of a plug train moving at ``speed_vc`` (units of v_c) whose grains move at ``v_grains_vc``."""
    p = ModelParams()
    L, n, nt = 120.0, 480, 401
    sim = SimulationParams(length_D=L, n_cells=n, duration_tc=200.0, output_interval_tc=0.5)
    z = (np.arange(n) + 0.5) * L / n
    t = np.arange(nt) * 0.5
    ph = (z[None, :] - speed_vc * t[:, None]) % period_D
    half = 0.5 * (c_plug - c_bubble)
    c = (c_bubble + half * (np.tanh(ph / 0.4) - np.tanh((ph - plug_D) / 0.4))
         + half * (1 + np.tanh((ph - period_D) / 0.4)))
    ones = np.ones_like(c)
    return SimulationResult(model=p, params=sim, z=z, time=t, c=c, v=v_grains_vc * ones, P=ones,
                            grain_total=np.ones(nt), air_total=np.ones(nt), n_steps=0, wall_s=0.0)


@pytest.fixture(scope="module")
def measured():
    cfg = Contents()
    frames, empty, packed = movie(cfg)
    return cfg, gp.analyze(frames, fps=250.0, mm_per_px=0.125, background=grey_background([empty]),
                           packed=grey_background([packed]))


def test_both_sides_in_the_same_figures(measured):
    cfg, res = measured
    sim = _train(-0.3)
    cmp = gp.compare(res, sim)
    e, m = cmp.experiment, cmp.model
    # the experiment: as its own summary says
    assert e.celerity_m_s == res.celerity_m_s and e.plug_length_mm == res.plug_length_mm
    assert e.compactness_plugs == pytest.approx(cfg.c_plug, abs=0.03)
    assert e.compactness_bubbles == pytest.approx(cfg.c_bubble, abs=0.03)
    # the model: its fields' known pattern, measured as a movie's, in m/s and mm, positive downstream
    assert m.regime == "propagative" and m.celerity_m_s == pytest.approx(-0.3 * sim.model.v_c_m_s, rel=0.01)
    assert m.plug_length_mm == pytest.approx(36.0, rel=0.02) and m.bubble_length_mm == pytest.approx(54.0, rel=0.02)
    assert m.compactness_plugs == pytest.approx(0.55, abs=0.02) and m.compactness_bubbles == pytest.approx(0.05,
                                                                                                         abs=0.02)
    assert m.grain_velocity_in_plugs_m_s == pytest.approx(0.02 * sim.model.v_c_m_s, rel=1e-6)
    lo, *_, hi = m.compactness_quantiles
    assert lo == pytest.approx(0.05, abs=0.01) and hi == pytest.approx(0.55, abs=0.01)
    # what the experiment lacks is said, not zero
    assert e.grain_velocity_in_plugs_m_s is None and any("grain velocity" in n for n in cmp.notes)
    rows = {r["quantity"]: r for r in cmp.table()}
    assert rows["compactness in the plugs"]["unit"] == "1" and rows["celerity (positive downstream)"]["unit"] == "m/s"
    json.dumps(cmp.as_dict())  # JSON-ready
    fig = cmp.plot()
    assert len(fig.axes) == 2
    import matplotlib.pyplot as plt
    plt.close(fig)


def test_a_model_without_bubbles_and_an_analysis_without_references_say_so():
    frames, _, _ = movie(Contents(n_frames=60))
    res = gp.analyze(frames, fps=250.0, mm_per_px=0.125)
    cmp = gp.compare(res, _train(-0.3, c_plug=0.58, c_bubble=0.56))
    assert cmp.experiment.compactness_plugs is None
    assert any("experiment: no compactness" in n for n in cmp.notes)
    assert any("model: the compactness hardly varies" in n for n in cmp.notes)


def test_anything_else_is_refused_in_one_line():
    with pytest.raises(ParameterError, match="result must be an analysis"):
        gp.compare("result.npz", _train(-0.3))
