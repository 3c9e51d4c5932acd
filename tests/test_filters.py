"""grainplug's OpenCV filters give the numbers of their scipy.ndimage namesakes (random inputs)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage, special

from grainplug import _filters as f


@pytest.mark.parametrize("mode", ["reflect", "nearest", "constant"])
@pytest.mark.parametrize("sigma", [0.5, 0.7, 1.0, 2.0, 10.0, 40.0])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_gaussian_filter1d(rng, mode, sigma, dtype):
    for shape, axis in (((57,), -1), ((23, 91), 1), ((91, 23), 0), ((5, 300), -1)):
        a = rng.normal(size=shape).astype(dtype)
        if mode == "reflect" or shape[axis] * 2 > 8 * sigma + 1:
            got = f.gaussian_filter1d(a, sigma, axis=axis, mode=mode)
            want = ndimage.gaussian_filter1d(a, sigma, axis=axis, mode=mode)
            assert got.dtype == want.dtype and got.shape == want.shape
            np.testing.assert_allclose(got, want, rtol=0, atol=2e-6 if dtype == np.float32 else 1e-12)


@pytest.mark.parametrize("sigma", [1.0, (0.7, 0.7), (2.0, 0.5)])
@pytest.mark.parametrize("mode", ["reflect", "nearest"])
def test_gaussian_filter(rng, sigma, mode):
    a = rng.normal(size=(64, 80)).astype(np.float32)
    np.testing.assert_allclose(f.gaussian_filter(a, sigma, mode=mode), ndimage.gaussian_filter(a, sigma, mode=mode),
                               rtol=0, atol=2e-6)


@pytest.mark.parametrize("size", [1, 2, 3, 6, 7, 16])
@pytest.mark.parametrize("origin", [0, -1])
def test_running_max_and_min(rng, size, origin):
    if size == 1 and origin == -1:
        return
    m = (rng.random((12, 60)) < 0.4).astype(np.uint8)
    pairs = ((f.maximum_filter1d, ndimage.maximum_filter1d), (f.minimum_filter1d, ndimage.minimum_filter1d))
    for ours, theirs in pairs:
        got = ours(m, size, axis=1, origin=origin)
        want = theirs(m, size, axis=1, mode="constant", cval=0, origin=origin)
        np.testing.assert_array_equal(got, want)
    b = m.astype(bool)
    np.testing.assert_array_equal(f.minimum_filter1d(b, size, axis=1, origin=origin),
                                  ndimage.minimum_filter1d(b, size, axis=1, mode="constant", cval=0, origin=origin))


@pytest.mark.parametrize("size", [3, 7, 15, 16])
def test_uniform_filter1d(rng, size):
    a = rng.normal(size=(9, 70)).astype(np.float32)
    np.testing.assert_allclose(f.uniform_filter1d(a, size, axis=1), ndimage.uniform_filter1d(a, size, axis=1),
                               rtol=0, atol=2e-6)


def test_t_quantile_matches_scipy():
    for df in [1, 2, 3, 4, 5, 6, 7, 9, 12, 20, 31, 50, 100, 400, 3000, 1e6]:
        assert f.t_quantile_975(df) == pytest.approx(float(special.stdtrit(df, 0.975)), rel=1e-9)


def test_otsu_threshold_matches_scikit_image(rng):
    from skimage.filters import threshold_otsu

    for k in range(20):
        v = np.concatenate([rng.normal(0, 1, 500 + 37 * k), rng.normal(3 + k / 5, 0.5 + k / 20, 300)])
        v = v.astype(np.float32 if k % 2 else np.float64)
        assert f.threshold_otsu(v, nbins=512) == float(threshold_otsu(v, nbins=512))
