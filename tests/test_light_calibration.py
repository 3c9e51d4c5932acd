"""Light calibration (issue 16, item 2): a picture of the tube with nothing moving in it flat-fields the diagram.

The movies are grainplug's synthetic ones seen through dirty glass and a steep lamp gradient: dark
spots 1-2 mm wide and 40-60 % deep fixed on the tube (not on the lamp beside it, which the analysis
reads the light on), the light halving along the view. The background is the same tube, empty,
through the same glass.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import tifffile
from warned import of_code

import grainplug as gp
from grainplug.campaigns.manifest import read_manifest
from grainplug.cli import main
from grainplug.synthetic import SynthConfig
from grainplug.synthetic.render import Renderer

H, W = 500, 96
CFG = SynthConfig(n_frames=200, width_px=W, height_px=H, fps=500.0, seed=4, rgb=False, bit_depth=8,
                  noise_sigma=2.0)


def _glass(rng: np.random.Generator) -> np.ndarray:
    """Dirt on the tube's glass (within 20 px of its axis: the lamp beside the tube is clean), and a lamp whose
    light halves along the view (everywhere)."""
    yy, xx = np.mgrid[0:H, 0:W]
    p = np.ones((H, W), np.float32)
    on_tube = np.abs(xx - W / 2) < 20
    for _ in range(8):
        y0, s = rng.uniform(40, H - 40), rng.uniform(4, 8)
        p *= 1 - on_tube * rng.uniform(0.4, 0.6) * np.exp(-0.5 * ((yy - y0) / s) ** 2)
    return p * (1 - 0.5 * yy / H)


@pytest.fixture(scope="module")
def movies() -> dict[str, np.ndarray]:
    glass = _glass(np.random.default_rng(0))
    clean = np.stack(list(Renderer(CFG).frames())).astype(np.float32)
    empty_cfg = SynthConfig(**{**CFG.__dict__, "regime": "none", "no_plug_fill": "empty",
                               "falling_grains_per_mm": 0.0, "n_frames": 10})
    empty = np.stack(list(Renderer(empty_cfg).frames())).astype(np.float32)

    def through(f: np.ndarray) -> np.ndarray:
        return np.clip(f * glass, 0, 255).astype(np.uint8)

    return {"clean": clean.astype(np.uint8), "dirty": through(clean), "empty": through(empty)}


def test_a_background_removes_fixed_spots_and_gradients(movies):
    clean = gp.analyze(movies["clean"], fps=500.0, mm_per_px=CFG.mm_per_px)
    dirty = gp.analyze(movies["dirty"], fps=500.0, mm_per_px=CFG.mm_per_px)
    bg = gp.Background(np.mean(movies["empty"], axis=0, dtype=np.float64).astype(np.float32), {"name": "empty"}, 10)
    fixed = gp.analyze(movies["dirty"], fps=500.0, mm_per_px=CFG.mm_per_px, background=bg)
    # the case is hard: without the background, the spots are read as plug edges, or (the record too short for the
    # places to be judged) their edges, still, are taken for still objects' and blinded
    assert abs(dirty.plug_length_mm / clean.plug_length_mm - 1) > 0.1 or dirty.blind
    # with it, nothing is blind, and the measures are those of the clean movie
    assert not fixed.blind
    assert fixed.celerity_m_s == pytest.approx(clean.celerity_m_s, rel=0.01)
    assert fixed.plug_length_mm == pytest.approx(clean.plug_length_mm, rel=0.02)
    assert fixed.celerity_m_s == pytest.approx(CFG.celerity_m_s, rel=0.02)
    assert fixed.summary["parameters"]["background"]["name"] == "empty"


def test_background_from_the_command_line(tmp_path, movies, capsys):
    tifffile.imwrite(tmp_path / "movie.tif", movies["dirty"], metadata={"fps": 500.0})
    tifffile.imwrite(tmp_path / "empty.tif", movies["empty"])
    out = tmp_path / "out"
    assert main(["analyze", str(tmp_path / "movie.tif"), "--out", str(out), "--fps", "500",
                 "--mm-per-px", str(CFG.mm_per_px), "--background", str(tmp_path / "empty.tif"),
                 "--no-figures"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["parameters"]["background"]["name"] == "empty.tif" and len(s["parameters"]["background"]["sha256"]) == 64
    assert s["parameters"]["background"]["n_frames"] == 10
    assert s["celerity_m_s"] == pytest.approx(CFG.celerity_m_s, rel=0.02)
    capsys.readouterr()
    # a background of another size is one clear line, and nothing is written
    tifffile.imwrite(tmp_path / "small.tif", movies["empty"][:, :200])
    code = main(["analyze", str(tmp_path / "movie.tif"), "--out", str(tmp_path / "o2"), "--fps", "500",
                 "--background", str(tmp_path / "small.tif")])
    err = capsys.readouterr().err
    assert code != 0 and err.count("\n") == 1 and "the background is 96 x 200 px but the movie's frames" in err
    assert not (tmp_path / "o2").exists()
    code = main(["analyze", str(tmp_path / "movie.tif"), "--out", str(tmp_path / "o3"), "--fps", "500",
                 "--background", str(tmp_path / "missing.tif")])
    err = capsys.readouterr().err
    assert code != 0 and err.count("\n") == 1 and "no such background file" in err


def test_a_dark_background_is_said(movies):
    dark = gp.Background(np.zeros((H, W), np.float32) + np.linspace(0, 1, H, dtype=np.float32)[:, None] ** 8, {}, 1)
    res = gp.analyze(movies["dirty"], fps=500.0, mm_per_px=CFG.mm_per_px, background=dark)
    [said] = of_code(res, "light.background")
    assert said.startswith("the background is dark over "), res.warnings


def test_manifest_background_column(tmp_path, movies):
    tifffile.imwrite(tmp_path / "empty.tif", movies["empty"])
    (tmp_path / "m.csv").write_text("run,movie,background\na,a.tif,empty.tif\nb,b.tif,\n")
    a, b = read_manifest(tmp_path / "m.csv")
    assert a.params.background.image.shape == (H, W) and b.params.background is None
    assert "background" not in a.meta
