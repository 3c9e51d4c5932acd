"""The tube search's fast paths agree with plain computations.

``sheared_profile`` (pixels splatted onto the grid, then convolved with the hat of
linear interpolation) against scipy's interpolation along every line; the integer
grey binning of 8-bit frames against float conversion then block means.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from grainplug.calibration.tube import bin_pixels, grey_binned, sheared_profile, to_grey


def _profile_by_map_coordinates(img, tan_b, x_grid, rows=None):
    """The definition: linear interpolation along every line, with scipy."""
    h, w = img.shape
    ys = np.arange(h, dtype=float)[rows if rows is not None else slice(None)]
    yy = np.repeat(ys[:, None], len(x_grid), axis=1)
    xx = x_grid[None, :] + (ys[:, None] + 0.5) * tan_b
    vals = ndimage.map_coordinates(img.astype(float), [yy, xx], order=1, mode="constant", cval=np.nan)
    vals[(xx < 0) | (xx > w - 1)] = np.nan
    count = np.isfinite(vals).sum(axis=0)
    out = np.full(len(x_grid), np.nan)
    ok = count >= max(1, 0.3 * len(ys))
    out[ok] = np.nansum(vals, axis=0)[ok] / count[ok]
    return out, xx


# steps that divide 1 px take the splatting path; 0.3 px takes the per-line gather
@pytest.mark.parametrize("step", [1.0, 0.5, 0.25, 0.1, 0.05, 0.3])
@pytest.mark.parametrize("tan_b", [0.0, 0.037, -0.105])
def test_sheared_profile_equals_interpolation(step, tan_b):
    rng = np.random.default_rng(11)
    img = rng.random((90, 70)).astype(np.float32)
    grid = np.arange(-8.3, 78.0, step)
    ref, xx = _profile_by_map_coordinates(img, tan_b, grid)
    got = sheared_profile(img, tan_b, grid)
    # away from the image's sides (where the splatted weights are partial by design)
    far = (np.abs(xx) > 1.01).all(axis=0) & (np.abs(xx - 69) > 1.01).all(axis=0)
    both = far & np.isfinite(ref)
    assert both.sum() > 20
    np.testing.assert_allclose(got[both], ref[both], rtol=0, atol=2e-6)
    assert np.array_equal(np.isnan(got[far]), np.isnan(ref[far]))
    block = slice(30, 50)  # a block of rows only
    ref_b, _ = _profile_by_map_coordinates(img, tan_b, grid, block)
    got_b = sheared_profile(img, tan_b, grid, block)
    ok = far & np.isfinite(ref_b)
    assert ok.sum() > 20
    np.testing.assert_allclose(got_b[ok], ref_b[ok], rtol=0, atol=2e-6)


@pytest.mark.parametrize("b", [1, 2, 4, 8])
@pytest.mark.parametrize("shape", [(64, 48, 3), (66, 50), (37, 41, 3)])
def test_grey_binning_is_exact(b, shape):
    rng = np.random.default_rng(b * 100 + len(shape))
    frame = rng.integers(0, 256, shape, dtype=np.uint8)
    got = grey_binned(frame, b)
    ref = bin_pixels(to_grey(frame), b)
    assert got.shape == (shape[0] // b, shape[1] // b)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-4)
    # and the plain definition: block means of the channel mean, in float64
    h, w = got.shape[0] * b, got.shape[1] * b
    g = frame.astype(np.float64).mean(axis=2) if frame.ndim == 3 else frame.astype(np.float64)
    blocks = g[:h, :w].reshape(h // b, b, w // b, b).mean(axis=(1, 3))
    np.testing.assert_allclose(got, blocks, rtol=0, atol=1e-4)
