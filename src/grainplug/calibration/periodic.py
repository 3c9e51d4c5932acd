"""The scale from a ruler or graph paper: the spatial frequency of their lines.

A ruler's millimetre ticks and graph paper's lines are gratings: in the image's
Fourier transform each family of parallel, evenly spaced lines is a peak at
the frequency vector ``f`` (cycles per px) perpendicular to the lines, with
``1 / |f|`` the spacing in pixels. The scale along ``f`` is then
``pitch_mm * |f|`` mm per px, measured from every line in the image at once.

Notes
-----
*Finding the peak.* The image, minus its slowly varying light (a Gaussian blur
of 4 % of its size), times a Hann window, is Fourier transformed with padding to
twice its size; the strongest peak away from zero frequency (at least 4 periods
across the image, below 0.45 cycles/px) is the first family. Thin lines have
harmonics as strong as their fundamental: when the transform is at least 35 % as
high at ``f / m`` (m = 2, 3, 4), that is the fundamental. Only sharp, isolated peaks
count (many lines), not the streaks of a ruler's edges. For graph paper the second
family is the strongest such peak 60-120 deg away from the first, with a spacing
within -20/+25 % of the first's (the paper is square).

*Refining it.* The discrete-time Fourier transform
``S(f) = sum_r w(r) g(r) exp(-2 pi i f . r)`` is maximised over ``f`` (Nelder-Mead
from the FFT's peak), which places the frequency to a small fraction of an FFT bin.
It is computed separably, ``e_y^T G e_x``.

*Edges.* A straight edge (a ruler's sides against the bench, a finger or the
tube's holder across graph paper) makes a streak through the transform that can
pull a peak. Before refining, the image is weighted by where the gratings are: its
local amplitude at the coarse frequencies (demodulated, low-passed over 1.5
periods), so that the refinement sees the lines and not what surrounds them.

*The map over the field.* The frequencies are measured again in tiles (up to 6 x 6; stretches along
a ruler), each started where the map fitted so far expects it, and a map from the image to the
pattern's plane (a homography after the lens's radial distortion is undone,
:mod:`grainplug.calibration.distortion`) is fitted to them: the frequency vectors are the rows of its
derivative. The tiles' scatter about it is the evidence that these are lines
(:func:`model_misfit`), and gives the uncertainty; the map gives the scale anywhere, and its variation.

*The finest level.* Graph paper has thin lines every millimetre and bolder ones every 5 and 10; a
ruler, longer ticks. The lines first found may be any level (the bold ones, or a harmonic of theirs).
The pattern's whole period is found by phase dispersion (:func:`coarsest_period`), the image is
folded over it through the map (:func:`fold`: every pixel at its position across the lines, so that
the faintest lines add up over the whole image), and the fold read (:func:`read_levels`): the finest
lines are the most numerous evenly spaced dips it shows, the bolder levels the classes of them that
dip deeper.

*Evidence.* Every image has a strongest peak; lines are believed only when each
family's peak stands ``MIN_PEAK_TO_NOISE`` times above the transform's median at
the same spatial frequency, makes ``MIN_LINES`` lines or more across where it was
found, and the parts agree on the spacing about the map (:func:`model_misfit`); the caller
(:func:`grainplug.calibration.pattern.calibrate_image`) refuses otherwise, and refuses lines whose
hierarchy does not show them to be the finest.
"""

from __future__ import annotations

import itertools
import logging
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

log = logging.getLogger(__name__)

#: the fundamental must reach this share of the strongest harmonic's height
FUNDAMENTAL_SHARE = 0.35
#: at least this many periods across the image
MIN_PERIODS = 4
#: a family's peak must stand this many times above the spectrum's median at the same spatial frequency
#: (white noise: 4-10 times; the speckle of a painted beam 26; graph paper and rulers 80 or more)
MIN_PEAK_TO_NOISE = 20.0
#: a family must have this many lines (periods) across where it was found
MIN_LINES = 16


def _prepare(grey: np.ndarray) -> np.ndarray:
    import cv2

    g = grey.astype(np.float32)
    sigma = 0.04 * max(g.shape)
    g = g - cv2.GaussianBlur(g, (0, 0), sigma)
    return g.astype(np.float64)


def _window(shape: tuple[int, int]) -> np.ndarray:
    return np.outer(np.hanning(shape[0]), np.hanning(shape[1]))


def _dtft_power(g: np.ndarray, f: np.ndarray) -> float:
    h, w = g.shape
    px = 2 * np.pi * f[0] * (np.arange(w) - (w - 1) / 2)
    py = 2 * np.pi * f[1] * (np.arange(h) - (h - 1) / 2)
    # g @ exp(-i px) with real products (no complex copy of the image)
    a, b = g @ np.cos(px), g @ np.sin(px)
    cy, sy = np.cos(py), np.sin(py)
    re = cy @ a - sy @ b
    im = -(cy @ b + sy @ a)
    return float(re * re + im * im)


def _refine(g: np.ndarray, f0: np.ndarray, bin_size: float, *, xatol: float = 1e-4, fatol: float = 1e-12) -> np.ndarray:
    from scipy.optimize import minimize

    scale = 1.0 / max(_dtft_power(g, f0), 1e-300)
    step = 0.3 * bin_size
    simplex = np.array([f0, f0 + np.array([step, 0.0]), f0 + np.array([0.0, step])])
    res = minimize(lambda f: -_dtft_power(g, f) * scale, f0, method="Nelder-Mead",
                   options={"initial_simplex": simplex,
                            "xatol": xatol * bin_size, "fatol": fatol, "maxiter": 400})
    return np.asarray(res.x, dtype=float)


def _peaks(g: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Magnitude of the padded FFT of the windowed image and its frequency axes (fx >= 0)."""
    h, w = g.shape
    spec = np.abs(np.fft.rfft2(g * _window(g.shape), s=(2 * h, 2 * w)))
    fy = np.fft.fftfreq(2 * h)
    fx = np.fft.rfftfreq(2 * w)
    return spec, fx, fy


def _height(spec: np.ndarray, fx: np.ndarray, fy: np.ndarray, f: np.ndarray) -> float:
    """Largest magnitude within one bin of frequency ``f`` (either sign)."""
    if f[0] < 0:
        f = -f
    ix = int(round(f[0] / fx[1]))
    iy = int(round(f[1] / (fy[1] - fy[0]))) % len(fy)
    best = 0.0
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            jx = ix + dx
            if 0 <= jx < spec.shape[1]:
                best = max(best, float(spec[(iy + dy) % spec.shape[0], jx]))
    return best


def _strongest(spec: np.ndarray, fx: np.ndarray, fy: np.ndarray, *, f_min: float, f_max: float = 0.45,
               away_from: np.ndarray | None = None) -> np.ndarray | None:
    """The strongest sharp peak (a grating of many lines), then its fundamental.

    A grating of many lines (16 or more) makes a sharp, isolated peak: along its
    direction the transform stays under half the peak's height from 5 % to 20 % of
    its frequency away. The few edges of a ruler against the bench make a streak of
    comparable lobes, and the thick lines every 10 mm of graph paper a comb of
    lobes 10 % apart: neither passes.
    """
    import cv2

    FX, FY = np.meshgrid(fx, fy)
    r = np.hypot(FX, FY)
    ok = (r >= f_min) & (r <= f_max)
    if away_from is not None:
        cos = np.abs(FX * away_from[0] + FY * away_from[1]) / np.maximum(r * np.hypot(*away_from), 1e-12)
        ok &= cos < math.cos(math.radians(60))
    spec32 = spec.astype(np.float32)
    local_max = (spec32 >= cv2.dilate(spec32, np.ones((5, 5), np.uint8))) & ok
    cand = np.flatnonzero(local_max)
    if not len(cand):
        return None
    cand = cand[np.argsort(spec.ravel()[cand])[::-1][:60]]
    bin_f = max(float(fx[1]), float(fy[1] - fy[0]))  # the coarser axis's bin

    def sharp(f: np.ndarray, top: float) -> bool:
        near = max(0.05, 4 * bin_f / float(np.hypot(*f)))
        if near >= 0.2:
            return False
        around = np.concatenate([np.linspace(0.8, 1 - near, 8), np.linspace(1 + near, 1.2, 8)])
        return max(_height(spec, fx, fy, f * k) for k in around) < 0.5 * top

    for k in cand:
        iy, ix = np.unravel_index(k, spec.shape)
        f = np.array([fx[ix], fy[iy]])
        top = float(spec[iy, ix])
        if not sharp(f, top):
            continue  # broad: not a grating
        # the fundamental: a lower harmonic, itself sharp, nearly as high as the strongest one
        for m in (4, 3, 2):
            sub = f / m
            h_sub = _height(spec, fx, fy, sub)
            if np.hypot(*sub) >= f_min and h_sub >= FUNDAMENTAL_SHARE * top and sharp(sub, h_sub):
                return sub
        return f
    return None


def _amplitude(g: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Local amplitude of the grating of frequency ``f``: the image demodulated at ``f``, low-passed over
    1.5 periods."""
    import cv2

    h, w = g.shape
    yy, xx = np.mgrid[0:h, 0:w]
    phase = 2 * np.pi * (f[0] * xx + f[1] * yy)
    sigma = 1.5 / max(float(np.hypot(*f)), 1e-6)
    c = cv2.GaussianBlur((g * np.cos(phase)).astype(np.float32), (0, 0), sigma)
    s = cv2.GaussianBlur((g * np.sin(phase)).astype(np.float32), (0, 0), sigma)
    return np.hypot(c, s).astype(np.float64)


def _support(g: np.ndarray, freqs: list[np.ndarray]) -> np.ndarray:
    """Where the gratings are, as weights in [0, 1]: 0 over the bench, a finger, a holder, and rising
    to 1 over two periods inside the gratings' edge (the edge itself is a step that would pull the peak)."""
    import cv2

    total = np.zeros(g.shape)
    for f in freqs:
        amp = _amplitude(g, f)
        total += amp / max(float(np.percentile(amp, 99.5)), 1e-12)
    on = (total / len(freqs) > 0.5).astype(np.uint8)
    period = 1.0 / max(float(np.hypot(*freqs[0])), 1e-6)
    k = max(3, int(round((3.0 if len(freqs) > 1 else 1.5) * period)) | 1)  # a ruler's ticks are short
    inner = cv2.erode(on, np.ones((k, k), np.uint8), borderType=cv2.BORDER_REPLICATE)
    return np.clip(cv2.GaussianBlur(inner.astype(np.float32), (0, 0), period), 0.0, 1.0).astype(np.float64)


@dataclass(frozen=True)
class Gratings:
    """Line gratings found in an image.

    Attributes
    ----------
    freqs : list of ndarray
        Frequency vector of each family (cycles/px, ``(fx, fy)``).
    support : ndarray
        Where the gratings are (weights in [0, 1]).
    box : tuple of int
        Bounding box ``(y0, y1, x0, x1)`` of the support.
    peak_to_noise : tuple of float
        Each family's peak over the median of the transform at the same spatial frequency
        (all directions, within two bins): how far the lines stand above the image's noise.
    lines : tuple of float
        How many periods of each family span the box.
    """

    freqs: list[np.ndarray]
    support: np.ndarray
    box: tuple[int, int, int, int]
    peak_to_noise: tuple[float, ...] = ()
    lines: tuple[float, ...] = ()


def find_gratings(grey: np.ndarray, *, families: int) -> Gratings | None:
    """The ``families`` strongest line gratings (1: a ruler's ticks; 2: graph paper), refined.

    Parameters
    ----------
    grey : ndarray
        The image, grey.
    families : {1, 2}
        How many families of lines to look for.

    Returns
    -------
    Gratings or None
        None when no grating is found (a second family may be missing).
    """
    g = _prepare(grey)
    spec, fx, fy = _peaks(g)
    f_min = MIN_PERIODS / min(g.shape)
    bin_size = float(fx[1])
    first = _strongest(spec, fx, fy, f_min=f_min)
    if first is None:
        return None
    coarse = [first]
    if families >= 2:
        # graph paper is square: the other family has nearly the same spacing, at 60-120 deg
        # (rolled and seen in perspective)
        f1 = float(np.hypot(*first))
        second = _strongest(spec, fx, fy, f_min=max(f_min, 0.8 * f1), f_max=min(0.45, 1.25 * f1), away_from=first)
        if second is not None and _height(spec, fx, fy, second) >= 0.15 * _height(spec, fx, fy, first):
            coarse.append(second)
    # weigh the image by where the gratings are, so that edges around and across them (the ruler's
    # sides, the bench, a finger) do not pull the peaks
    support = _support(g, coarse)
    gw = g * _window(g.shape) * support
    freqs = [_refine(gw, f, bin_size) for f in coarse]
    ys, xs = np.nonzero(support > 0.5)
    h, w = g.shape
    box = (0, h, 0, w) if len(ys) < 16 else (int(ys.min()), int(ys.max()) + 1, int(xs.min()), int(xs.max()) + 1)
    y0, y1, x0, x1 = box
    FX, FY = np.meshgrid(fx, fy)
    radius = np.hypot(FX, FY)
    snr, lines = [], []
    for f in freqs:
        ring = np.abs(radius - float(np.hypot(*f))) <= 2 * bin_size
        floor = float(np.median(spec[ring])) if ring.any() else 0.0
        snr.append(_height(spec, fx, fy, f) / floor if floor > 0 else math.inf)
        lines.append(float(abs(f[0]) * (x1 - x0) + abs(f[1]) * (y1 - y0)))
    return Gratings(freqs, support, box, tuple(snr), tuple(lines))


def local_frequencies(grey: np.ndarray, found: Gratings) -> tuple[np.ndarray, np.ndarray]:
    """The families' frequencies refined in parts of the gratings' box: a 3 x 3 grid of tiles for two
    families, five stretches along the lines' normal for one (a ruler).

    Returns
    -------
    centres : ndarray, (n, 2)
        Each part's weighted centre (x, y) in px.
    freqs : ndarray, (n, 2 * families)
        Its families' frequency vectors, end to end.
    sizes : ndarray, (n, 2)
        Its height and width in px.
    """
    y0, y1, x0, x1 = found.box
    freqs = found.freqs
    if len(freqs) >= 2:
        ycuts, xcuts = np.linspace(y0, y1, 4).astype(int), np.linspace(x0, x1, 4).astype(int)
        parts = [(slice(a, b), slice(c, d)) for a, b in itertools.pairwise(ycuts)
                 for c, d in itertools.pairwise(xcuts)]
    elif abs(freqs[0][0]) >= abs(freqs[0][1]):  # a ruler across the image: stretches of columns
        cuts = np.linspace(x0, x1, 6).astype(int)
        parts = [(slice(y0, y1), slice(a, b)) for a, b in itertools.pairwise(cuts)]
    else:
        cuts = np.linspace(y0, y1, 6).astype(int)
        parts = [(slice(a, b), slice(x0, x1)) for a, b in itertools.pairwise(cuts)]
    weights = [float(found.support[ys, xs].sum()) for ys, xs in parts]
    centres, out, sizes = [], [], []
    for (ys, xs), wsum in zip(parts, weights, strict=True):
        part = grey[ys, xs]
        weight = found.support[ys, xs]
        if min(part.shape) < 16 or wsum < 0.3 * max(weights):
            continue
        gw = _prepare(part) * _window(part.shape) * weight
        bin_size = 0.5 / max(part.shape)
        out.append(np.concatenate([_refine(gw, f, bin_size) for f in freqs]))
        yy, xx = np.mgrid[ys, xs]
        centres.append([float((xx * weight).sum() / wsum), float((yy * weight).sum() / wsum)])
        sizes.append(part.shape)
    return (np.asarray(centres, dtype=float).reshape(-1, 2),
            np.asarray(out, dtype=float).reshape(len(out), 2 * len(freqs)),
            np.asarray(sizes, dtype=float).reshape(-1, 2))


#: the parts' spatial frequencies may scatter about a smooth trend by this share of a part's frequency bin
MAX_PART_MISFIT_BINS = 0.1


def part_misfit(centres: np.ndarray, freqs: np.ndarray, sizes: np.ndarray) -> float:
    """How far the parts' line spacings scatter about a smooth trend, in frequency bins of a part.

    Perspective makes the spacing change smoothly over the image: each family's spatial
    frequency ``|f|`` in the parts is fitted by a plane in the parts' centres (a line when
    the parts lie along a line, as along a ruler), and the residuals' standard deviation is
    expressed in units of a part's frequency resolution (one over its extent along ``f``).
    Real lines agree to a few hundredths of a bin (0.02 at most on the rendered graph paper
    and rulers); the peak of noise or of a random texture wanders by a third of a bin or
    more from part to part.

    Returns
    -------
    float
        The largest misfit over the families (inf with fewer than 4 parts).
    """
    n = len(centres)
    if n < 4:
        return math.inf
    c = centres - centres.mean(axis=0)
    _, sv, vt = np.linalg.svd(c, full_matrices=False)
    axes = vt[sv > 0.1 * sv[0]] if sv[0] > 0 else vt[:0]
    A = np.column_stack([np.ones(n), c @ axes.T])
    dof = n - A.shape[1]
    if dof < 1:
        return math.inf
    worst = 0.0
    for k in range(freqs.shape[1] // 2):
        f = freqs[:, 2 * k: 2 * k + 2]
        mag = np.hypot(f[:, 0], f[:, 1])
        coef, *_ = np.linalg.lstsq(A, mag, rcond=None)
        resid = mag - A @ coef
        u = np.abs(f / mag[:, None])
        extent = u[:, 0] * sizes[:, 1] + u[:, 1] * sizes[:, 0]  # each part's length along f, px
        worst = max(worst, math.sqrt(float(resid @ resid) / dof) * float(np.mean(extent)))
    return worst


# -- the map over the field (lens distortion, perspective) and the lines' hierarchy -------------------------
def tile_frequencies(grey: np.ndarray, found: Gratings, *, grid: int,
                     predict: Callable[[np.ndarray], np.ndarray] | None = None,
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The families' frequencies refined in ``grid`` x ``grid`` tiles of the gratings' box (``grid`` stretches
    along a ruler), each started from ``predict(centre)`` (the frequencies a map fitted already expects there)
    or from the whole image's.

    Returns
    -------
    centres : ndarray, (n, 2)
        Each part's weighted centre (x, y) in px.
    freqs : ndarray, (n, 2 * families)
        Its families' frequency vectors (cycles/px), end to end.
    sizes : ndarray, (n, 2)
        Its height and width in px.
    weights : ndarray, (n,)
        Its share of the gratings (sum of the support).
    """
    y0, y1, x0, x1 = found.box
    freqs = found.freqs

    def spans(lo: int, hi: int) -> list[slice]:
        edges = np.linspace(lo, hi, grid + 1)
        half = 0.5 * (hi - lo) / grid
        out = []
        for mid in 0.5 * (edges[:-1] + edges[1:]):
            a = int(round(min(max(mid - half, lo), hi - 2 * half)))
            out.append(slice(a, int(round(a + 2 * half))))
        return out

    if len(freqs) >= 2:
        parts = [(ys, xs) for ys in spans(y0, y1) for xs in spans(x0, x1)]
    elif abs(freqs[0][0]) >= abs(freqs[0][1]):
        parts = [(slice(y0, y1), xs) for xs in spans(x0, x1)]
    else:
        parts = [(ys, slice(x0, x1)) for ys in spans(y0, y1)]
    sums = [float(found.support[ys, xs].sum()) for ys, xs in parts]
    centres, out, sizes, weights = [], [], [], []
    for (ys, xs), wsum in zip(parts, sums, strict=True):
        part = grey[ys, xs]
        weight = found.support[ys, xs]
        if min(part.shape) < 16 or wsum < 0.3 * max(sums):
            continue
        yy, xx = np.mgrid[ys, xs]
        centre = np.array([float((xx * weight).sum() / wsum), float((yy * weight).sum() / wsum)])
        start = (np.asarray(predict(centre), float).reshape(-1, 2) if predict is not None
                 else np.asarray(freqs, float))
        gw = _prepare(part) * _window(part.shape) * weight
        bin_size = 0.5 / max(part.shape)
        out.append(np.concatenate([_refine(gw, f, bin_size, xatol=1e-3, fatol=1e-8) for f in start]))
        centres.append(centre)
        sizes.append(part.shape)
        weights.append(wsum)
    n = len(out)
    return (np.asarray(centres, dtype=float).reshape(-1, 2), np.asarray(out, dtype=float).reshape(n, 2 * len(freqs)),
            np.asarray(sizes, dtype=float).reshape(-1, 2), np.asarray(weights, dtype=float))


def model_misfit(freqs: np.ndarray, model: np.ndarray, sizes: np.ndarray, *, n_params: int) -> float:
    """How far the parts' line spacings scatter about a fitted map's, in frequency bins of a part.

    As :func:`part_misfit`, with the map fitted to the parts (perspective and the lens's distortion) as the
    smooth trend: each family's ``|f|`` against the map's at the same place, the residuals' standard
    deviation (``n_params`` shared between the families) in units of one over a part's extent along ``f``.

    Returns
    -------
    float
        The largest misfit over the families (inf when there are no more parts than parameters).
    """
    n, families = len(freqs), freqs.shape[1] // 2
    dof = n - n_params / families
    if dof < 1:
        return math.inf
    worst = 0.0
    for k in range(families):
        f = freqs[:, 2 * k: 2 * k + 2]
        mag = np.hypot(f[:, 0], f[:, 1])
        resid = mag - np.hypot(model[:, 2 * k], model[:, 2 * k + 1])
        u = np.abs(f / mag[:, None])
        extent = u[:, 0] * sizes[:, 1] + u[:, 1] * sizes[:, 0]
        worst = max(worst, math.sqrt(float(resid @ resid) / dof) * float(np.mean(extent)))
    return worst


#: the pattern's whole period, in periods of the lines first found (graph paper's 10 mm lines in its 1 mm, 5 mm
#: lines, or in the 2nd harmonic of its 5 mm ones; a ruler's 10 mm in its half-millimetre ticks)
COARSE_PERIODS = (2, 4, 5, 10, 20)
#: periods no pattern has, folded to see how much a fold over a long period scatters by chance
CONTROL_PERIODS = (3, 7)
#: ... and must repeat at least this many times across the image
MIN_COARSE_CYCLES = 2.0
#: a coarser repeat must stand this many times above the profile's noise (and 3 % of the lines' own); one found
#: wrongly is harmless: the fold then shows no level of bolder lines, and the lines are refused
COARSE_Z = 4.0
#: finer lines closer than this (px) cannot be resolved
MIN_FINE_PX = 2.4
#: a level of bolder lines (every 2nd, 5th, 10th...) and finer lines must stand this many standard errors out
LEVEL_Z = 5.0


def coarsest_period(coordinate: np.ndarray, values: np.ndarray, *, bins: int, period_px: float) -> int:
    """The pattern's whole period, in periods of the lines first found: graph paper whose 1 mm lines were found
    repeats every 10 (its 10 mm lines; every 5 when they are not bolder than the 5 mm ones), one whose 5 mm
    lines were found every 2, a ruler with half-millimetre ticks every 20, a grating without bolder lines 1.

    Phase dispersion: the pixels (``values`` at ``coordinate``, in periods from a fitted map, perspective and
    the lens's distortion undone) are folded over ``j`` periods (``j`` in ``COARSE_PERIODS``, repeating
    ``MIN_COARSE_CYCLES`` times or more across the image) and each period of the fold compared with the
    fold over one: the mean square difference ``D_j`` is the structure that repeats every ``j`` periods and
    not every one. The pattern's period is the smallest ``j`` with ``D_j`` at least 80 % of the largest,
    when that stands ``COARSE_Z`` times above the ``D`` of periods that do not divide into it or it into
    them (3 and 7, never a pattern's, among them: with few repeats across the image, a fold over any long
    period scatters); else 1.
    """
    length = float(np.ptp(coordinate))
    one = fold(values, coordinate, span=1, bins=bins, period_px=period_px)
    dispersion = {}
    for j in sorted({*COARSE_PERIODS, *CONTROL_PERIODS}):
        if length < MIN_COARSE_CYCLES * j:
            continue
        fj = fold(values, coordinate, span=j, bins=bins, period_px=period_px)
        diff = fj.profile.reshape(j, bins) - one.profile[None, :]
        dispersion[j] = float(np.nanmean(diff**2))
    log.debug("phase dispersion by period: %s", {j: round(d, 2) for j, d in dispersion.items()})
    candidates = {j: d for j, d in dispersion.items() if j in COARSE_PERIODS}
    if not candidates:
        return 1
    top = max(candidates.values())
    j0 = min(j for j, d in candidates.items() if d >= 0.8 * top)
    others = [d for j, d in dispersion.items() if j % j0 and j0 % j]
    if not others:
        return 1
    return j0 if candidates[j0] > COARSE_Z * float(np.median(others)) else 1


@dataclass(frozen=True)
class Fold:
    """The image's mean grey level against the position across one family of lines, modulo ``span`` periods.

    Attributes
    ----------
    profile : ndarray, (span * bins,)
        Mean grey in each bin (nan where no pixel fell).
    se : ndarray
        Its standard error.
    span : int
        Periods folded.
    bins : int
        Bins per period.
    period_px : float
        The period in px (at the pattern's centre).
    halves : tuple of ndarray
        The profiles of the two halves of the image across the lines, for the reproducibility of what
        is read in the fold.
    """

    profile: np.ndarray
    se: np.ndarray
    span: int
    bins: int
    period_px: float
    halves: tuple[np.ndarray, ...] = ()

    def at(self, x: np.ndarray, *, profile: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The profile (or another over the same bins) and its standard error at positions ``x`` (periods),
        linearly interpolated, circular."""
        n = len(self.profile)
        t = np.mod(np.asarray(x, float) * self.bins - 0.5, n)
        i = np.floor(t).astype(int)
        a = t - i
        i %= n  # np.mod of a tiny negative number can give n itself
        j = (i + 1) % n
        p = self.profile if profile is None else profile
        value = (1 - a) * p[i] + a * p[j]
        se = np.hypot((1 - a) * self.se[i], a * self.se[j])
        return value, se


def fold(values: np.ndarray, coordinate: np.ndarray, *, span: int, bins: int, period_px: float) -> Fold:
    """Fold pixels' ``values`` by their ``coordinate`` (periods, from a fitted map) modulo ``span`` periods.

    The standard error is the folds' own: half the robust spread of the difference between the folds of
    the two halves of the image across the lines (noise, and the map's misfit), the same for every bin
    but for its count of pixels.
    """
    n_bins = span * bins
    v = np.asarray(values, np.float64)
    c = np.asarray(coordinate, np.float64)
    b = np.floor(np.mod(c, span) * bins).astype(np.int64) % n_bins

    def mean_of(sel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = np.bincount(b[sel], minlength=n_bins).astype(float)
        s1 = np.bincount(b[sel], weights=v[sel], minlength=n_bins)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(n > 0, s1 / n, np.nan), n

    everything = np.ones(len(v), bool)
    mean, n = mean_of(everything)
    half = c < np.median(c)
    a_mean, _ = mean_of(half)
    b_mean, _ = mean_of(~half)
    d = np.abs(a_mean - b_mean)
    ok = np.isfinite(d)
    # each half's mean has twice the variance of the whole's: sd(whole) = sd(a - b) / 2
    spread = 1.4826 * float(np.median(d[ok])) / 2.0 if ok.any() else np.inf
    mean_n = float(np.mean(n[n > 0])) if np.any(n > 0) else 1.0
    with np.errstate(invalid="ignore", divide="ignore"):
        se = spread * np.sqrt(mean_n / n)
    empty = n < 1
    mean[empty], se[empty] = np.nan, np.nan
    return Fold(mean, se, span, bins, period_px, (a_mean, b_mean))


def _dips(f: Fold, x: np.ndarray, half: float) -> tuple[np.ndarray, np.ndarray]:
    """How much darker the profile is at ``x`` than ``half`` a period either side, and its standard error: half
    the robust spread of the same dips measured in the two halves of the image (noise, and the fitted map's
    misfit between them), the same for every position."""
    def dip(profile: np.ndarray | None) -> np.ndarray:
        centre, _ = f.at(x, profile=profile)
        left, _ = f.at(x - half, profile=profile)
        right, _ = f.at(x + half, profile=profile)
        return 0.5 * (left + right) - centre

    d = dip(None)
    if len(f.halves) == 2:
        gap = np.abs(dip(f.halves[0]) - dip(f.halves[1]))
        gap = gap[np.isfinite(gap)]
        se = 1.4826 * float(np.median(gap)) / 2.0 if len(gap) else math.inf
        se = max(se, 1e-9)
    else:
        se = float(np.nanmedian(f.at(x)[1]))
    return d, np.full(len(d), se)


def _line_phase(f: Fold, m: int) -> float:
    """Where the dark lines repeating ``m`` times over the fold are, in periods (modulo ``span / m``)."""
    x = (np.arange(len(f.profile)) + 0.5) / f.bins
    ok = np.isfinite(f.profile)
    nu = m / f.span
    c = np.sum((f.profile[ok] - np.mean(f.profile[ok])) * np.exp(-2j * np.pi * nu * x[ok]))
    return float(np.mod((np.pi - np.angle(c)) / (2 * np.pi * nu), 1.0 / nu))


@dataclass(frozen=True)
class Levels:
    """The lines' hierarchy read in a :class:`Fold`.

    Attributes
    ----------
    finer : int
        The finest lines seen are this many per fold (the pattern's whole period).
    phase : float
        Where a finest line is, in periods first found (modulo ``span / finer``).
    bolder : tuple of int
        Every how many finest lines a bolder (longer) one comes, for each level seen (2, 5, 10).
    dips : ndarray
        The finest lines' depths over the fold (grey levels), for the record.
    """

    finer: int
    phase: float
    bolder: tuple[int, ...]
    dips: np.ndarray


def read_levels(f: Fold) -> Levels:
    """The finest lines in a fold over the pattern's whole period, and the bolder lines among them.

    The finest lines are ``m`` per fold, for the largest ``m`` (their spacing at least
    ``MIN_FINE_PX``) at which the profile dips (against a quarter of their spacing either side, clear of a
    bold neighbour's edge) at every one of the ``m`` evenly spaced positions:
    by ``LEVEL_Z`` standard errors in the median and by 2 at 9 positions in 10 (at ``m`` too large,
    half the positions fall between lines). Among them, a level of bolder ones every ``r`` (2, 5,
    10, 20) is seen when every line of one class modulo ``r`` dips deeper than any other's, by
    ``LEVEL_Z`` standard errors or a quarter of the others' median depth, whichever is more.
    """
    max_m = int(min(40, f.span * f.period_px / MIN_FINE_PX))
    finer, phase = 1, _line_phase(f, 1)
    for m in range(max(max_m, 1), 0, -1):
        x0 = _line_phase(f, m)
        x = x0 + np.arange(m) * f.span / m
        d, se = _dips(f, x, 0.25 * f.span / m)
        ok = np.isfinite(d) & np.isfinite(se) & (se > 0)
        if ok.sum() < 0.9 * m:
            continue
        z = d[ok] / se[ok]
        if np.median(z) >= LEVEL_Z and np.mean(z > 2.0) >= 0.9:
            finer, phase = m, x0
            break
    x = phase + np.arange(finer) * f.span / finer
    d, se = _dips(f, x, 0.5 * f.span / finer)
    bolder = []
    for r in (2, 5, 10, 20):
        if finer < r or finer % r or not np.all(np.isfinite(d)):
            continue
        classes = [d[c::r] for c in range(r)]
        best = int(np.argmax([float(np.mean(c)) for c in classes]))
        others = np.concatenate([c for i, c in enumerate(classes) if i != best])
        margin = max(LEVEL_Z * float(np.median(se)), 0.25 * max(float(np.median(others)), 0.0))
        if float(np.min(classes[best])) > float(np.max(others)) + margin:
            bolder.append(r)
    return Levels(finer, float(phase), tuple(bolder), d)
