"""Every warning of an analysis has a stable code (grainplug.warning_codes): in the result, in summary.json (the
parallel ``warning_codes``), through result.npz and back; a result saved before codes reads as uncoded, and a
reviewer's corrections still replace their own old warnings on it."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest
from camera_writers import write_cine
from warned import codes

import grainplug as gp
from grainplug.corrections import NOT_APPLIED, UNCHECKED, Corrections, apply_corrections
from grainplug.synthetic import SynthConfig
from grainplug.synthetic.render import Renderer
from grainplug.warning_codes import CODES, CodedWarning, code_of, codes_of

#: the codes the analyses below give between them (each analysis is built to give some)
EXPECTED = {
    "movie.truncated", "movie.fps_disagrees", "movie.frames_out_of_step", "window.end_past_movie",
    "tube.cut_by_frame", "tube.second_region", "scale.model_alone", "scale.tube_wide", "scale.tube_narrow",
    "scale.edges_only", "scale.contents_back_lit", "scale.given_vs_tube", "light.saturated", "light.background",
    "frames.repaired", "flow.sign_assumed", "plugs.implausible_speed", "still.region", "shake.along_unmeasured",
    "corrections.not_applied", "corrections.unchecked",
}


@pytest.fixture(scope="module")
def frames() -> np.ndarray:
    cfg = SynthConfig(n_frames=120, width_px=64, height_px=300, fps=500.0, seed=3, rgb=False, bit_depth=8)
    return np.stack(list(Renderer(cfg).frames()))


@pytest.fixture(scope="module")
def results(frames, tmp_path_factory) -> dict[str, gp.AnalysisResult]:
    """Analyses that warn of many things: a wrong frame rate, a strip cut close to the tube, a region through the
    tube, a second tube, an over-exposed movie with dark frames, a wrong scale and a window past its end, a
    truncated camera file with a frame out of step given another rate, a dark background, a clamp over the tube,
    and corrections that do not fit."""
    out: dict[str, gp.AnalysisResult] = {}
    out["fast"] = gp.analyze(frames, fps=500_000.0)
    out["strip"] = gp.analyze(np.ascontiguousarray(frames[:, :, 24:42]), fps=500.0)
    out["cut"] = gp.analyze(frames, fps=500.0, roi=(0, 0, 36, frames.shape[1]))  # the bore spans x = 24-40
    cfg = SynthConfig(n_frames=120, width_px=64, height_px=300, fps=500.0, seed=4, rgb=False, bit_depth=8)
    out["two"] = gp.analyze(np.concatenate([frames, np.stack(list(Renderer(cfg).frames()))], axis=2), fps=500.0)
    bright = np.clip(frames.astype(np.int32) * 3, 0, 255).astype(np.uint8)
    bright[20:25] = 0  # the lamp failed for five frames
    out["bright"] = gp.analyze(bright, fps=500.0, mm_per_px=0.06, end_frame=400)
    stamps = 1.6e9 + np.arange(len(frames)) / 500.0
    stamps[50] += 0.0007  # frame 50's time stamp is out of step
    path = write_cine(tmp_path_factory.mktemp("cine") / "m.cine", frames.astype(np.uint16) << 4, fps=500.0,
                      real_bpp=12, stamps_s=stamps)
    path.write_bytes(path.read_bytes()[:-1000])  # the last frame loses its end
    out["cine"] = gp.analyze(path, fps=250.0, allow_truncated=True)
    dark = gp.Background(np.zeros(frames.shape[1:], np.float32)
                         + np.linspace(0, 1, frames.shape[1], dtype=np.float32)[:, None] ** 8, {}, 1)
    out["background"] = gp.analyze(frames, fps=500.0, mm_per_px=0.185, background=dark)
    cfg = SynthConfig(n_frames=200, seed=5, celerity_m_s=0.05, plug_length_mm=10, bubble_length_mm=8,
                      plug_length_sd_mm=1, bubble_length_sd_mm=1)
    clamped = np.stack(list(Renderer(cfg).frames()))
    clamped[:, 300:330] = np.clip(30 + np.random.default_rng(1).normal(0, 3, clamped[:, 300:330].shape), 0, 255)
    out["clamp"] = gp.analyze(clamped, fps=cfg.fps, mm_per_px=cfg.mm_per_px)
    from scipy import ndimage

    t = np.arange(len(frames)) / 500.0  # the camera shaking across the tube, 1.2 px at 30 Hz
    shaken = np.stack([ndimage.shift(f.astype(np.float32), (0.0, 1.2 * np.sin(2 * np.pi * 30 * tk)), order=3,
                                     mode="nearest") for f, tk in zip(frames, t, strict=True)])
    out["shaken"] = gp.analyze(np.clip(shaken, 0, 255).astype(np.uint8), fps=500.0, mm_per_px=0.185)
    old = Corrections.from_dict({"format": "grainplug-corrections", "format_version": 1,  # no traces
                                 "edits": [{"action": "exclude", "track": 0, "at": ""},
                                           {"action": "exclude", "track": 999, "at": ""}]})
    out["corrected"] = apply_corrections(out["cine"], old, reanalysed=True)  # with the movie's own warnings
    return out


def test_every_warning_of_an_analysis_has_a_known_code(results):
    seen: set[str] = set()
    for name, res in results.items():
        for w in [*res.warnings, *res.info.warnings]:
            assert isinstance(w, CodedWarning) and w.code in CODES and w.code != "legacy.uncoded", (name, w)
        seen |= codes(res)
    assert EXPECTED <= seen, sorted(EXPECTED - seen)  # the analyses above are the many kinds they mean to be


def test_summary_json_and_result_npz_keep_each_warnings_code(results, tmp_path):
    for name, res in results.items():
        out = tmp_path / name
        res.save(out, figures=False, report=False)
        summary = json.loads((out / "summary.json").read_text())
        assert summary["warnings"] == [str(w) for w in res.warnings]
        assert summary["warning_codes"] == codes_of(res.warnings), name  # parallel, one code a warning
        assert all(c in CODES and c != "legacy.uncoded" for c in summary["warning_codes"]), summary["warning_codes"]
        back = gp.load_result(out)
        for mine, theirs in ((res.warnings, back.warnings), (res.info.warnings, back.info.warnings)):
            assert [(str(w), code_of(w)) for w in theirs] == [(str(w), code_of(w)) for w in mine], name
        assert back.summary["warning_codes"] == summary["warning_codes"]


def _as_saved_before_codes(folder) -> None:
    """Rewrite ``folder``'s result.npz as grainplug wrote it before codes: each warning its text, format 2."""
    npz = folder / "result.npz"
    with np.load(npz, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    meta = json.loads(str(arrays.pop("__tree__")))
    assert meta["format_version"] == 4

    def plain(obj):
        if isinstance(obj, dict):
            if set(obj) == {"__warning__"}:
                return obj["__warning__"][1]
            return {k: plain(v) for k, v in obj.items()}
        if isinstance(obj, list):
            return [plain(v) for v in obj]
        return obj

    text = json.dumps(meta)
    meta = plain(meta)
    meta["format_version"] = 2
    assert "__warning__" in text and "__warning__" not in json.dumps(meta)
    with open(npz, "wb") as fh:
        np.savez(fh, __tree__=np.array(json.dumps(meta)), **arrays)
    assert zipfile.is_zipfile(npz)


def test_a_result_saved_before_codes_reads_uncoded_and_its_corrections_warnings_are_still_replaced(results, tmp_path):
    corrected = results["corrected"]
    ours = [w for w in corrected.warnings if w.code in ("corrections.not_applied", "corrections.unchecked")]
    assert sorted(w.code for w in ours) == ["corrections.not_applied", "corrections.unchecked"], corrected.warnings
    others = [str(w) for w in corrected.warnings if w not in ours]
    assert others  # the analysis' own warnings, which the corrections must leave alone
    corrected.save(tmp_path / "old", figures=False, report=False)
    _as_saved_before_codes(tmp_path / "old")

    old = gp.load_result(tmp_path / "old")
    assert old.warnings == [str(w) for w in corrected.warnings]  # the same sentences ...
    assert set(codes_of([*old.warnings, *old.info.warnings])) == {"legacy.uncoded"}  # ... without their codes
    assert old.info.warnings and not any(isinstance(w, CodedWarning) for w in old.warnings)
    assert old.summary["warning_codes"] == ["legacy.uncoded"] * len(old.warnings)

    # replayed: the old sentences of the corrections are replaced by coded ones, the analysis' own are kept
    again = apply_corrections(old, old.corrections)
    assert not [w for w in again.warnings if code_of(w) == "legacy.uncoded" and w.startswith((NOT_APPLIED, UNCHECKED))]
    assert sorted(code_of(w) for w in again.warnings if code_of(w) != "legacy.uncoded") == [
        "corrections.not_applied", "corrections.unchecked"]  # the unchecked edit still flagged, by the old sentence
    assert [w for w in again.warnings if code_of(w) == "legacy.uncoded"] == others
    assert [str(w) for w in again.warnings if code_of(w) != "legacy.uncoded"] == [str(w) for w in ours]
    # the reviewer removed the edits: their old warnings go, the analysis' stay
    cleared = apply_corrections(old, Corrections())
    assert cleared.warnings == others and set(codes_of(cleared.warnings)) == {"legacy.uncoded"}
