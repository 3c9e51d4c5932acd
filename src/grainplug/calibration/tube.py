"""Find the tube in the frame: orientation, tilt, axis position and inner diameter.

The tube is located from the data alone, on a sample of frames spread over the
movie. Two images are formed after removing each frame's global light level
(flicker): the temporal mean ``M`` and the temporal standard deviation ``S``.
Inside the bore the contents change (plugs, bubbles, falling grains), so ``S``
is high there and low on the static background and glass; the walls are long
straight edges in ``M``.

Notes
-----
*Axis direction.* For each candidate tilt the feature image is projected along
the candidate direction (a shear, then a histogram across the tube); the tilt
whose projection has the largest energy (sum of squares) is the axis direction,
as in projection-profile skew detection. Vertical and horizontal tubes are both
tried; the more concentrated projection wins.

*Axis position.* The bore is located in blocks of rows along the tube; a
weighted straight-line fit of the blocks' centres (outliers dropped) gives the
axis position and refines the tilt.

*Inner diameter.* The bore is measured on the relative variation
``sqrt(S^2 - S_bg^2) / M`` (``S_bg^2``, the background's variance, is the sensor
noise). In transmitted light (a back-lit tube: the background is brighter than
the bore) a local loss of light, such as the dark band that refraction draws
along the inner wall, scales the mean and the variation alike and cancels;
optical blur, however, mixes the bore's edge with the brighter surround and
makes the relative variation read narrow, while the excess variation
``sqrt(S^2 - S_bg^2)`` is unbiased by blur but reads narrow where the wall
darkens the contents. Both can only err narrow, so the wider is kept. In
scattered light (dark field: the bore is brighter than the background) glare
from the walls adds light rather than removing it, so the excess variation
``sqrt(S^2 - S_bg^2)`` itself is measured. Across the tube the projected profile
is a plateau over the bore; each of its two edges is placed where the profile
crosses half of its local step (the step's top read 1-2.5 px inside the
steepest point, its base 1-2.5 px outside), by linear interpolation on a 0.05 px
grid. This is insensitive to any symmetric blur of the edges and to a plateau
that is not flat across the bore. The scale follows as ``mm_per_px = D / width``.

*Limits.* The apparent width of the bore is taken as its true width: thick
glass walls magnify the bore by refraction, and a bore seen in scattered light
was measured about 2% narrow on grainplug's own synthetic movies. When that
matters, give the scale from a calibration image (``--mm-per-px``).
"""

from __future__ import annotations

import dataclasses
import itertools
import logging
from dataclasses import dataclass

import numpy as np

from .._filters import gaussian_filter, gaussian_filter1d
from ..errors import MovieError, non_finite_frames
from .tube_model import WallMeasure, measure_walls

log = logging.getLogger(__name__)

MAX_TILT_DEG = 6.0


#: the narrowest bore measured without a wall seen beside it (an outer silhouette): below it a strip of background or
#: a line of texture is not told from a tube
MIN_BORE_PX = 6.0
#: when nothing moves, a mean image whose level varies across the frame by less than this share holds no wall ...
FLAT_SHARE = 0.05
#: ... asked only when nothing moves: the contents' change over the frames peaks at no more than this many times its
#: stillest (5th percentile)
MOVING_OVER_STILL = 4.0

@dataclass(frozen=True)
class TubeGeometry:
    """Where the tube is in the image.

    Positions refer to the canonical view: for a horizontal tube the frame is
    transposed first (``orientation == "horizontal"``), so that the axis runs
    along the image rows in both cases.

    Attributes
    ----------
    orientation : {"vertical", "horizontal"}
        Direction of the tube axis in the frame.
    tilt_deg : float
        Angle of the axis from the image column (canonical view): the axis
        passes through ``x = axis_x0_px + (y + 0.5) * tan(tilt)``.
    axis_x0_px : float
        Axis position at the top edge of the canonical view (``y = -0.5``).
    inner_diameter_px : float
        Apparent inner diameter of the tube, perpendicular to the axis.
    contrast : float
        Height of the bore's temporal-variation plateau over the background (a
        quality figure: near zero when nothing moves in the tube).
    method : str
        ``"variation"`` (from the moving contents) or ``"walls"`` (from the
        mean image, used when nothing moves).
    canonical_shape : tuple of int
        (height, width) of the canonical view.
    background_level : float
        Median grey level of the frames.
    back_lit : bool or None
        Whether the tube is seen against a lamp (the bore darker than its
        surround); None when it could not be told.
    walls : WallMeasure or None
        The outer silhouette and the bright stripes of the walls, measured on the
        mean image (see :mod:`grainplug.calibration.tube_model`).
    side_variation : float
        How much the contents change at the frame's two sides (the two outer columns of
        the canonical view), as a share of the most they change anywhere: near 1 when
        the moving contents run up to a side, a tube cut by the frame or the region of
        interest; near 0 when the tube is whole in view.
    """

    orientation: str
    tilt_deg: float
    axis_x0_px: float
    inner_diameter_px: float
    contrast: float
    method: str
    canonical_shape: tuple[int, int]
    background_level: float = float("nan")
    back_lit: bool | None = None
    walls: WallMeasure | None = None
    side_variation: float = 0.0

    def axis_x(self, y: np.ndarray | float) -> np.ndarray:
        """Axis position (canonical x) at canonical row ``y``."""
        return self.axis_x0_px + (np.asarray(y, dtype=float) + 0.5) * np.tan(np.radians(self.tilt_deg))

    def as_dict(self) -> dict[str, object]:
        return {
            "orientation": self.orientation, "tilt_deg": self.tilt_deg,
            "axis_x0_px": self.axis_x0_px, "inner_diameter_px": self.inner_diameter_px,
            "contrast": self.contrast, "method": self.method,
            "canonical_shape": list(self.canonical_shape), "background_level": self.background_level,
            "back_lit": self.back_lit, "walls": None if self.walls is None else self.walls.as_dict(),
            "side_variation": self.side_variation,
        }


def to_grey(frame: np.ndarray) -> np.ndarray:
    """Float32 grey image: the mean of the colour channels."""
    if frame.ndim == 3:
        g = frame[..., 0].astype(np.float32)
        for c in range(1, frame.shape[2]):
            g += frame[..., c]
        g *= np.float32(1.0 / frame.shape[2])
        return g
    return frame.astype(np.float32)


def bin_pixels(img: np.ndarray, b: int) -> np.ndarray:
    if b == 1:
        return img
    h, w = img.shape[0] // b * b, img.shape[1] // b * b
    out = np.zeros((h // b, w // b), np.float32)
    for i in range(b):
        for j in range(b):
            out += img[i:h:b, j:w:b]
    out *= np.float32(1.0 / (b * b))
    return out


def grey_binned(frame: np.ndarray, b: int) -> np.ndarray:
    """``bin_pixels(to_grey(frame), b)``; 8-bit frames are summed in 16-bit integers (exact, and
    about twice as fast as converting the whole frame to float first)."""
    n_ch = frame.shape[2] if frame.ndim == 3 else 1
    if b == 1 or frame.dtype != np.uint8 or n_ch * b * b * 255 >= 2**16:
        return bin_pixels(to_grey(frame), b)
    h, w = frame.shape[0] // b * b, frame.shape[1] // b * b
    if frame.ndim == 3:
        g = frame[:h, :w, 0].astype(np.uint16)
        for c in range(1, n_ch):
            g += frame[:h, :w, c]
    else:
        g = frame[:h, :w].astype(np.uint16)
    rows = g[0::b].copy()
    for i in range(1, b):
        rows += g[i::b]
    out = rows[:, 0::b].copy()
    for j in range(1, b):
        out += rows[:, j::b]
    return out.astype(np.float32) * np.float32(1.0 / (n_ch * b * b))


def mean_and_variation(frames: list[np.ndarray], *, binning: int = 1, transpose: bool = False,
                       cols: slice | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """Temporal mean and standard deviation of gain-normalised grey frames.

    Parameters
    ----------
    frames : list of ndarray
        Grey or colour frames.
    binning : int
        Average ``binning x binning`` blocks first (a coarse look at large frames).
    transpose : bool
        Work in the transposed frame (canonical view of a horizontal tube).
    cols : slice, optional
        Only these columns (of the possibly transposed frame).

    Returns
    -------
    mean, std : ndarray
        Images of the frames divided by their median (flicker removed).
    level : float
        Median grey level of the frames (the background's light).
    """
    acc = acc2 = None
    levels = []
    for f in frames:
        view = np.swapaxes(f, 0, 1) if transpose else f
        if cols is not None:
            view = view[:, cols]
        g = grey_binned(view, binning)
        level = float(np.median(g[::4, ::4]))
        levels.append(level)
        g = g * np.float32(1.0 / max(level, 1e-6))
        if acc is None:
            acc = np.zeros(g.shape, np.float64)
            acc2 = np.zeros(g.shape, np.float64)
        acc += g
        acc2 += g * g
    n = len(frames)
    mean = acc / n
    var = np.maximum(acc2 / n - mean * mean, 0.0)
    return mean.astype(np.float32), np.sqrt(var).astype(np.float32), float(np.median(levels))


def sheared_profile(img: np.ndarray, tan_b: float, x_grid: np.ndarray,
                    rows: slice | None = None) -> np.ndarray:
    """Mean of ``img`` along the lines ``x = x0 + (y + 0.5) tan_b``, for each ``x0`` in ``x_grid``.

    Linear interpolation across the lines; samples falling outside the image are
    ignored (NaN where a line crosses fewer than 30% of the rows).

    Notes
    -----
    The mean along a line is :math:`\\sum_{y,x} I_{yx}\\,\\Lambda(x_0 + s_y - x)` over the
    rows it crosses, with :math:`s_y = (y + 1/2)\\tan\\beta` and :math:`\\Lambda` the
    unit hat of linear interpolation. Every pixel is therefore dropped at its
    sheared position :math:`x - s_y` onto the grid (linear weights) and the result
    convolved with :math:`\\Lambda` sampled on the grid: exact when the grid step
    divides 1 px, and a cost in the number of pixels rather than rows x grid points.
    Within 1 px of the image's sides the weights are partial instead of absent.
    """
    h, w = img.shape
    ys = np.arange(h)[rows if rows is not None else slice(None)]
    n_g = len(x_grid)
    step = float(x_grid[1] - x_grid[0]) if n_g > 1 else 1.0
    k = int(round(1.0 / step))
    if n_g < 2 or abs(k * step - 1.0) > 1e-6 or not np.allclose(np.diff(x_grid), step, rtol=0, atol=1e-9):
        return _sheared_profile_gather(img, tan_b, x_grid, ys)
    block = np.asarray(img[ys], dtype=np.float64)
    shift = (ys + 0.5) * tan_b
    u = (np.arange(w)[None, :] - shift[:, None] - float(x_grid[0])) / step
    i = np.floor(u)
    f = (u - i).ravel()
    idx = i.astype(np.intp).ravel() + k
    vals = block.ravel()
    n_bins = n_g + 2 * k + 1
    sel = (idx >= 0) & (idx <= n_g - 1 + 2 * k) & np.isfinite(vals)
    idx, f, vals = idx[sel], f[sel], vals[sel]
    total = (np.bincount(idx, weights=vals * (1 - f), minlength=n_bins)
             + np.bincount(idx + 1, weights=vals * f, minlength=n_bins))
    count = (np.bincount(idx, weights=1 - f, minlength=n_bins)
             + np.bincount(idx + 1, weights=f, minlength=n_bins))
    hat = 1.0 - np.abs(np.arange(-k, k + 1)) / k
    total = np.convolve(total, hat, mode="same")[k: k + n_g]
    count = np.convolve(count, hat, mode="same")[k: k + n_g]
    out = np.full(n_g, np.nan)
    ok = count >= max(1, 0.3 * len(ys)) - 1e-9
    out[ok] = total[ok] / count[ok]
    return out


def _sheared_profile_gather(img: np.ndarray, tan_b: float, x_grid: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """``sheared_profile`` on any grid: every (row, grid point) interpolated."""
    w = img.shape[1]
    xx = x_grid[None, :] + (ys[:, None] + 0.5) * tan_b
    inside = (xx >= 0) & (xx <= w - 1)
    x0 = np.clip(np.floor(xx), 0, max(w - 2, 0)).astype(np.intp)
    f = xx - x0
    flat = np.ascontiguousarray(img, dtype=np.float64).reshape(-1)
    base = x0 + (ys.astype(np.intp) * w)[:, None]
    vals = flat[base] * (1 - f) + flat[np.minimum(base + 1, flat.size - 1)] * f
    inside &= np.isfinite(vals)
    count = inside.sum(axis=0)
    total = np.where(inside, vals, 0.0).sum(axis=0)
    out = np.full(len(x_grid), np.nan)
    ok = count >= max(1, 0.3 * len(ys))
    out[ok] = total[ok] / count[ok]
    return out


def _downsample(img: np.ndarray, limit: int = 120_000) -> np.ndarray:
    """Halve the image (2x2 means) until it holds at most ``limit`` pixels."""
    while img.shape[0] * img.shape[1] > limit and min(img.shape) >= 64:
        img = bin_pixels(img, 2)
    return img


def _coarse_tilt(feature: np.ndarray, *, centre: float = 0.0, span: float = MAX_TILT_DEG) -> tuple[float, float]:
    """Tilt (deg) whose projection of ``feature`` has the most energy, and that energy.

    Searched in ``centre +- span`` on successively finer grids.
    """
    small = _downsample(feature, 80_000)
    h, w = small.shape
    pad = h * np.tan(np.radians(MAX_TILT_DEG + 1))
    grid = np.arange(-pad, w + pad, 1.0)

    def energy(deg: float) -> float:
        prof = sheared_profile(small, np.tan(np.radians(deg)), grid)
        if not np.isfinite(prof).any():  # every line leaves the frame at this angle
            return 0.0
        prof = gaussian_filter1d(np.nan_to_num(prof, nan=float(np.nanmedian(prof))), 1.0)
        prof = prof - np.median(prof)
        return float(np.mean(prof * prof))

    best, e_best = centre, -1.0
    grids = ((1.0, span), (0.25, 1.0), (0.05, 0.25), (0.0125, 0.05)) if span > 1 else (
        (0.05, span), (0.0125, 0.05))
    for step, reach in grids:
        centre = best
        for d in np.arange(centre - reach, centre + reach + 1e-9, step):
            if abs(d) > MAX_TILT_DEG + 1e-9:
                continue
            e = energy(float(d))
            if e > e_best:
                best, e_best = float(d), e
    return best, e_best


def _half_height(prof: np.ndarray, centre: int, level: float) -> tuple[float, float] | None:
    """Positions (in samples) where ``prof`` falls below ``level`` left and right of ``centre``."""
    n = len(prof)
    i = centre
    while i > 0 and prof[i - 1] >= level:
        i -= 1
    if i == 0:
        return None
    left = (i - 1) + (level - prof[i - 1]) / (prof[i] - prof[i - 1])
    j = centre
    while j < n - 1 and prof[j + 1] >= level:
        j += 1
    if j == n - 1:
        return None
    right = j + (prof[j] - level) / (prof[j] - prof[j + 1])
    return float(left), float(right)


@dataclass(frozen=True)
class _Bore:
    left: float
    right: float
    contrast: float
    noise: float


def _local_edge(grid: np.ndarray, sm: np.ndarray, approx: int, inward: int) -> float | None:
    """Sub-sample position where ``sm`` crosses half of its local step near ``approx``.

    The step's top is read 1 to 2.5 px inside the steepest point and its base 1 to
    2.5 px outside, so that a plateau that is not flat across the bore (shading,
    vignetting) does not move the edge.
    """
    step = grid[1] - grid[0]
    n = len(sm)
    win = max(2, int(round(1.0 / step)))
    lo, hi = max(1, approx - win), min(n - 2, approx + win)
    if hi <= lo:
        return None
    grad = np.abs(np.gradient(sm[lo - 1: hi + 2]))[1:-1]
    k = lo + int(np.argmax(grad))
    near, far = int(round(1.0 / step)), int(round(2.5 / step))
    a_in, b_in = sorted((k + inward * near, k + inward * far))
    a_out, b_out = sorted((k - inward * near, k - inward * far))
    if min(a_in, a_out) < 0 or max(b_in, b_out) >= n:
        return None
    top = float(np.max(sm[a_in: b_in + 1]))
    base = float(np.min(sm[a_out: b_out + 1]))
    half = 0.5 * (top + base)
    # walk from the inside towards the outside until the profile drops below half
    i = k + inward * near
    while 0 < i < n - 1 and sm[i] >= half:
        i -= inward
    j = i + inward  # last sample at or above half
    if sm[j] == sm[i]:
        return float(grid[i])
    frac = (sm[j] - half) / (sm[j] - sm[i])
    return float(grid[j] + (grid[i] - grid[j]) * frac)


def _bore_in_profile(grid: np.ndarray, prof: np.ndarray) -> _Bore | None:
    """Edges of the variation plateau in a profile sampled on ``grid``."""
    ok = np.isfinite(prof)
    if ok.sum() < 10:
        return None
    prof = np.interp(grid, grid[ok], prof[ok])
    step = grid[1] - grid[0]
    sm = gaussian_filter1d(prof, 0.5 / step)
    # the background: the lower part of the profile (in a strip cropped close to the tube most of
    # the profile is the bore, so its median would be the plateau)
    low = sm[sm <= np.percentile(sm, 25)]
    base = float(np.median(low))
    noise = float(np.median(np.abs(low - base))) * 1.4826 + 1e-12
    centre = int(np.argmax(sm))
    peak = float(sm[centre])
    plateau = sm[sm >= base + 0.75 * (peak - base)]
    top = float(np.median(plateau))
    cross = _half_height(sm, centre, base + 0.5 * (top - base))
    if cross is None:
        return None
    left = _local_edge(grid, sm, int(round(cross[0])), +1)
    right = _local_edge(grid, sm, int(round(cross[1])), -1)
    if left is None or right is None:
        left, right = grid[0] + cross[0] * step, grid[0] + cross[1] * step
    return _Bore(float(left), float(right), top - base, noise)


#: a frame this many times longer than wide holds a tube along its length (a strip cropped to the tube)
STRIP_ASPECT = 2.5


def _too_short(shape: tuple[int, ...], orient: str) -> bool:
    """Whether a tube in this orientation would cross the short side of a strip-shaped frame: a plug
    flow is filmed along the tube, so a strip holds the tube lengthwise."""
    h, w = shape[:2]
    return (orient == "horizontal" and h >= STRIP_ASPECT * w) or (orient == "vertical" and w >= STRIP_ASPECT * h)


#: the sharpest edges of the mean image (this top share of its gradients) tell how far the camera shook
SHAKE_EDGE_SHARE = 0.01
#: ... by the low quantile of their variance over their squared gradient (%): edges that only shake, not contents
SHAKE_QUANTILE = 20.0


def _shaken_variance(mean: np.ndarray, var: np.ndarray) -> np.ndarray:
    """The variance over the frames that the camera's shake alone puts at each pixel: a still edge of the mean
    image moved by ``s`` px varies by about ``s |grad|``, so its variance is ``s^2 |grad|^2``. ``s^2`` is the low
    quantile (:data:`SHAKE_QUANTILE`) of ``var / |grad|^2`` over the sharpest edges (:data:`SHAKE_EDGE_SHARE`):
    among them the walls' and the lamp's, which vary by the shake only (the contents' edges vary more). Without
    shake it is about 0; with it, the sharp outer edges of the walls no longer outshine the bore's contents."""
    gy, gx = np.gradient(np.asarray(mean, np.float32))
    g2 = gx * gx
    g2 += gy * gy
    step = max(1, int(np.sqrt(g2.size / 65536)))  # the quantiles from a grid of about 65 000 pixels
    cut = float(np.quantile(g2[::step, ::step], 1.0 - SHAKE_EDGE_SHARE))
    edges = g2 >= cut
    if not cut > 0 or edges.sum() < 16:
        return np.zeros_like(var)
    noise = float(np.median(var[::step, ::step]))
    s2 = float(np.percentile(np.clip(var[edges] - noise, 0, None) / g2[edges], SHAKE_QUANTILE))
    return s2 * g2.astype(var.dtype)


def _locate(mean: np.ndarray, std: np.ndarray, orientation: str | None, *, coarse: bool = False,
            tilt_hint: float | None = None, unshake: bool = False) -> TubeGeometry:
    """The tube in temporal mean and standard-deviation images (one resolution).

    ``coarse``: orientation, tilt, axis and an approximate width only (no block
    refinement, a 0.25 px profile grid), for the first look at a binned frame.
    ``unshake``: the variance the camera's shake puts on still edges taken out first
    (:func:`_shaken_variance`).
    """
    # relative variation of the contents: sensor noise removed (the background's
    # variance), divided by the local mean so that any local loss of light (the
    # dark bands of refraction at the walls, vignetting) cancels out
    var = std.astype(np.float64) ** 2
    if unshake:
        var = var - _shaken_variance(mean, var)
    excess = np.sqrt(np.clip(var - np.median(var), 0, None))
    floor = max(1e-3 * float(np.max(mean)), 1e-6)
    relative = (excess / np.maximum(mean, floor)).astype(np.float32)
    excess = excess.astype(np.float32)
    var = relative
    candidates = []
    for orient in ("vertical", "horizontal"):
        if orientation and orient != orientation:
            continue
        if not orientation and _too_short(mean.shape, orient):
            continue
        m = mean if orient == "vertical" else np.ascontiguousarray(mean.T)
        v = var if orient == "vertical" else np.ascontiguousarray(var.T)
        g = np.abs(np.gradient(gaussian_filter(m, 1.0), axis=1))
        vz = np.clip(v - np.median(v), 0, None)
        gz = np.clip(g - np.median(g), 0, None)
        feat = vz / (np.percentile(vz, 99.9) + 1e-12) + 0.25 * gz / (np.percentile(gz, 99.9) + 1e-12)
        if tilt_hint is None:
            tilt, energy = _coarse_tilt(feat)
        else:
            tilt, energy = _coarse_tilt(feat, centre=tilt_hint, span=0.3)
        candidates.append((energy, orient, tilt, m, v, feat))
    _, orient, tilt, m, v, feat = max(candidates, key=lambda c: c[0])
    h, w = m.shape
    # how much the contents change at the two sides, against the most they change (a tube cut by the frame)
    across = np.clip(v, 0, None).mean(axis=0)
    top = float(across.max())
    sides = (float(across[:2].max()), float(across[-2:].max()))
    structured = top > 3.0 * float(np.median(across))  # not noise alike everywhere (nothing moves)
    tan_b = np.tan(np.radians(tilt))
    # coarse axis position: the peak of the projected feature
    pad = h * abs(tan_b) + 2
    grid1 = np.arange(-pad, w + pad, 0.5)
    pf = sheared_profile(feat, tan_b, grid1)
    pf = gaussian_filter1d(np.nan_to_num(pf, nan=float(np.nanmin(pf))), 2.0)
    # the middle of the peak's span above half its height over the median: in a wide bore the walls' edges
    # (the mean image's gradient) can top the contents' flat plateau, and the peak alone would be a wall
    k = int(np.argmax(pf))
    level = 0.5 * (float(pf[k]) + float(np.median(pf)))
    above = pf >= level
    lo = k - int(np.argmin(above[k::-1])) + 1 if not above[: k + 1].all() else 0
    hi = k + int(np.argmin(above[k:])) - 1 if not above[k:].all() else len(pf) - 1
    x0 = float(0.5 * (grid1[lo] + grid1[hi]))
    # refine the axis from the bore's centre in blocks of rows
    half = max(0.25 * w, 40.0)
    fine = np.arange(x0 - half, x0 + half, 0.1)
    n_blocks = int(np.clip(h // 40, 4, 32))
    edges = np.linspace(0, h, n_blocks + 1).astype(int)
    ys, cs, ws = [], [], []
    for a, b in itertools.pairwise(edges if not coarse else []):
        bore = _bore_in_profile(fine, sheared_profile(v, tan_b, fine, slice(a, b)))
        if bore is not None and bore.contrast > 6 * bore.noise:
            ys.append(0.5 * (a + b) - 0.5)
            cs.append(0.5 * (bore.left + bore.right) + (0.5 * (a + b)) * tan_b)
            ws.append(bore.contrast)
    method = "variation"
    if len(ys) >= 3 and not coarse:  # weighted straight-line fit of the block centres, outliers dropped
        ys_a, cs_a, w_a = np.asarray(ys), np.asarray(cs), np.asarray(ws)
        keep = np.ones(len(ys_a), bool)
        for _ in range(3):
            coef = np.polyfit(ys_a[keep] + 0.5, cs_a[keep], 1, w=w_a[keep])
            res = cs_a - np.polyval(coef, ys_a + 0.5)
            mad = np.median(np.abs(res[keep])) * 1.4826 + 0.05
            keep = np.abs(res) < 3 * mad
            if keep.sum() < 3:
                keep[:] = True
                break
        coef = np.polyfit(ys_a[keep] + 0.5, cs_a[keep], 1, w=w_a[keep])
        tan_b = float(coef[0])
        x0 = float(coef[1])
        tilt = float(np.degrees(np.arctan(tan_b)))
    fine = np.arange(x0 - half, x0 + half, 0.25 if coarse else 0.05)
    prof_v = sheared_profile(v, tan_b, fine)
    prof_m = sheared_profile(m, tan_b, fine)
    bore = _bore_in_profile(fine, prof_v)
    lighting = "transmitted"
    if bore is not None:
        inside = np.abs(fine - 0.5 * (bore.left + bore.right)) < 0.3 * (bore.right - bore.left)
        # the background: beyond the walls (1.8 contents widths from the axis clears a 7 mm tube of
        # 3 mm bore against a 15 deg lamp) where the frame reaches that far, else what surrounds the bore
        width = bore.right - bore.left
        wide = np.arange(max(-pad, x0 - 3 * width - 6), min(w + pad, x0 + 3 * width + 6), 0.5)
        prof_wide = sheared_profile(m, tan_b, wide)
        far = (np.abs(wide - 0.5 * (bore.left + bore.right)) > 1.8 * width) & np.isfinite(prof_wide)
        surround = prof_wide[far] if far.sum() >= 8 else prof_m[~inside]
        if np.nanmedian(prof_m[inside]) > np.nanmedian(surround):
            # dark field: the bore is brighter than the background, light is scattered and
            # glare adds rather than multiplies, so the excess variation itself is measured
            lighting = "scattered"
            ex = excess if orient == "vertical" else np.ascontiguousarray(excess.T)
            bore = _bore_in_profile(fine, sheared_profile(ex, tan_b, fine))
        else:
            # transmitted light: each measure can only read the bore narrow — the excess
            # variation where the wall darkens the contents, the relative variation where blur
            # mixes the bore with the brighter surround — so the wider of the two is kept
            ex = excess if orient == "vertical" else np.ascontiguousarray(excess.T)
            other = _bore_in_profile(fine, sheared_profile(ex, tan_b, fine))
            if other is not None and other.right - other.left > bore.right - bore.left:
                bore = _Bore(other.left, other.right, bore.contrast, bore.noise)
    if bore is not None and bore.contrast > 8 * bore.noise:
        left, right, contrast = bore.left, bore.right, bore.contrast
        method = f"variation ({lighting} light)"
    else:
        method = "walls"
        contrast = 0.0
        if np.isfinite(prof_m).sum() < 4:
            raise MovieError("no tube found: nothing in the frames looks like a tube — is the tube in view and lit?")
        pm = np.interp(fine, fine[np.isfinite(prof_m)], prof_m[np.isfinite(prof_m)])
        gm = np.abs(np.gradient(gaussian_filter1d(pm, 10)))
        centre = int(np.argmin(np.abs(fine - x0)))
        lpk = int(np.argmax(gm[:centre])) if centre > 2 else 0
        rpk = centre + int(np.argmax(gm[centre:]))
        left, right = float(fine[lpk]), float(fine[rpk])
        # when nothing moves, the tube is its walls: a mean image flat across the frame holds none (plain background)
        seen = np.isfinite(prof_m)  # the profile's positions inside the frame
        # the positions whose tilted line stays in the frame over its whole height
        lo_seen, hi_seen = max(0.0, -h * tan_b), min(w - 1.0, w - 1.0 - h * tan_b)
        level = float(np.median(np.abs(pm[seen]))) or 1.0
        region = (fine >= lo_seen) & (fine <= hi_seen) & seen
        flat = region.any() and float(np.ptp(pm[region])) < FLAT_SHARE * level
        pv = prof_v[np.isfinite(prof_v)]
        moving = pv.size > 0 and float(np.max(pv)) > MOVING_OVER_STILL * max(float(np.percentile(pv, 5)), 1e-12)
        if not moving and flat:
            raise MovieError("no tube found: nothing moves in the frames and no two walls stand out in them — is "
                             "the tube in view (the region of interest around it) and lit?")
    width_px = (right - left) * np.cos(np.radians(tilt))
    axis_x0 = 0.5 * (left + right)
    if not width_px >= 3:
        raise MovieError(_too_narrow(width_px))
    # a side counts where the tube found reaches within its own width of it (a second tube cut there is not this one)
    reach = max(right - left, 3.0)
    near = (left + min(0.0, h * tan_b) < reach, right + max(0.0, h * tan_b) > w - 1 - reach)
    side = max([sv for sv, n in zip(sides, near, strict=True) if n], default=0.0) / top if structured else 0.0
    back_lit = None if method == "walls" else lighting == "transmitted"
    walls = None
    if not coarse and back_lit:
        # the walls' features, for the tube model: out to 3 visible widths from the axis
        reach = 3.0 * (right - left) + 6
        wide = np.arange(max(-pad, axis_x0 - reach), min(w + pad, axis_x0 + reach), 0.05)
        walls = measure_walls(wide, sheared_profile(m, tan_b, wide), axis_px=axis_x0,
                              visible_half_px=0.5 * (right - left)).scaled(np.cos(np.radians(tilt)))
    # narrow, no wall to tell a tube by, and not a tube the frame cuts (that is said: tube.cut_by_frame)
    if (not coarse and width_px < MIN_BORE_PX and side < 0.5
            and (walls is None or not np.isfinite(walls.outer_half_px))):
        raise MovieError(_too_narrow(width_px))  # narrow, and no wall to tell a tube by: a strip, a line of texture
    log.info("tube: %s, tilt %.3f deg, axis x0 %.2f px, inner diameter %.3f px (%s)",
             orient, tilt, axis_x0, width_px, method)
    return TubeGeometry(orient, float(tilt), float(axis_x0), float(width_px), float(contrast),
                        method, (h, w), back_lit=back_lit, walls=walls, side_variation=side)


def _too_narrow(width_px: float) -> str:
    return (f"no tube found (bore {width_px:.1f} px wide, and no wall seen beside it; at least {MIN_BORE_PX:g} px "
            f"needed) — is the tube in view, lit and at least {MIN_BORE_PX:g} px wide (the camera closer, or a larger "
            "image)?")


def find_tube(frames: list[np.ndarray], *, orientation: str | None = None) -> TubeGeometry:
    """Locate the tube from a sample of frames.

    Large frames are searched in two stages: the whole frame binned 2x2 (or
    more) gives the orientation, the tilt and the axis; the bore is then
    measured at full resolution in a band of columns around that axis only.

    Parameters
    ----------
    frames : list of ndarray
        Frames spread over the movie (grey or RGB).
    orientation : {"vertical", "horizontal"}, optional
        Restrict the search (known from the flow direction).

    Returns
    -------
    TubeGeometry

    Raises
    ------
    MovieError
        When no tube-like structure is found.
    """
    if not frames:
        raise MovieError("no frames to find the tube in")
    h, w = frames[0].shape[:2]
    if min(h, w) < 8:
        raise MovieError(f"the frames are {w} x {h} px: too small to hold a tube (at least 8 px each way)")
    bad = sum(1 for f in frames if f.dtype.kind == "f" and not np.isfinite(f).all())
    if bad:
        raise non_finite_frames(f"{bad} of the {len(frames)} sampled frames")
    lo = min(float(np.min(f)) for f in frames)
    hi = max(float(np.max(f)) for f in frames)
    if not hi > lo:
        raise MovieError(f"every sampled frame is uniform (all pixels {lo:g}): no tube to see — check the lamp, "
                         "the exposure and the lens cap")
    # frames without the scene's structure (lamp off, a flash, all saturated) say nothing of the tube
    # (one sample in 64 of one channel: the check costs ~1 ms instead of 40 on 1280 x 1024 RGB)
    spread = np.array([float(np.std(f[::8, ::8, 0] if f.ndim == 3 else f[::8, ::8], dtype=np.float64))
                       for f in frames])
    keep = spread >= 0.25 * float(np.median(spread))
    if keep.sum() >= 4 and not keep.all():
        log.info("tube: %d of %d sampled frames without structure left out", int((~keep).sum()), len(frames))
        frames = [f for f, k in zip(frames, keep, strict=True) if k]
    b = 1
    while max(h, w) // b > 700:
        b *= 2
    if b > 1:
        b *= 2  # the first look only needs the direction and position: coarser still
    try:
        return _find(frames, orientation, b, unshake=False)
    except MovieError as first:
        # the shaken outer edges of light walls can outshine the bore's contents: look again without the
        # variance the shake puts on still edges (only then: on steady footage it changes nothing found)
        try:
            tube = _find(frames, orientation, b, unshake=True)
        except MovieError:
            raise first from None
        log.info("tube found once the camera's shake was taken out of the still edges' variation (%s)", first)
        return tube


def _find(frames: list[np.ndarray], orientation: str | None, b: int, *, unshake: bool) -> TubeGeometry:
    """:func:`find_tube`'s search at binning ``b`` (1: one look at full resolution; else a coarse look at the
    binned frames, then a fine one on a band of full-resolution columns around the tube)."""
    h, w = frames[0].shape[:2]
    if b == 1:
        mean, std, level = mean_and_variation(frames)
        return dataclasses.replace(_locate(mean, std, orientation, unshake=unshake), background_level=level)
    mean, std, level = mean_and_variation(frames, binning=b)
    coarse = _locate(mean, std, orientation, coarse=True, unshake=unshake)
    transpose = coarse.orientation == "horizontal"
    ch, cw = (w, h) if transpose else (h, w)
    tan_b = np.tan(np.radians(coarse.tilt_deg))
    x0 = b * coarse.axis_x0_px + (b - 1) / 2  # binned pixel centre -> full-resolution pixel
    reach = 2.0 * b * coarse.inner_diameter_px + 8 * b
    xs = x0 + (np.array([0.0, ch]) + 0.5) * tan_b
    lo = int(max(0, np.floor(xs.min() - reach)))
    hi = int(min(cw, np.ceil(xs.max() + reach) + 1))
    cm, cs, _ = mean_and_variation(frames, transpose=transpose, cols=slice(lo, hi))
    fine = _locate(cm, cs, "vertical", tilt_hint=coarse.tilt_deg, unshake=unshake)
    log.debug("coarse tube at binning %d: %s", b, coarse)
    return TubeGeometry(coarse.orientation, fine.tilt_deg, fine.axis_x0_px + lo, fine.inner_diameter_px,
                        fine.contrast, fine.method, (ch, cw), level, fine.back_lit, fine.walls,
                        # the fine look sees a band of columns: the frame's sides are in the coarse one
                        side_variation=coarse.side_variation)
