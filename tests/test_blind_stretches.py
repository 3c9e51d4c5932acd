"""Blind stretches (issue 33, item 3): a clamp, a label or a fitting hides the tube's contents there.

A plug touching one is cut there (its length not used, its other edge still times the train), a bubble
across one is not measured, and nothing of it is taken for a plug. Given as ``mask_mm`` (``--mask``)
or found where nothing changes over the record.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from warned import of_code

import grainplug as gp
from grainplug.cli import main
from grainplug.synthetic import SynthConfig
from grainplug.synthetic.render import Renderer


@pytest.fixture(scope="module")
def clamped():
    """A plug train (10 mm plugs, 8 mm bubbles, +0.05 m/s) with a dark clamp over rows 300-329 (55.5-61.1 mm)."""
    cfg = SynthConfig(n_frames=200, seed=7, celerity_m_s=0.05, plug_length_mm=10, bubble_length_mm=8,
                      plug_length_sd_mm=1, bubble_length_sd_mm=1, rgb=False)
    frames = np.stack(list(Renderer(cfg).frames()))
    clean = gp.analyze(frames, fps=cfg.fps, mm_per_px=cfg.mm_per_px)
    frames[:, 300:330] = np.clip(30 + np.random.default_rng(1).normal(0, 3, frames[:, 300:330].shape), 0, 255)
    return cfg, frames, clean


def test_no_plug_touching_a_blind_stretch_is_measured_whole(clamped):
    cfg, frames, _ = clamped
    res = gp.analyze(frames, fps=cfg.fps, mm_per_px=cfg.mm_per_px, mask_mm=[(55.0, 62.0)])
    edges = res.edges
    for col in ("top_mm", "bottom_mm"):  # no edge measured inside the blind stretch or against it
        v = edges[col].dropna()
        assert not ((v > 54.9) & (v < 62.1)).any(), v[(v > 54.9) & (v < 62.1)]
    # every plug measured whole lies on one side of it
    whole = edges.dropna()
    assert ((whole.bottom_mm < 55.0) | (whole.top_mm > 62.0)).all()


def test_a_bubble_across_a_blind_stretch_is_not_measured(clamped):
    cfg, frames, clean = clamped
    res = gp.analyze(frames, fps=cfg.fps, mm_per_px=cfg.mm_per_px, mask_mm=[(55.0, 62.0)])
    assert res.bubble_length_mm == pytest.approx(clean.bubble_length_mm, rel=0.05)
    # no bubble measured holds the stretch: every bubble pair measured is seen whole on one side of it
    e = res.edges.set_index(["frame", "plug_id"])
    for up, down in res.bubbles[["upstream_plug_id", "downstream_plug_id"]].itertuples(index=False):
        a = e.xs(up, level="plug_id").bottom_mm
        b = e.xs(down, level="plug_id").top_mm
        gaps = (a.to_frame().join(b, how="inner")).dropna()
        inside = gaps[(gaps.bottom_mm < 55.0) & (gaps.top_mm > 62.0)]
        assert inside.empty, inside


def test_the_corrections_keep_the_blind_stretches(clamped):
    cfg, frames, _ = clamped
    res = gp.analyze(frames, fps=cfg.fps, mm_per_px=cfg.mm_per_px)
    again = gp.apply_corrections(res, gp.Corrections())
    assert again.blind == res.blind and again.plug_length_mm == pytest.approx(res.plug_length_mm)


def test_blind_stretches_round_trip(clamped, tmp_path):
    cfg, frames, _ = clamped
    res = gp.analyze(frames, fps=cfg.fps, mm_per_px=cfg.mm_per_px, mask_mm=[(55.0, 62.0)])
    res.save(tmp_path / "o", figures=False, report=False)
    back = gp.load_result(tmp_path / "o")
    assert back.blind == res.blind
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["blind_stretches"] == [
        {"from_mm": 55.0, "to_mm": 62.0, "found_by": "mask_mm", "treated": "blind", "contrast_left": None,
         "kept": True}]


@pytest.mark.parametrize(("mask", "words"), [
    ([(500.0, 600.0)], "outside the view"),
    ([(0.0, 1000.0)], "cover the whole view"),
    ([(20.0, 10.0)], "0 <= from_mm < to_mm"),
])
def test_a_mask_outside_the_view_or_covering_it_is_refused(clamped, mask, words):
    cfg, frames, _ = clamped
    with pytest.raises(gp.ParameterError, match=words):
        gp.analyze(frames, fps=cfg.fps, mm_per_px=cfg.mm_per_px, mask_mm=mask)


def test_the_command_line_takes_masks(clamped, tmp_path, capsys):
    import tifffile

    cfg, frames, _ = clamped
    movie = tmp_path / "m.tif"
    tifffile.imwrite(movie, frames, metadata={"fps": cfg.fps})
    capsys.readouterr()
    code = main(["analyze", str(movie), "--out", str(tmp_path / "o"), "--mm-per-px", str(cfg.mm_per_px),
                 "--mask", "55:62", "--mask", "0:2", "--no-figures", "--json"])
    out = capsys.readouterr()
    assert code == 0, out.err
    assert [(b["from_mm"], b["to_mm"]) for b in json.loads(out.out)["blind_stretches"]] == [(0.0, 2.0),
                                                                                          (55.0, 62.0)]
    code = main(["analyze", str(movie), "--out", str(tmp_path / "o2"), "--mask", "55-62"])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("error: --mask") and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "o2").exists()


def test_a_blind_stretch_added_as_a_correction_is_measured_as_one_given(clamped):
    """The review page's "blind" edit: a stretch added to an analysis that did not know it measures as the same
    stretch given to the analysis (no edge inside it, the plugs and bubbles of the clean movie)."""
    cfg, frames, clean = clamped
    given = gp.analyze(frames, fps=cfg.fps, mm_per_px=cfg.mm_per_px, mask_mm=[(55.0, 62.0)])
    found = gp.analyze(frames, fps=cfg.fps, mm_per_px=cfg.mm_per_px)
    # whatever the analysis found by itself is removed, then the clamp marked by hand
    corr = gp.Corrections()
    for b in found.blind:
        corr = corr.add("unblind", from_mm=b.from_mm, to_mm=b.to_mm)
    marked = gp.apply_corrections(found, corr.add("blind", from_mm=55.0, to_mm=62.0))
    assert [(b.from_mm, b.to_mm, b.found_by) for b in marked.blind if b.kept] == [(55.0, 62.0, "review")]
    for col in ("top_mm", "bottom_mm"):
        v = marked.edges[col].dropna()
        assert not ((v > 54.9) & (v < 62.1)).any()
    assert marked.plug_length_mm == pytest.approx(clean.plug_length_mm, rel=0.05)
    assert marked.bubble_length_mm == pytest.approx(clean.bubble_length_mm, rel=0.05)
    assert marked.plug_length_mm == pytest.approx(given.plug_length_mm, rel=0.02)


def test_removing_a_blind_stretch_measures_through_it_and_undoing_restores_it(clamped, tmp_path):
    cfg, frames, _ = clamped
    res = gp.analyze(frames, fps=cfg.fps, mm_per_px=cfg.mm_per_px, mask_mm=[(55.0, 62.0)])
    removed = gp.apply_corrections(res, gp.Corrections().add("unblind", from_mm=58.0, to_mm=58.0))
    assert [(b.found_by, b.kept) for b in removed.blind] == [("mask_mm", False)]
    # the clamp's edges are measured again (it is taken for part of the plugs)
    v = removed.edges[["top_mm", "bottom_mm"]].stack()
    assert ((v > 54.9) & (v < 62.1)).any()
    removed.save(tmp_path / "o", figures=False, report=False)
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["blind_stretches"] == [
        {"from_mm": 55.0, "to_mm": 62.0, "found_by": "mask_mm", "treated": "blind", "contrast_left": None,
         "kept": False}]
    # replayed from the saved folder: the same; with the edit undone: as analysed
    assert gp.load_result(tmp_path / "o").blind == removed.blind
    back = gp.apply_corrections(removed, gp.Corrections())
    assert back.blind == res.blind and back.plug_length_mm == pytest.approx(res.plug_length_mm, rel=1e-12)


@pytest.mark.parametrize(("edit", "why"), [((500.0, 600.0), "outside the view"), ((-5.0, 1000.0), "whole view")])
def test_a_blind_edit_outside_the_view_or_over_all_of_it_is_not_applied(clamped, edit, why):
    cfg, frames, _ = clamped
    res = gp.analyze(frames, fps=cfg.fps, mm_per_px=cfg.mm_per_px)
    out = gp.apply_corrections(res, gp.Corrections().add("blind", from_mm=edit[0], to_mm=edit[1]))
    [said] = of_code(out, "corrections.not_applied")
    assert why in said
    assert out.blind == res.blind and out.plug_length_mm == pytest.approx(res.plug_length_mm, rel=1e-12)


def test_a_blind_edit_with_its_ends_reversed_or_not_numbers_is_refused():
    with pytest.raises(gp.ParameterError, match="from_mm"):
        gp.Corrections().add("blind", from_mm=20.0, to_mm=10.0)
    with pytest.raises(gp.ParameterError, match="to_mm must be a finite position"):
        gp.Corrections().add("blind", from_mm=1.0, to_mm="12 mm")
    with pytest.raises(gp.ParameterError, match="needs to_mm"):
        gp.Corrections().add("unblind", from_mm=1.0)
    # and through corrections.json
    text = gp.Corrections().add("blind", from_mm=1.5, to_mm=3.0).as_dict()
    assert gp.Corrections.from_dict(json.loads(json.dumps(text))).edits[0].to_mm == 3.0
