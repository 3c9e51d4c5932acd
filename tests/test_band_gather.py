"""The band readers' fast gather agrees with :meth:`Band.profile`, and the band
the analysis asks for lies in the core of the tube.

:class:`BandGather` reads a band's samples through flat offsets computed from a
frame's strides; it must give the plain profile for frames in any memory layout a
reader may hand out (views of memory maps, bottom-up rows, BGR, padded planes,
broadcast or byte-swapped arrays).
"""

from __future__ import annotations

import numpy as np
import pytest

from grainplug.band import Band
from grainplug.calibration.tube import TubeGeometry
from grainplug.diagram.extract import CORE_FRACTION, band_along_tube
from grainplug.readers.band import BandGather, profiles_from_blocks, profiles_from_frames

H, W = 37, 29


def random_band(rng: np.random.Generator, shape: tuple[int, int] = (H, W)) -> Band:
    """Random pixels anywhere in the frame, random positive weights summing to 1 per position."""
    n_pos, n_across = int(rng.integers(1, 40)), int(rng.integers(1, 8))
    rows = rng.integers(0, shape[0], (n_pos, n_across))
    cols = rng.integers(0, shape[1], (n_pos, n_across))
    w = rng.uniform(0.05, 1.0, (n_pos, n_across)).astype(np.float32)
    return Band(rows, cols, w / w.sum(axis=1, keepdims=True), shape)


def random_frame(rng: np.random.Generator, shape: tuple[int, ...], dtype: str) -> np.ndarray:
    if np.dtype(dtype).kind == "f":
        return rng.uniform(0, 1000, shape).astype(dtype)
    return rng.integers(0, np.iinfo(dtype).max, shape, endpoint=True).astype(dtype)


def layouts(rng: np.random.Generator, dtype: str, channels: int) -> dict[str, np.ndarray]:
    """The same kind of frame (H x W [x channels]) in many memory layouts."""
    c = () if channels == 1 else (channels,)
    base = random_frame(rng, (H, W, *c), dtype)
    big = random_frame(rng, (3 * H + 5, 2 * W + 7, *c), dtype)
    t = random_frame(rng, (W, H, *c), dtype)
    out = {
        "contiguous": base,
        "rows reversed": base[::-1],
        "columns reversed": base[:, ::-1],
        "rows and columns reversed": base[::-1, ::-1],
        "transposed": np.swapaxes(t, 0, 1),
        "transposed, reversed": np.swapaxes(t, 0, 1)[::-1],
        "crop": big[4: 4 + H, 3: 3 + W],
        "strided crop": big[1: 1 + 3 * H: 3, 2: 2 + 2 * W: 2],
        "strided crop, reversed": big[3 * H - 1:: -3][:H, ::-2][:, :W],
        "broadcast rows": np.broadcast_to(big[:1, :W], base.shape),
        "broadcast columns": np.broadcast_to(big[:H, :1], base.shape),
        "big-endian": base.astype(base.dtype.newbyteorder(">")),
        "big-endian, reversed": base.astype(base.dtype.newbyteorder(">"))[::-1],
    }
    if channels > 1:
        out["channels reversed"] = base[..., ::-1]
        out["everything reversed"] = base[::-1, ::-1, ::-1]
        out["channel planes"] = np.moveaxis(random_frame(rng, (channels, H, W), dtype), 0, 2)
        out["broadcast channels"] = np.broadcast_to(big[:H, :W, :1], base.shape)
    return out


CASES = [(dtype, ch) for dtype in ("uint8", "uint16", "float32") for ch in (1, 3, 4)]


@pytest.mark.parametrize(("dtype", "channels"), CASES)
def test_gather_equals_the_plain_profile_in_every_layout(dtype, channels):
    rng = np.random.default_rng(CASES.index((dtype, channels)))
    frames = layouts(rng, dtype, channels)
    for name, frame in frames.items():
        assert frame.shape[:2] == (H, W), name
        for _ in range(3):
            band = random_band(rng)
            want = band.profile(frame)
            got = BandGather(band)(frame)
            assert got.dtype == np.float32 and got.shape == (band.n_positions,)
            np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6, err_msg=name)
    # one gather through frames of changing layouts: its offsets follow each layout
    band = random_band(rng)
    gather = BandGather(band)
    for name, frame in [*frames.items(), *reversed(frames.items())]:
        np.testing.assert_allclose(gather(frame), band.profile(frame), rtol=1e-5, atol=1e-6, err_msg=name)


def test_alpha_is_ignored(rng):
    rgb = rng.integers(0, 256, (H, W, 3), dtype=np.uint8)
    band = random_band(rng)
    profiles = []
    for alpha in (0, 255):
        rgba = np.concatenate([rgb, np.full((H, W, 1), alpha, np.uint8)], axis=2)
        profiles.append(BandGather(band)(rgba))
    np.testing.assert_array_equal(profiles[0], profiles[1])
    np.testing.assert_allclose(profiles[0], band.profile(rgb), rtol=1e-5)
    # and the reference is the mean over the colour channels
    manual = (rgb[band.rows, band.cols].astype(float).mean(axis=2) * band.weights).sum(axis=1)
    np.testing.assert_allclose(profiles[0], manual, rtol=1e-5)


@pytest.mark.parametrize("rgb", [False, True])
def test_threaded_blocks_equal_frames_in_order_equal_the_plain_profiles(rgb):
    rng = np.random.default_rng(7 + rgb)
    n = 23
    stack = rng.integers(0, 2**16, (n, H, W, 3) if rgb else (n, H, W), dtype=np.uint16)
    stored = stack[:, ::-1]  # as a reader may hand them out: rows bottom-up
    band = random_band(rng)
    want = np.stack([band.profile(f) for f in stored])
    seen: list[int] = []
    in_order = profiles_from_frames(iter(stored), band, n_frames=n, progress=seen.append)
    np.testing.assert_allclose(in_order, want, rtol=1e-5)
    assert seen[-1] == n
    asked: list[tuple[int, int]] = []

    def read_block(start: int, count: int) -> np.ndarray:
        asked.append((start, count))
        return stored[start: start + count]

    for threads in (1, 3):
        asked.clear()
        done: list[int] = []
        blocks = profiles_from_blocks(read_block, band, n_frames=n, threads=threads, block_frames=5,
                                      progress=done.append)
        np.testing.assert_array_equal(blocks, in_order)
        assert sorted(asked) == [(s, min(5, n - s)) for s in range(0, n, 5)]
        assert done == sorted(done) and done[-1] == n
    # a stream that ends early gives the frames it had
    short = profiles_from_frames(iter(stored[:9]), band, n_frames=n)
    np.testing.assert_array_equal(short, in_order[:9])


TUBES = [
    TubeGeometry("vertical", 0.0, 31.7, 14.0, 1.0, "test", (200, 64)),
    TubeGeometry("vertical", 3.5, 20.2, 11.3, 1.0, "test", (180, 64)),
    TubeGeometry("vertical", -4.8, 50.9, 17.6, 1.0, "test", (240, 80)),
    TubeGeometry("horizontal", 0.0, 40.0, 20.0, 1.0, "test", (300, 96)),
    TubeGeometry("horizontal", 2.7, 33.3, 9.5, 1.0, "test", (150, 72)),
    TubeGeometry("horizontal", -5.0, 61.1, 12.4, 1.0, "test", (220, 90)),
]


@pytest.mark.parametrize("tube", TUBES, ids=lambda t: f"{t.orientation}{t.tilt_deg:+g}")
def test_band_along_tube_lies_in_the_core(tube):
    band, axis_px = band_along_tube(tube)
    h, w = tube.canonical_shape
    assert band.frame_shape == ((h, w) if tube.orientation == "vertical" else (w, h))
    # canonical coordinates: y along the tube, x across
    y, x = (band.rows, band.cols) if tube.orientation == "vertical" else (band.cols, band.rows)
    t = np.radians(tube.tilt_deg)
    # distance of each pixel from the axis, the line through (axis_x0, -0.5) along (sin t, cos t)
    dist = np.abs((x - tube.axis_x0_px) * np.cos(t) - (y + 0.5) * np.sin(t))
    assert (band.weights > 0).all()  # these tubes lie inside their frames: every pixel counts
    assert dist.max() <= 0.5 * CORE_FRACTION * tube.inner_diameter_px + 1
    assert band.rows.shape[1] >= 0.6 * CORE_FRACTION * tube.inner_diameter_px
    np.testing.assert_allclose(band.weights.sum(axis=1), 1.0, rtol=1e-6)
    assert band.n_positions == len(axis_px) >= 0.9 * h
    assert (np.diff(axis_px) > 0).all()
    # from the top (left) of the view down the axis
    along = ((x - tube.axis_x0_px) * np.sin(t) + (y + 0.5) * np.cos(t)).mean(axis=1)
    assert (np.diff(along) > 0).all()
    # axis_px is the distance along the axis: what the samples span, to within the rounding
    # of their columns
    assert abs((axis_px[-1] - axis_px[0]) - abs(along[-1] - along[0])) <= 1.0
