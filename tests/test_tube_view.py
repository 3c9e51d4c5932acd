"""Frames where the tube is not in view (issue 33, bad input): something in front of it, the camera knocked off
it, the lamp out for a stretch. They are found from the walls, said, and not measured."""

from __future__ import annotations

import numpy as np
import pytest

from grainplug.calibration.tube import find_tube
from grainplug.diagram.extract import probes_along_tube
from grainplug.measures.view import tube_view
from grainplug.synthetic import SynthConfig
from grainplug.synthetic.render import Renderer


@pytest.fixture(scope="module")
def movie():
    cfg = SynthConfig(n_frames=200, width_px=64, height_px=400, fps=250.0, seed=3, rgb=False)
    return cfg, np.stack(list(Renderer(cfg).frames()))


def variants(fr: np.ndarray) -> dict[str, tuple[np.ndarray, bool]]:
    """Movies and whether frames 80-109 lose the tube."""
    rng = np.random.default_rng(0)
    out = {"clean": (fr, False)}
    a = fr.copy()
    a[80:110] = np.roll(fr[80:110], 30, axis=2)  # the camera knocked 30 px aside
    out["knocked aside"] = (a, True)
    b = fr.copy()
    b[80:110] = np.clip(np.median(fr[:, :, :5]) + rng.normal(0, 3, b[80:110].shape), 0, 255)  # a card in front
    out["hidden"] = (b, True)
    c = fr.copy()
    c[80:110] = np.clip(fr[80:110] * 0.6, 0, 255).astype(fr.dtype)  # a shadow: the tube still seen
    out["shadow"] = (c, False)
    shake = np.rint(3 * np.sin(2 * np.pi * 30 * np.arange(len(fr)) / 250.0)).astype(int)
    out["shake 3 px"] = (np.stack([np.roll(f, s, axis=1) for f, s in zip(fr, shake, strict=True)]), False)
    return out


@pytest.mark.parametrize("name", ["clean", "knocked aside", "hidden", "shadow", "shake 3 px"])
def test_the_frames_without_the_tube_are_found_from_its_walls(movie, name):
    _, fr = movie
    m, lost = variants(fr)[name]
    tube = find_tube(list(fr[::10]))
    band, _, probes = probes_along_tube(tube)
    _, across, _, _ = probes.split(np.stack([band.profile(f) for f in m]))
    view = tube_view(across, len(m))
    assert view.stretches == ([(80, 109)] if lost else [])


@pytest.mark.parametrize("name", ["knocked aside", "hidden"])
def test_an_analysis_says_which_frames_lost_the_tube_and_does_not_measure_them(movie, name, tmp_path):
    import json

    from warned import of_code

    import grainplug as gp

    cfg, fr = movie
    m, _ = variants(fr)[name]
    clean = gp.analyze(fr, fps=cfg.fps, mm_per_px=cfg.mm_per_px)
    res = gp.analyze(m, fps=cfg.fps, mm_per_px=cfg.mm_per_px)
    [said] = of_code(res, "frames.tube_unseen")
    assert "80-109" in said
    assert res.tube_unseen == ((80, 109),)
    assert not np.isin(res.runs.frame, np.arange(80, 110)).any()  # nothing measured there
    assert res.celerity_m_s == pytest.approx(cfg.celerity_m_s, rel=0.03)
    assert res.plug_length_mm == pytest.approx(clean.plug_length_mm, rel=0.03)
    assert not of_code(clean, "frames.tube_unseen")
    res.save(tmp_path / "o", figures=False, report=False)
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["tube_unseen_frames"] == [[80, 109]]
    again = gp.apply_corrections(gp.load_result(tmp_path / "o"), gp.Corrections().add("blind", from_mm=20, to_mm=25))
    assert not np.isin(again.runs.frame, np.arange(80, 110)).any()  # found again: still not there
