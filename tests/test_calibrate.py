"""`grainplug calibrate` and the scale from a calibration in the analysis.

The accuracy of the scale on rendered calibration images (other optics, perspective,
blur, noise, occlusion) is checked in test_calibration_accuracy.py; here: the command,
its files and errors, and how a calibration is used and reported by the analysis.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
import tifffile
from warned import coded_pairs, codes, of_code

import grainplug as gp
from grainplug.calibration.pattern import Calibration, CalibrationError, index_lattice
from grainplug.cli import main
from grainplug.synthetic import SynthConfig
from grainplug.synthetic.render import Renderer


def board(shape=(480, 640), square_px=32.0, n=(10, 7), angle_deg=4.0) -> np.ndarray:
    """A plain checkerboard image, square to the camera (supersampled)."""
    ss = 4
    ys, xs = np.mgrid[0:shape[0] * ss, 0:shape[1] * ss] / ss
    a = math.radians(angle_deg)
    x, y = xs - shape[1] / 2, ys - shape[0] / 2
    u = (math.cos(a) * x - math.sin(a) * y) / square_px
    v = (math.sin(a) * x + math.cos(a) * y) / square_px
    inside = (np.abs(u) < n[0] / 2) & (np.abs(v) < n[1] / 2)
    img = np.where(inside & ((np.floor(u) + np.floor(v)) % 2 == 0), 30.0, 225.0)
    return img.reshape(shape[0], ss, shape[1], ss).mean(axis=(1, 3)).astype(np.uint8)


def uniform_calibration(mm_per_px: float, shape=(300, 48)) -> Calibration:
    return Calibration(mm_per_px=mm_per_px, mm_per_px_x=mm_per_px, mm_per_px_y=mm_per_px,
                       jacobian_mm_per_px=((mm_per_px, 0.0), (0.0, mm_per_px)), rel_sd=0.001, tilt_deg=0.0,
                       scale_variation=0.0, rms_residual_px=0.05, n_points=60, pattern="checkerboard", pitch_mm=2.0,
                       image_shape=shape, centre_px=(shape[1] / 2, shape[0] / 2),
                       homography=((1 / mm_per_px, 0, 0), (0, 1 / mm_per_px, 0), (0, 0, 1)),
                       image={"name": "cal.tif"})


def test_calibrate_writes_the_scale_and_a_figure(tmp_path, capsys):
    tifffile.imwrite(tmp_path / "board.tif", board())
    out = tmp_path / "cal" / "calibration.json"
    assert main(["calibrate", str(tmp_path / "board.tif"), "--pitch-mm", "2", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    data = json.loads(out.read_text())
    assert data["format"] == "grainplug-calibration" and data["version"] == 1 and data["pattern"] == "checkerboard"
    assert data["mm_per_px"] == pytest.approx(2.0 / 32.0, rel=2e-3)
    assert data["tilt_deg"] == pytest.approx(4.0, abs=0.1)  # turned counter-clockwise on the screen
    assert data["image"]["sha256"] and data["image"]["name"] == "board.tif" and data["grainplug_version"]
    assert out.with_name(f"{out.stem}_points.png").stat().st_size > 10_000
    shown = re.search(r"^scale +([0-9.]+) mm/px ± ([0-9.]+) %", printed, re.M)
    assert shown and float(shown[1]) == pytest.approx(2.0 / 32.0, rel=2e-3) and float(shown[2]) < 0.5
    cal = gp.load_calibration(out)
    assert cal.mm_per_px == data["mm_per_px"] and len(cal.points_px) == cal.n_points == 9 * 7


def _tube_frame() -> np.ndarray:
    from grainplug.synthetic import SynthConfig
    from grainplug.synthetic.render import Renderer

    return next(iter(Renderer(SynthConfig(n_frames=2, width_px=160, height_px=400, seed=1, rgb=False)).frames()))


@pytest.mark.parametrize(("image", "words"), [
    (np.full((100, 100), 128, np.uint8), "uniform"),
    (np.random.default_rng(0).integers(0, 255, (200, 200)).astype(np.uint8),
     "no checkerboard, dot grid, graph paper or ruler was found"),
    (_tube_frame(), "no checkerboard, dot grid, graph paper or ruler was found"),  # a frame of the movie itself
])
def test_calibrate_without_a_pattern_is_one_clear_line(tmp_path, capsys, image, words):
    tifffile.imwrite(tmp_path / "x.tif", image)
    assert main(["calibrate", str(tmp_path / "x.tif"), "--pitch-mm", "2", "--out", str(tmp_path / "c.json")]) != 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and words in err
    assert not (tmp_path / "c.json").exists()


def test_bad_calibration_files_are_one_clear_line(tmp_path, capsys):
    (tmp_path / "bad.json").write_text("{not json")
    (tmp_path / "other.json").write_text('{"format": "something"}')
    movie = tmp_path / "m.tif"
    tifffile.imwrite(movie, np.zeros((4, 8, 8), np.uint8), photometric="minisblack")
    for name, words in (("missing.json", "no such calibration file"), ("bad.json", "is not a calibration JSON"),
                        ("other.json", "is not a grainplug calibration")):
        code = main(["analyze", str(movie), "--out", str(tmp_path / "o"), "--calibration", str(tmp_path / name)])
        err = capsys.readouterr().err
        assert code != 0 and err.count("\n") == 1 and words in err, err
    with pytest.raises(CalibrationError, match="pitch must be a positive length"):
        gp.calibrate_image(board(), pitch_mm=0.0)


@pytest.fixture(scope="module")
def plug_movie():
    """Frames of plug flow, and the scale at which the tube's width reads 3 mm."""
    cfg = SynthConfig(n_frames=120, width_px=48, height_px=300, fps=500.0, seed=3)
    frames = np.stack(list(Renderer(cfg).frames()))
    tube_scale = gp.analyze(frames, fps=500.0).mm_per_px
    return frames, tube_scale


def test_analysis_takes_its_scale_from_the_calibration(tmp_path, plug_movie):
    frames, tube_scale = plug_movie
    cal = uniform_calibration(tube_scale * 1.01)  # agrees with the tube within 3 %: no warning
    res = gp.analyze(frames, fps=500.0, calibration=cal)
    assert res.mm_per_px == pytest.approx(tube_scale * 1.01, rel=1e-12)
    assert res.scale_source.startswith("calibration image cal.tif (checkerboard, 60 points 2 mm apart")
    assert res.summary["scale_rel_sd"] == pytest.approx(0.001)
    assert not res.warnings
    # the same scale typed by hand gives the same celerity
    typed = gp.analyze(frames, fps=500.0, mm_per_px=tube_scale * 1.01)
    assert res.summary["celerity_m_s"] == pytest.approx(typed.summary["celerity_m_s"], rel=1e-9)
    res.save(tmp_path / "out", figures=False, report=False)
    assert gp.load_result(tmp_path / "out").params.calibration == cal
    # the calibration file's path, as the command line takes it, as a keyword or in a dict of parameters
    gp.save_calibration(cal, tmp_path / "cal.json")
    for by_path in (gp.analyze(frames, fps=500.0, calibration=str(tmp_path / "cal.json")),
                    gp.analyze(frames, {"fps": 500.0, "calibration": tmp_path / "cal.json"})):
        assert by_path.mm_per_px == res.mm_per_px


def test_doubtful_calibrations_are_said(plug_movie):
    frames, tube_scale = plug_movie
    wrong = uniform_calibration(tube_scale * 1.2, shape=(1024, 1280))  # another image size, 20 % off the tube
    res = gp.analyze(frames, fps=500.0, calibration=wrong)
    [size] = of_code(res, "scale.calibration_size")
    assert "1280 x 1024 px" in size and "48 x 300" in size, res.warnings
    # more than the tube's optics allow: doubted first, and the intervals carry the disagreement (1/1.2 in scale)
    assert next(c for _, c in coded_pairs(res)) == "scale.calibration_doubted", res.warnings
    assert res.summary["scale_rel_sd"] >= abs(math.log(1 / 1.2)) / 2
    assert res.mm_per_px == pytest.approx(tube_scale * 1.2, rel=1e-3)  # the calibration is still what is used
    # within what back-lit optics allow (the tube reads 4 % narrower than the calibration makes it): said, mildly,
    # and the calibration's own uncertainty kept
    finer = gp.analyze(frames, fps=500.0, calibration=uniform_calibration(tube_scale / 1.04))
    assert codes(finer) == {"scale.calibration_vs_tube"}, finer.warnings
    assert finer.summary["scale_rel_sd"] == pytest.approx(0.001)
    # graph paper read at its 5 mm lines as if they were 1 mm apart: a factor 5, named, with the pitch to check
    coarse = gp.analyze(frames, fps=500.0, calibration=uniform_calibration(tube_scale / 5))
    [said] = of_code(coarse, "scale.calibration_doubted")
    assert "factor 5.00" in said and "pitch" in said
    assert coarse.summary["scale_rel_sd"] > 0.5
    with pytest.raises(gp.ParameterError, match="either a calibration or mm_per_px"):
        gp.AnalysisParams(mm_per_px=0.1, calibration=wrong)


def test_anisotropic_calibration_is_taken_along_the_tube():
    cal = uniform_calibration(0.1)
    cal = Calibration(**{**cal.__dict__, "jacobian_mm_per_px": ((0.1, 0.0), (0.0, 0.12))})
    assert cal.mm_per_px_along((0.0, 1.0)) == pytest.approx(0.12)
    assert cal.mm_per_px_along((1.0, 0.0)) == pytest.approx(0.1)
    assert cal.mm_per_px_along((1.0, 1.0)) == pytest.approx(math.hypot(0.1, 0.12) / math.sqrt(2))


def test_lattice_indexing_follows_perspective_and_gaps():
    # a 9 x 7 grid seen in strong perspective, with a hole in it
    i, j = np.mgrid[0:9, 0:7]
    X, Y = i.ravel() * 1.0, j.ravel() * 1.0
    w = 1.0 + 0.04 * Y
    pts = np.stack([(30 * X + 5 * Y) / w, (30 * Y - 4 * X) / w], axis=1)
    hole = (np.abs(X - 4) <= 1) & (np.abs(Y - 3) <= 1)
    index, found = index_lattice(pts[~hole])
    assert len(index) == (~hole).sum()
    # indices are those of the grid, up to the lattice's symmetries: check neighbours stay neighbours
    lookup = {tuple(p): tuple(k) for p, k in zip(np.round(found, 6), index, strict=True)}
    for a, b in ((0, 1), (10, 11), (50, 57)):
        if hole[a] or hole[b]:
            continue
        ka, kb = np.array(lookup[tuple(np.round(pts[a], 6))]), np.array(lookup[tuple(np.round(pts[b], 6))])
        assert np.abs(ka - kb).sum() == 1


def rendered_board(shape=(800, 1024), px_per_mm=10.0, pitch_mm=5.0, n=(12, 9), roll_deg=0.0, ink=25.0,
                   paper=235.0, noise=0.0, ss=4, seed=0) -> np.ndarray:
    """A board of n squares centred in the frame (larger than it if n is large), supersampled, with noise."""
    h, w = shape
    ys, xs = np.mgrid[0:h * ss, 0:w * ss].astype(np.float64)
    xs, ys = (xs + 0.5) / ss - 0.5 - w / 2, (ys + 0.5) / ss - 0.5 - h / 2
    a = math.radians(roll_deg)
    u = (math.cos(a) * xs + math.sin(a) * ys) / (px_per_mm * pitch_mm) + n[0] / 2
    v = (-math.sin(a) * xs + math.cos(a) * ys) / (px_per_mm * pitch_mm) + n[1] / 2
    inside = (u >= 0) & (u < n[0]) & (v >= 0) & (v < n[1])
    img = np.where(inside & ((np.floor(u) + np.floor(v)) % 2 == 0), ink, paper)
    img = img.reshape(h, ss, w, ss).mean(axis=(1, 3))
    img += np.random.default_rng(seed).normal(0.0, noise, img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def _synth_movie(tmp_path, **kw) -> str:
    from grainplug.synthetic import synthesize

    return str(synthesize(SynthConfig(fps=500.0, seed=2, **kw), tmp_path / "m", fmt="tiff").movie)


@pytest.mark.parametrize(("what", "pitch"), [("noise", 1.0), ("empty tube", 1.0), ("plug flow", 3.0)])
def test_calibrate_refuses_images_without_a_pattern(tmp_path, capsys, what, pitch):
    """Noise (grey 200, sd 3) was read as a ruler of 556 ticks; a movie of the empty tube as graph paper with
    0 crossings, varying by 190 %; a plug-flow movie crashed in the line reader."""
    if what == "noise":
        image = np.clip(np.random.default_rng(1).normal(200.0, 3.0, (800, 1024)), 0, 255).astype(np.uint8)
        tifffile.imwrite(tmp_path / "x.tif", image)
        path = str(tmp_path / "x.tif")
    elif what == "empty tube":
        path = _synth_movie(tmp_path, regime="none", n_frames=30)
    else:
        path = _synth_movie(tmp_path, n_frames=20)
    out = tmp_path / "c.json"
    assert main(["calibrate", path, "--pitch-mm", str(pitch), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: no checkerboard, dot grid, graph paper or ruler was found")
    assert "unexpected" not in err and not out.exists() and not out.with_name(f"{out.stem}_points.png").exists()


@pytest.mark.parametrize("sample", ["pyidi/data_showcase.cih", "pyMRAW/beam.cihx"])
def test_calibrate_refuses_camera_movies_of_other_things(sample):
    """Real camera files (a structure, a speckled beam) were read as rulers of 48 and 221 ticks."""
    path = Path("/work/shared/camera-samples") / sample
    if not path.exists():
        pytest.skip("the camera samples are not on this machine")
    from grainplug.calibration_files import calibrate_file

    with pytest.raises(CalibrationError, match="no checkerboard, dot grid, graph paper or ruler was found"):
        calibrate_file(path, pitch_mm=1.0)


@pytest.mark.parametrize("noise", [9.0, 12.0])
def test_low_contrast_noisy_checkerboard_is_a_checkerboard(noise):
    """Grey 110 on 140 with noise 9-12 was read as graph paper along the squares' diagonals: 29 % off."""
    image = rendered_board(roll_deg=-12.0, ink=110.0, paper=140.0, noise=noise, ss=3)
    cal = gp.calibrate_image(image, pitch_mm=5.0)
    # 88 inner corners; a few T-junctions where the lines meet the board's edge lie on the lattice too
    assert cal.pattern == "checkerboard" and 80 <= cal.n_points <= 96
    assert cal.mm_per_px == pytest.approx(0.1, rel=0.003)
    assert cal.mm_per_px_x == pytest.approx(0.1, rel=0.003) and cal.mm_per_px_y == pytest.approx(0.1, rel=0.003)


def test_lines_are_believed_only_on_evidence():
    """The line reader asked for directly refuses noise with the reason, and still reads a real ruler's ticks."""
    noise = np.clip(np.random.default_rng(5).normal(200.0, 3.0, (400, 500)), 0, 255).astype(np.uint8)
    with pytest.raises(CalibrationError, match=r"no ruler's ticks was found in the image \(the strongest repeat.*"
                                               r"stands only \d+ times above the image's noise"):
        gp.calibrate_image(noise, pitch_mm=1.0, pattern="ruler")
    from calibration_optics import GRATING_CASES, render

    image, _ = render(rng=np.random.default_rng(11), **GRATING_CASES["ruler"])
    assert gp.calibrate_image(image, pitch_mm=1.0, pattern="ruler").pattern == "ruler"


def test_board_larger_than_the_frame_gives_no_false_warning():
    """Corners within ~8 px of the frame's edge were pulled 3.5-5 px by the refinement's zero padding and kept:
    "fit residual 0.80 px", "the scale varies by 0.7 %", "0.80 px from the fitted plane"."""
    image = rendered_board(n=(30, 24), roll_deg=3.0, noise=3.0, ss=8)
    cal = gp.calibrate_image(image, pitch_mm=5.0)
    assert cal.pattern == "checkerboard" and cal.n_points > 250
    assert not cal.warnings, cal.warnings
    assert cal.rms_residual_px < 0.1 and cal.scale_variation < 0.002
    assert cal.mm_per_px == pytest.approx(0.1, rel=2e-4)
    h, w = image.shape
    pts = np.asarray(cal.points_px)
    assert np.min([pts[:, 0], pts[:, 1], w - 1 - pts[:, 0], h - 1 - pts[:, 1]]) > 8


def test_a_false_corner_off_the_lattice_is_dropped():
    """A point within the indexing's tolerance (30 % of the pitch) but off its neighbours' lattice is dropped."""
    i, j = np.mgrid[0:9, 0:7]
    pts = np.stack([40.0 * i.ravel() + 3.0 * j.ravel(), 40.0 * j.ravel() - 3.0 * i.ravel()], axis=1) + 100.0
    pts = pts + np.random.default_rng(0).normal(0.0, 0.1, pts.shape)
    pts[30] += (6.0, -4.0)  # 7 px: 18 % of the pitch
    _, found = index_lattice(pts)
    assert len(found) == len(pts) - 1
    assert not np.any(np.all(np.isclose(found, pts[30]), axis=1))


def test_a_16_bit_tiff_written_by_opencv_is_read(tmp_path, capsys, monkeypatch):
    """OpenCV writes TIFFs LZW-compressed, which tifffile decodes only with the optional imagecodecs package:
    such a calibration image was refused ("requires the 'imagecodecs' package"); OpenCV reads it instead."""
    import cv2

    image = board().astype(np.uint16) * 257
    assert cv2.imwrite(str(tmp_path / "board16.tif"), image)
    out = tmp_path / "c.json"
    assert main(["calibrate", str(tmp_path / "board16.tif"), "--pitch-mm", "2", "--out", str(out)]) == 0
    assert json.loads(out.read_text())["mm_per_px"] == pytest.approx(2.0 / 32.0, rel=2e-3)
    capsys.readouterr()
    (tmp_path / "broken.tif").write_bytes((tmp_path / "board16.tif").read_bytes()[:2000])
    assert main(["calibrate", str(tmp_path / "broken.tif"), "--pitch-mm", "2", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ")
    # when OpenCV cannot either, the message gives the install fix
    import grainplug.calibration_files as files

    monkeypatch.setattr(files, "_opencv_picture", lambda path: None)
    assert main(["calibrate", str(tmp_path / "board16.tif"), "--pitch-mm", "2", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "install imagecodecs (pip install imagecodecs)" in err


def test_pixels_far_from_square_are_taken_when_the_pattern_is_named():
    """Pixels 10 % from square were refused even with the pattern named; auto mode still refuses them (it must
    tell a misread lattice from a real one) and says how to accept them."""
    image = board(shape=(400, 480), square_px=30.0, n=(12, 9), angle_deg=0.0)
    stretched = cv2_resize(image, 1.1)  # 10 % more pixels per mm along y
    with pytest.raises(CalibrationError, match=r"10 % from square \(x:y scales 1\.100\) — if the camera's pixels "
                                               r"are that shape, name the pattern \(pattern=\"checkerboard\"\)"):
        gp.calibrate_image(stretched, pitch_mm=3.0)
    cal = gp.calibrate_image(stretched, pitch_mm=3.0, pattern="checkerboard")
    assert cal.mm_per_px_x == pytest.approx(0.1, rel=2e-3) and cal.mm_per_px_y == pytest.approx(0.1 / 1.1, rel=2e-3)
    assert any("pixels are not square" in w for w in cal.warnings)


def cv2_resize(image: np.ndarray, y_factor: float) -> np.ndarray:
    import cv2

    h, w = image.shape
    return cv2.resize(image, (w, int(round(h * y_factor))), interpolation=cv2.INTER_AREA)


def test_the_calibration_file_is_recorded_in_the_analysis(tmp_path, plug_movie):
    """summary.json embedded the calibration's content and its image's name, but not which calibration file it
    came from; the path is now there, without entering the file itself or a campaign's run key."""
    from grainplug.campaigns.batch import run_key
    from grainplug.campaigns.manifest import RunSpec

    frames, tube_scale = plug_movie
    for where in ("a", "b"):
        (tmp_path / where).mkdir()
        gp.save_calibration(uniform_calibration(tube_scale), tmp_path / where / "cal.json")
    assert "source" not in json.loads((tmp_path / "a" / "cal.json").read_text())
    cal = gp.load_calibration(tmp_path / "a" / "cal.json")
    assert cal.source == str((tmp_path / "a" / "cal.json").resolve())
    res = gp.analyze(frames, fps=500.0, calibration=cal)
    res.save(tmp_path / "out", figures=False, report=False)
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["parameters"]["calibration"]["source"] == cal.source
    assert gp.load_result(tmp_path / "out").params.calibration.source == cal.source
    # the same calibration elsewhere (a campaign copied to another drive) is the same run
    ident = {"bytes": 1, "files": 1, "sha256_sampled": "x"}
    keys = {run_key(RunSpec("r", tmp_path / "m.tif", gp.AnalysisParams(
        calibration=gp.load_calibration(tmp_path / where / "cal.json"))), identity=ident) for where in ("a", "b")}
    assert len(keys) == 1
