"""The few image filters of the analysis, on OpenCV.

They give the numbers of their :mod:`scipy.ndimage` namesakes (same kernels, truncation
and borders; ``tests/test_filters.py`` holds them to it on random inputs) at a tenth of
the start-up cost: ``import cv2`` takes 0.03 s where ``scipy.ndimage`` and
``scipy.special`` take 0.2 s together, paid by every run.

Border modes use scipy's names: ``"reflect"`` (``dcba|abcd``, OpenCV's
``BORDER_REFLECT``), ``"nearest"`` (``BORDER_REPLICATE``), ``"constant"`` (zeros).
"""

from __future__ import annotations

import math

import numpy as np

_BORDERS = {"reflect": 2, "nearest": 1, "constant": 0}  # cv2.BORDER_REFLECT, _REPLICATE, _CONSTANT


def true_runs(flag: np.ndarray, min_len: int = 1) -> list[tuple[int, int]]:
    """Runs ``[a, b)`` of True in the 1-D ``flag``, at least ``min_len`` long."""
    step = np.diff(np.concatenate([[0], np.asarray(flag, bool).astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(step == 1), np.flatnonzero(step == -1)
    return [(int(a), int(b)) for a, b in zip(starts, stops, strict=True) if b - a >= min_len]


def _gauss_kernel(sigma: float, truncate: float = 4.0) -> np.ndarray:
    radius = int(truncate * float(sigma) + 0.5)
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    k = np.exp(-0.5 * (x / float(sigma)) ** 2)
    return k / k.sum()


def _as_2d(a: np.ndarray, axis: int) -> tuple[np.ndarray, bool, tuple[int, ...]]:
    """``a`` as a contiguous 2-D array whose axis 1 is ``axis``."""
    shape = a.shape
    if a.ndim == 1:
        return np.ascontiguousarray(a.reshape(1, -1)), False, shape
    if a.ndim != 2:
        raise ValueError("only 1-D and 2-D arrays")
    if axis in (0, -2):
        return np.ascontiguousarray(a.T), True, shape
    return np.ascontiguousarray(a), False, shape


def _back(out: np.ndarray, transposed: bool, shape: tuple[int, ...]) -> np.ndarray:
    if transposed:
        out = out.T
    return np.ascontiguousarray(out).reshape(shape)


def _float(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a)
    return a if a.dtype in (np.float32, np.float64) else a.astype(np.float64)


def gaussian_filter1d(a: np.ndarray, sigma: float, *, axis: int = -1, mode: str = "reflect") -> np.ndarray:
    """``scipy.ndimage.gaussian_filter1d(a, sigma, axis=axis, mode=mode)`` (truncate 4)."""
    a = _float(a)
    if sigma <= 0:
        return a.copy()
    if a.ndim == 2 and axis in (0, -2):
        return _separable(a, (_gauss_kernel(sigma), None), mode)
    return _separable(a.reshape(1, -1) if a.ndim == 1 else a, (None, _gauss_kernel(sigma)), mode).reshape(a.shape)


def gaussian_filter(a: np.ndarray, sigma: float | tuple[float, float], *, mode: str = "reflect") -> np.ndarray:
    """``scipy.ndimage.gaussian_filter(a, sigma, mode=mode)`` of a 2-D array (truncate 4)."""
    sy, sx = (sigma, sigma) if np.isscalar(sigma) else sigma
    a = _float(a)
    return _separable(a, (_gauss_kernel(float(sy)) if sy > 0 else None, _gauss_kernel(float(sx)) if sx > 0 else None),
                      mode)


def _separable(a: np.ndarray, kernels: tuple[np.ndarray | None, np.ndarray | None], mode: str) -> np.ndarray:
    """``a`` (2-D, float) filtered by ``kernels`` = (along axis 0, along axis 1) in one OpenCV pass.

    float32 data are summed in float32 (scipy sums in double: 1e-7 apart), which keeps the
    diagram's temporaries at their size. Where a kernel is longer than twice the data, OpenCV
    would pad only once: those axes are done with numpy instead.
    """
    import cv2

    ky, kx = kernels
    out = np.ascontiguousarray(a)
    for axis, k in ((0, ky), (1, kx)):
        if k is not None and mode == "reflect" and len(k) > 2 * out.shape[axis]:
            from numpy.lib.stride_tricks import sliding_window_view

            r = len(k) // 2
            pad = [(0, 0), (0, 0)]
            pad[axis] = (r, r)
            padded = np.pad(out, pad, mode="symmetric")
            out = np.ascontiguousarray((sliding_window_view(padded, len(k), axis=axis) * k).sum(axis=-1),
                                       dtype=a.dtype)
            if axis == 0:
                ky = None
            else:
                kx = None
    if ky is None and kx is None:
        return out
    one = np.ones(1, out.dtype)
    return cv2.sepFilter2D(out, -1, (kx if kx is not None else one).astype(out.dtype),
                           (ky if ky is not None else one).astype(out.dtype), borderType=_BORDERS[mode])


def _running(a: np.ndarray, size: int, *, axis: int, origin: int, op: str) -> np.ndarray:
    import cv2

    m, transposed, shape = _as_2d(np.asarray(a), axis)
    dtype = m.dtype
    if dtype == np.bool_:
        m = m.view(np.uint8)
    # scipy's window for sample i: i - size // 2 - origin ... + size - 1; OpenCV's anchor is where
    # the sample sits in the kernel
    anchor = size // 2 + origin
    kernel = np.ones((1, size), np.uint8)
    f = cv2.dilate if op == "max" else cv2.erode
    out = f(m, kernel, anchor=(anchor, 0), borderType=cv2.BORDER_CONSTANT, borderValue=0)
    if dtype == np.bool_:
        out = out.view(np.bool_)
    return _back(out, transposed, shape)


def maximum_filter1d(a: np.ndarray, size: int, *, axis: int = -1, origin: int = 0) -> np.ndarray:
    """``scipy.ndimage.maximum_filter1d(a, size, axis, mode="constant", cval=0, origin=origin)`` for
    integer or boolean 2-D arrays."""
    return _running(a, size, axis=axis, origin=origin, op="max")


def minimum_filter1d(a: np.ndarray, size: int, *, axis: int = -1, origin: int = 0) -> np.ndarray:
    """``scipy.ndimage.minimum_filter1d(a, size, axis, mode="constant", cval=0, origin=origin)`` for
    integer or boolean 2-D arrays."""
    return _running(a, size, axis=axis, origin=origin, op="min")


def uniform_filter1d(a: np.ndarray, size: int, *, axis: int = -1, mode: str = "reflect") -> np.ndarray:
    """``scipy.ndimage.uniform_filter1d(a, size, axis=axis, mode=mode)`` of a float 2-D array."""
    import cv2

    m, transposed, shape = _as_2d(_float(a), axis)
    k = np.full(size, 1.0 / size, m.dtype)
    # scipy centres an even window at size // 2 (the later sample): OpenCV's anchor the same
    out = cv2.sepFilter2D(m, -1, k, np.ones(1, m.dtype), anchor=(size // 2, 0), borderType=_BORDERS[mode])
    return _back(out, transposed, shape)


def t_quantile_975(df: float) -> float:
    """The 97.5 % quantile of Student's t with ``df`` degrees of freedom (``scipy.special.stdtrit(df, 0.975)``).

    Notes
    -----
    Exact for 1 and 2 degrees of freedom. Otherwise Hill's approximation (algorithm
    396, Comm. ACM 13, 617, 1970; within 1e-3) refined by Newton's method on the
    t distribution's integral ``int_0^t f(u) du = 0.475``, the density
    ``f(u) = Gamma((n+1)/2) / (sqrt(n pi) Gamma(n/2)) (1 + u^2/n)^(-(n+1)/2)``
    integrated by Simpson's rule on 2000 intervals (above 100 000 degrees of freedom Hill's
    alone is within 1e-11): within 1e-9 of scipy (tested).
    """
    t = _hill(df)
    n = float(df)
    if n <= 2 or n > 1e5:  # exact, or Hill's within 1e-11 (the gamma functions' ratio would lose digits)
        return t
    log_c = math.lgamma((n + 1) / 2) - math.lgamma(n / 2) - 0.5 * math.log(n * math.pi)

    def density(u: np.ndarray | float) -> np.ndarray:
        return np.exp(log_c - (n + 1) / 2 * np.log1p(np.asarray(u, dtype=np.float64) ** 2 / n))

    for _ in range(4):
        u = np.linspace(0.0, t, 2001)
        w = np.ones(2001)
        w[1:-1:2], w[2:-1:2] = 4.0, 2.0
        integral = float((w * density(u)).sum() * t / 6000.0)
        t -= (integral - 0.475) / float(density(t))
    return t


def _hill(df: float) -> float:
    """Hill's approximation of the 97.5 % t quantile (exact for 1 and 2 degrees of freedom)."""
    n = float(df)
    p = 0.05
    if n < 1:
        raise ValueError(f"need at least one degree of freedom, got {df}")
    if n == 1:
        return math.cos(p * math.pi / 2) / math.sin(p * math.pi / 2)
    if n == 2:
        return math.sqrt(2.0 / (p * (2.0 - p)) - 2.0)
    a = 1.0 / (n - 0.5)
    b = 48.0 / (a * a)
    c = ((20700.0 * a / b - 98.0) * a - 16.0) * a + 96.36
    d = ((94.5 / (b + c) - 3.0) / b + 1.0) * math.sqrt(a * math.pi / 2) * n
    x = d * p
    y = x ** (2.0 / n)
    if y > 0.05 + a:
        x = 1.959963984540054  # the normal's 97.5 % quantile
        y = x * x
        if n < 5:
            c += 0.3 * (n - 4.5) * (x + 0.6)
        c = (((0.05 * d * x - 5.0) * x - 7.0) * x - 2.0) * x + b + c
        y = (((((0.4 * y + 6.3) * y + 36.0) * y + 94.5) / c - y - 3.0) / b + 1.0) * x
        y = a * y * y
        y = math.expm1(y) if y > 0.002 else 0.5 * y * y + y
    else:
        y = ((1.0 / (((n + 6.0) / (n * y) - 0.089 * d - 0.822) * (n + 2.0) * 3.0) + 0.5 / (n + 4.0)) * y
             - 1.0) * (n + 1.0) / (n + 2.0) + 1.0 / y
    return math.sqrt(n * y)


def threshold_otsu(values: np.ndarray, *, nbins: int = 512) -> float:
    """``skimage.filters.threshold_otsu(values, nbins=nbins)`` for float values: the histogram bin
    centre that maximises the between-class variance (Otsu, 1979)."""
    v = np.asarray(values).ravel()
    lo, hi = v.min(), v.max()  # in the values' own type, as scikit-image does
    if lo == hi:
        return float(lo)
    counts, edges = np.histogram(v, bins=nbins, range=(lo, hi))
    centres = (edges[:-1] + edges[1:]) / 2
    counts = counts.astype(np.float32)
    w1 = np.cumsum(counts)
    w2 = np.cumsum(counts[::-1])[::-1]
    m1 = np.cumsum(counts * centres) / w1
    m2 = (np.cumsum((counts * centres)[::-1]) / w2[::-1])[::-1]
    between = w1[:-1] * w2[1:] * (m1[:-1] - m2[1:]) ** 2
    return float(centres[int(np.argmax(between))])
