"""The grains' compactness from the light between an empty and a packed tube, on independently rendered contents
(tests/compactness_render.py: Beer–Lambert through the bore's chords, grain texture, camera noise, 8 bits)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from compactness_render import Contents, movie
from warned import codes

import grainplug as gp
from grainplug.calibration.background import grey_background
from grainplug.cli import main
from grainplug.corrections import Corrections, apply_corrections
from grainplug.errors import ParameterError

#: the issue's target: the plugs' and the bubbles' compactness within this of the truth
WITHIN = 0.03
MM_PER_PX = 0.125


def _analyze(cfg: Contents, **kw):
    frames, empty, packed = movie(cfg, **kw)
    return gp.analyze(frames, fps=250.0, mm_per_px=MM_PER_PX, background=grey_background([empty]),
                      packed=grey_background([packed]))


@pytest.mark.parametrize(("case", "kw"), [
    ("dense plugs, dilute bubbles", {}),
    ("weakly absorbing grains (packed lets 52 % through)", {"kappa_per_mm": 0.4}),
    ("strongly absorbing grains (packed lets 8 % through)", {"kappa_per_mm": 1.6}),
    ("loose plugs, dense rain", {"c_plug": 0.45, "c_bubble": 0.12}),
    ("coarse texture, noisy camera", {"texture": 0.3, "grain_px": 3.0, "noise": 5.0}),
])
def test_the_plugs_and_bubbles_compactness_is_read_within_0_03(case, kw):
    cfg = Contents(**kw)
    s = _analyze(cfg).summary["compactness"]
    assert s["note"] is None and s["n_plugs"] >= 3 and s["n_bubbles"] >= 3, s
    assert abs(s["plugs"] - cfg.c_plug) <= WITHIN, (case, s)
    assert abs(s["bubbles"] - cfg.c_bubble) <= WITHIN, (case, s)
    for phase, truth in (("plugs", cfg.c_plug), ("bubbles", cfg.c_bubble)):
        lo, hi = s[f"{phase}_ci95"]
        assert lo <= truth <= hi, (case, phase, s)


def test_references_taken_under_another_lamp_level_are_scaled_to_the_movie_s():
    """The empty picture 10 % brighter and the packed one 10 % darker than the movie's lamp: read plainly, the plugs
    would be 0.03 low and the bubbles 0.03 high; scaled by the background beside the tube, both are right."""
    cfg = Contents()
    s = _analyze(cfg, empty_lamp=cfg.lamp * 1.1, packed_lamp=cfg.lamp * 0.9).summary["compactness"]
    assert abs(s["plugs"] - cfg.c_plug) <= WITHIN and abs(s["bubbles"] - cfg.c_bubble) <= WITHIN, s


def test_without_references_it_says_what_is_not_measured():
    frames, _, _ = movie(Contents(n_frames=60))
    s = gp.analyze(frames, fps=250.0, mm_per_px=MM_PER_PX).summary["compactness"]
    assert s["plugs"] is None and s["bubbles"] is None
    assert "not measured" in s["note"] and "packed" in s["note"]


def test_in_front_light_the_references_are_said_unusable():
    frames, empty, packed = movie(Contents(n_frames=60))
    res = gp.analyze(255 - frames, fps=250.0, mm_per_px=MM_PER_PX, background=grey_background([255 - empty]),
                     packed=grey_background([255 - packed]))
    assert res.compactness is None and "compactness.unmeasured" in codes(res)


def test_bad_references_are_refused_in_one_line(tmp_path, capsys):
    import tifffile
    frames, empty, packed = movie(Contents(n_frames=40))
    tifffile.imwrite(tmp_path / "movie.tif", frames)
    tifffile.imwrite(tmp_path / "empty.tif", empty.astype(np.uint8))
    tifffile.imwrite(tmp_path / "packed.tif", packed.astype(np.uint8))
    tifffile.imwrite(tmp_path / "small.tif", packed[:100].astype(np.uint8))
    base = ["analyze", str(tmp_path / "movie.tif"), "--fps", "250", "--mm-per-px", str(MM_PER_PX), "--no-figures"]
    for extra, says in (
        (["--background", str(tmp_path / "packed.tif"), "--packed", str(tmp_path / "empty.tif")], "must be darker"),
        (["--packed", str(tmp_path / "packed.tif")], "needs the empty tube"),
        (["--background", str(tmp_path / "empty.tif"), "--packed", str(tmp_path / "small.tif")],
         "the packed picture is 96 x 100 px"),
    ):
        out = tmp_path / f"out{len(says)}"
        code = main([*base, "--out", str(out), *extra])
        err = capsys.readouterr().err
        assert code != 0 and err.count("\n") == 1 and says in err, err
        assert not out.exists()
    with pytest.raises(ParameterError, match="needs the empty tube"):
        gp.analyze(frames, fps=250.0, mm_per_px=MM_PER_PX, packed=grey_background([packed]))


def test_the_command_line_reads_it_and_corrections_recount_it(tmp_path, capsys):
    import tifffile
    cfg = Contents(n_frames=100)
    frames, empty, packed = movie(cfg)
    tifffile.imwrite(tmp_path / "movie.tif", frames)
    tifffile.imwrite(tmp_path / "empty.tif", np.rint(empty).astype(np.uint8))
    tifffile.imwrite(tmp_path / "packed.tif", np.rint(packed).astype(np.uint8))
    out = tmp_path / "out"
    code = main(["analyze", str(tmp_path / "movie.tif"), "--fps", "250", "--mm-per-px", str(MM_PER_PX),
                 "--background", str(tmp_path / "empty.tif"), "--packed", str(tmp_path / "packed.tif"),
                 "--packed-compactness", "0.62", "--no-figures", "--out", str(out)])
    printed = capsys.readouterr().out
    assert code == 0 and "compactness     plugs 0." in printed
    s = json.loads((out / "summary.json").read_text())
    assert s["compactness"]["packed_reference"] == 0.62
    assert s["parameters"]["packed"]["sha256"]  # the reference's identity kept
    # every compactness scales with the packed reference's
    assert abs(s["compactness"]["plugs"] - cfg.c_plug * 0.62 / 0.60) <= WITHIN
    import xarray as xr
    with xr.open_dataset(out / "fields.nc", engine="scipy") as ds:  # beside the simulation's: same names and units
        assert ds["c"].dims == ("time", "z") and ds["c"].attrs["units"] == "1"
        assert ds["time_s"].shape == (cfg.n_frames,) and "position_mm" in ds.coords
        assert s["outputs"]["fields"] == "fields.nc"
        field = ds["c"].values
    res = gp.load_result(out)
    np.testing.assert_allclose(field, res.compactness_field)
    tid = next(iter(res.compactness.per_track))
    ex = apply_corrections(res, Corrections().add("exclude", track=tid))
    assert ex.compactness.n_plugs == res.compactness.n_plugs - 1 and tid not in ex.compactness.per_track
