"""frame.png's title gives the bore at the scale in use (issue 34: it said "bore 3 mm = 15.87 px", the tube model's
reading, when the calibration in use made it 16.2 px)."""

from __future__ import annotations

import re

import numpy as np
import pytest
from test_calibrate import uniform_calibration

import grainplug as gp
from grainplug.plotting.figures import plot_annotated_frame
from grainplug.synthetic import SynthConfig
from grainplug.synthetic.render import Renderer


@pytest.fixture(scope="module")
def frames():
    cfg = SynthConfig(n_frames=60, width_px=64, height_px=300, seed=4, rgb=False)
    return cfg, np.stack(list(Renderer(cfg).frames()))


def _title_px(res: gp.AnalysisResult) -> tuple[float, str]:
    fig = plot_annotated_frame(res)
    title = fig.axes[0].get_title()
    return float(re.search(r"bore 3 mm = ([\d.]+) px", title).group(1)), title


def test_the_bore_is_given_at_the_scale_in_use(frames):
    cfg, fr = frames
    typed = gp.analyze(fr, fps=cfg.fps, mm_per_px=cfg.mm_per_px * 1.03)
    px, _ = _title_px(typed)
    assert px == pytest.approx(3.0 / (cfg.mm_per_px * 1.03), abs=0.01)
    calibrated = gp.analyze(fr, fps=cfg.fps, calibration=uniform_calibration(cfg.mm_per_px * 0.98, shape=fr.shape[1:]))
    px, title = _title_px(calibrated)
    assert px == pytest.approx(3.0 / (cfg.mm_per_px * 0.98), abs=0.01)
    assert "the tube model reads" in title  # the tube's own reading is shown beside it when it differs
    own = gp.analyze(fr, fps=cfg.fps)
    px, title = _title_px(own)
    assert px == pytest.approx(own.bore.diameter_px, abs=0.01) and "the tube model reads" not in title
