"""The bore's true width in pixels from a physical model of the tube (issue 16, item 3).

What the camera shows of a glass tube depends on the lighting; the tube's own
geometry does not. :func:`measure_walls` reads, on the mean profile across a
tube, the features that refraction fixes whatever the lamp:

* the **outer silhouette**: where the direct view of the background ends;
* the **bright stripe** inside each wall of a back-lit tube, where the rays that
  are totally reflected at the inner wall go straight on
  (:func:`grainplug.calibration.refraction.stripe_radius`).

:func:`bore_from_model` turns them, with what the user knows of the tube (inner
diameter, and the outer diameter and the glass's index if known), into
independent estimates of the bore's width in pixels, picks the best, and says how
far they agree.

Notes
-----
Estimates of the bore's diameter ``2a`` in pixels (``o``, ``s``: measured outer
and stripe half-widths; ``v``: the half-width over which the contents are seen
to change; ``ID``, ``OD``: the tube's diameters in mm):

``outer``
    ``2 o ID / OD``: needs ``OD``; independent of the lamp and of the glass.
``stripe + outer``
    the ratio ``a / b`` that puts the stripe at ``s / o`` of the outer radius
    (:func:`~grainplug.calibration.refraction.radius_ratio_from_stripe`), times
    ``2 o``: needs the glass's index (1.47 for borosilicate; 1.52 soda-lime glass
    moves it by ~2 %).
``stripe``
    ``2 s / k`` with ``k = x0 / a`` for the tube's ``OD / ID`` (or 1.395, the value
    for ``OD / ID = 1.83``, when the outer diameter is unknown: ``k`` is 1.37-1.43
    for ``OD / ID`` = 1.67-2.33).
``contents``
    ``2 v``: right in front light and for large lamps; in back light a lower
    bound (65 % of the bore at a 15 deg lamp).

The measured positions are taken on the mean image, so that the moving contents
average out; the stripe's centre is the centroid of its bright part, which a
symmetric optical blur does not move.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .refraction import BOROSILICATE_INDEX, bisect, lamp_table

#: OD / ID assumed for the stripe alone when the outer diameter is unknown (3 mm bore, 5.5 mm tube)
TYPICAL_OUTER_OVER_INNER = 1.83
#: estimates further apart than this (relative) are reported as disagreeing
AGREEMENT = 0.03
#: how far (px, on the diameter) the edges of the contents' variation may lie from the bore's edges on any camera:
#: blur, noise and a lossy codec's blocks move a half-height crossing by a few tenths of a pixel on each side.
#: Calibrated on the sweep of ``benchmarks/intervals.py`` (front light, 10-60 px bores, TIFF/H.264/MJPEG: 95 % of
#: the errors of the seeds it was fitted on are within 1.96 times ``hypot(0.6 px / bore, 1 %)``)
CONTENTS_EDGE_PX = 0.6
#: the same for the bright stripes' centroids (px, on their separation): a centroid, not an edge, so less
STRIPE_CENTROID_PX = 0.1
#: how much narrower than its bore a back-lit tube's contents can look (the lamp's angular size; the renderers tried:
#: up to 35 %; a 15 deg lamp, 24 %)
BACK_LIT_NARROWING = 0.35
#: the relative standard uncertainty that a bore read from the contents alone in back light carries for it: the bore
#: is between the contents' width and 1 / (1 - BACK_LIT_NARROWING) times it, and the estimate is the lower end, so
#: 1.96 standard deviations reach the upper end
BACK_LIT_CONTENTS_SD = (1 / (1 - BACK_LIT_NARROWING) - 1) / 1.96


@dataclass(frozen=True)
class WallMeasure:
    """Features of the walls on the mean profile across the tube (px from the axis).

    Attributes
    ----------
    outer_half_px : float
        Half the outer silhouette's width (NaN when a side of the tube is out of
        view or has no background beyond it).
    stripe_half_px : float
        Half the distance between the two bright stripes (NaN when not seen).
    outer_sides_px, stripe_sides_px : tuple of float
        The left and right values (distance from the axis), to judge symmetry.
    stripe_width_px : float
        Mean width of the two bright bands (grows with the lamp's size).
    """

    outer_half_px: float
    stripe_half_px: float
    outer_sides_px: tuple[float, float]
    stripe_sides_px: tuple[float, float]
    stripe_width_px: float = float("nan")

    def scaled(self, factor: float) -> WallMeasure:
        """The same measures with every distance multiplied by ``factor`` (e.g. ``cos(tilt)``)."""
        return WallMeasure(self.outer_half_px * factor, self.stripe_half_px * factor,
                           (self.outer_sides_px[0] * factor, self.outer_sides_px[1] * factor),
                           (self.stripe_sides_px[0] * factor, self.stripe_sides_px[1] * factor),
                           self.stripe_width_px * factor)

    def as_dict(self) -> dict[str, object]:
        return {"outer_half_px": self.outer_half_px, "stripe_half_px": self.stripe_half_px,
                "outer_sides_px": list(self.outer_sides_px), "stripe_sides_px": list(self.stripe_sides_px),
                "stripe_width_px": self.stripe_width_px}


def _smooth(prof: np.ndarray, sigma_samples: float) -> np.ndarray:
    if sigma_samples <= 0:
        return prof
    half = int(math.ceil(4 * sigma_samples))
    k = np.exp(-0.5 * (np.arange(-half, half + 1) / sigma_samples) ** 2)
    k /= k.sum()
    padded = np.pad(prof, half, mode="edge")
    return np.convolve(padded, k, mode="valid")


def _crossing(r: np.ndarray, sm: np.ndarray, level: float, start: int, stop: int) -> float:
    """First position between samples ``start`` and ``stop`` (either direction) where ``sm`` crosses ``level``."""
    step = 1 if stop >= start else -1
    above = sm[start] >= level
    for i in range(start + step, stop + step, step):
        if (sm[i] >= level) != above:
            j = i - step
            if sm[i] == sm[j]:
                return float(r[i])
            return float(r[j] + (r[i] - r[j]) * (level - sm[j]) / (sm[i] - sm[j]))
    return float("nan")


def _side(r: np.ndarray, sm: np.ndarray, visible_half: float, step_px: float) -> tuple[float, float, float]:
    """``(outer, stripe, stripe width)`` on one side of a back-lit tube (px from the axis); NaN where not found.

    ``r`` increases outwards from the axis; ``sm`` is the smoothed mean profile.
    """
    nan = float("nan")
    n = len(r)
    if n < 20:
        return nan, nan, nan
    px = int(round(1.0 / step_px))
    # the background: the bright level the profile reaches beyond the tube and keeps to the end of the
    # searched range (at least 3 px of it)
    tail = max(3 * px, n // 20)
    if n <= tail + 2 * px:
        return nan, nan, nan
    bg = float(np.median(sm[-tail:]))
    start_v = int(np.searchsorted(r, visible_half))
    if start_v >= n - tail:
        return nan, nan, nan  # the range ends inside the tube (a cropped strip): no silhouette
    dark = float(np.min(sm[start_v:]))
    if not bg - dark > 0.2 * abs(bg):
        return nan, nan, nan  # walls without contrast: nothing to measure
    if np.mean(np.abs(sm[-tail:] - bg) < 0.15 * (bg - dark)) < 0.9:
        return nan, nan, nan  # no flat background at the end of the range: the strip is cropped to the tube
    # walk in from the background to the first sample darker than half-way to the darkest point of
    # the wall; the silhouette's edge is the steepest point of that rise (a symmetric blur keeps it)
    half_global = 0.5 * (bg + dark)
    k = n - tail
    while k > start_v and sm[k] >= half_global:
        k -= 1
    if k <= start_v:
        return nan, nan, nan
    lo, hi = max(start_v + 1, k - 2 * px), min(n - 2, k + 3 * px)
    grad = sm[lo + 1: hi + 2] - sm[lo - 1: hi]
    g = int(np.argmax(grad))
    i = lo + g
    outer = float(r[i])
    if 0 < g < len(grad) - 1:
        den = grad[g - 1] - 2 * grad[g] + grad[g + 1]
        if den < 0:
            outer += float(0.5 * (grad[g - 1] - grad[g + 1]) / den) * (r[i + 1] - r[i])
    # the stripe: the brightest peak between the visible bore's edge and the outer wall's dark band
    i_out = int(np.searchsorted(r, outer))
    seg_lo = start_v + px // 2
    seg_hi = i_out - px
    if seg_hi - seg_lo < 2 * px:
        return outer, nan, nan
    seg = sm[seg_lo:seg_hi]
    j = int(np.argmax(seg))
    peak = float(seg[j])
    if j == 0 or j == len(seg) - 1:
        return outer, nan, nan  # rises into the bore or the silhouette: not a separate stripe
    floor_in = float(np.min(seg[:j + 1]))
    floor_out = float(np.min(seg[j:]))
    floor = max(floor_in, floor_out)
    if peak - floor < 0.12 * (bg - dark):
        return outer, nan, nan
    # the band's edges: half-way between its top and the dark on each side
    level_in = floor_in + 0.5 * (peak - floor_in)
    level_out = floor_out + 0.5 * (peak - floor_out)
    rs = r[seg_lo:seg_hi]
    inner_edge = _crossing(rs, seg, level_in, j, 0)
    outer_edge = _crossing(rs, seg, level_out, j, len(seg) - 1)
    if not (math.isfinite(inner_edge) and math.isfinite(outer_edge)):
        return outer, nan, nan
    return outer, 0.5 * (inner_edge + outer_edge), outer_edge - inner_edge


def measure_walls(grid_px: np.ndarray, mean_profile: np.ndarray, *, axis_px: float, visible_half_px: float,
                  blur_px: float = 0.5) -> WallMeasure:
    """The outer silhouette and the bright stripes of a back-lit tube on its mean profile.

    Parameters
    ----------
    grid_px : ndarray
        Evenly spaced positions across the tube (px, canonical view), at most
        0.25 px apart.
    mean_profile : ndarray
        The temporal mean image averaged along the tube's axis, on ``grid_px``
        (NaN where no pixel was seen).
    axis_px : float
        The tube's axis on ``grid_px``.
    visible_half_px : float
        Half the width over which the contents are seen to change (the search for
        the walls starts there).
    blur_px : float
        Smoothing (px) applied to the profile first.

    Returns
    -------
    WallMeasure
    """
    ok = np.isfinite(mean_profile)
    nan = float("nan")
    empty = WallMeasure(nan, nan, (nan, nan), (nan, nan), nan)
    if ok.sum() < 20:
        return empty
    step = float(grid_px[1] - grid_px[0])
    # only the seen part, on each side of the axis (a side cut by the frame ends where the pixels do)
    idx = np.flatnonzero(ok)
    grid, prof = grid_px[idx[0]: idx[-1] + 1], mean_profile[idx[0]: idx[-1] + 1]
    prof = np.interp(grid, grid[np.isfinite(prof)], prof[np.isfinite(prof)])
    sm = _smooth(prof, blur_px / step)
    c = int(np.searchsorted(grid, axis_px))
    if not 0 < c < len(grid) - 1:
        return empty
    sides = []
    for sl, sign in ((slice(c, None), 1.0), (slice(c, None, -1) if c > 0 else slice(0, 0), -1.0)):
        g = grid[sl]
        r = sign * (g - axis_px)
        sides.append(_side(r, sm[sl], visible_half_px, step))
    (o_r, s_r, w_r), (o_l, s_l, w_l) = sides
    return WallMeasure(0.5 * (o_l + o_r), 0.5 * (s_l + s_r), (o_l, o_r), (s_l, s_r), 0.5 * (w_l + w_r))


#: lamps considered (half-angle, degrees): from a small diffuser far away to a panel close behind
LAMP_RANGE_DEG = (5.0, 89.0)


def solve_lamp(visible_half: float, stripe_mid: float, stripe_width: float, *, outer_over_inner: float,
               n_glass: float = BOROSILICATE_INDEX) -> tuple[float, float, float]:
    """The bore's radius from the bright wall band of a back-lit tube, for every lamp the picture allows.

    Parameters
    ----------
    visible_half : float
        Half the width over which the contents are seen (px).
    stripe_mid, stripe_width : float
        The bright wall band's middle (from the axis) and width (px).
    outer_over_inner : float
        The tube's ``OD / ID``.
    n_glass : float
        The glass's index.

    Returns
    -------
    beta_deg : float
        The largest lamp half-angle the picture allows.
    radius_px : float
        The bore's radius (NaN when the band fits no lamp).
    rel_sd : float
        Its relative uncertainty from the lamp's unknown size.

    Notes
    -----
    In bore radii ``a`` the band lies at ``M(beta)`` (its middle), ``W(beta)`` wide, and
    the contents are seen over ``F(beta)`` of the principal rays
    (:func:`~grainplug.calibration.refraction.lamp_table`). ``M`` hardly depends on the
    lamp (1.34-1.41 for a 3/5.5 mm tube over 5-89 deg), so ``a = s / M`` with ``M`` taken
    mid-range over the lamps that the picture allows. Two measures bound the lamp from
    above only: partial reflections let the contents be seen beyond the principal rays
    (``v / s >= F / M``), and blur widens the band (``w / s >= W / M``, 5 % slack). The
    half-range of ``M`` over the allowed lamps, over sqrt(3) (uniform), is the uncertainty.
    An exact solve of ``v / s = F / M`` read the bore 2.3 % wide on the optical renderer's
    25 deg lamp: the partial reflections widen ``v`` by 15 %.
    """
    nan = float("nan")
    t = lamp_table(outer_over_inner, n_glass=n_glass)
    ok = np.isfinite(t.band_mid) & (t.beta_deg >= LAMP_RANGE_DEG[0]) & (t.beta_deg <= LAMP_RANGE_DEG[1])
    if not ok.any() or not (stripe_mid > 0):
        return nan, nan, nan
    mid = t.band_mid[ok]
    allowed = np.ones(int(ok.sum()), bool)
    if visible_half > 0:
        allowed &= (t.visible_fraction[ok] / mid) <= visible_half / stripe_mid + 0.01
    if math.isfinite(stripe_width) and stripe_width > 0:
        allowed &= (t.band_width[ok] / mid) <= stripe_width / stripe_mid * 1.05
    if not allowed.any():
        allowed[:] = True
    lo, hi = float(mid[allowed].min()), float(mid[allowed].max())
    m = 0.5 * (lo + hi)
    return float(t.beta_deg[ok][allowed].max()), float(stripe_mid / m), float((hi - lo) / (2 * m) / math.sqrt(3))


@dataclass(frozen=True)
class BoreEstimate:
    """The bore's width in pixels from the tube model, and how sure it is.

    Attributes
    ----------
    diameter_px : float
        The chosen estimate of the bore's true width.
    method : str
        Which estimate was chosen: ``"outer and stripe"`` (their mean), ``"outer"``,
        ``"stripe + outer"``, ``"stripe"`` or ``"contents"``.
    estimates_px : dict
        Every estimate that could be made, by method.
    agreement : float
        Largest relative difference between the chosen estimate and the other
        independent ones (NaN when there is no other).
    rel_sd : float
        Relative standard uncertainty of the chosen estimate.
    visible_fraction : float
        Share of the bore over which the contents are seen (``2 v`` over the
        chosen width).
    warnings : tuple of str
        What is doubtful, with the fix.
    lamp_half_angle_deg : float
        The largest back-light half-angle the picture allows (NaN when not
        back-lit or not found): an upper bound, indicative only.
    """

    diameter_px: float
    method: str
    estimates_px: dict[str, float] = field(default_factory=dict)
    agreement: float = float("nan")
    rel_sd: float = float("nan")
    visible_fraction: float = float("nan")
    warnings: tuple[str, ...] = ()
    lamp_half_angle_deg: float = float("nan")

    def as_dict(self) -> dict[str, object]:
        return {"diameter_px": self.diameter_px, "method": self.method, "estimates_px": dict(self.estimates_px),
                "agreement": self.agreement, "rel_sd": self.rel_sd, "visible_fraction": self.visible_fraction,
                "warnings": list(self.warnings), "lamp_half_angle_deg": self.lamp_half_angle_deg}


def bore_from_model(walls: WallMeasure, *, visible_diameter_px: float, back_lit: bool, inner_diameter_mm: float,
                    outer_diameter_mm: float | None = None,
                    n_glass: float = BOROSILICATE_INDEX) -> BoreEstimate:
    """Independent estimates of the bore's width in pixels, the best of them, and their agreement.

    Parameters
    ----------
    walls : WallMeasure
        What :func:`measure_walls` found.
    visible_diameter_px : float
        Width over which the contents are seen to change.
    back_lit : bool
        The tube is seen against a lamp (the background is brighter than the bore).
    inner_diameter_mm : float
        The bore's diameter.
    outer_diameter_mm : float, optional
        The tube's outer diameter (glass tubing is sold by both).
    n_glass : float
        The glass's refractive index.

    Returns
    -------
    BoreEstimate

    Notes
    -----
    Preference: with the outer diameter given, the inverse-variance mean of the outer
    silhouette and the stripes (``outer and stripe``: two independent measures, neither
    trusted over the other), else ``outer`` > ``stripe + outer`` > ``stripe`` >
    ``contents``. In back light ``contents`` is only a lower bound and is used
    alone with a warning. The uncertainty of a single estimate is its model's:
    0.5 px on each silhouette edge, ``STRIPE_CENTROID_PX`` on the stripes' separation
    and the lamp's range with 0.5 % (the glass's index) for the stripe with the outer
    silhouette, 2 % more for the stripe alone (index and wall thickness),
    ``CONTENTS_EDGE_PX`` and 1 % for the contents' width, and in back light
    ``BACK_LIT_CONTENTS_SD`` more (the lamp's narrowing, one-sided). The edge and
    centroid floors were calibrated on a sweep of an independent renderer
    (``benchmarks/intervals.py``, docs/accuracy.md "Intervals on a sweep").
    """
    est: dict[str, float] = {}
    sd: dict[str, float] = {}
    o, s, v, w = walls.outer_half_px, walls.stripe_half_px, 0.5 * visible_diameter_px, walls.stripe_width_px
    q_known = outer_diameter_mm / inner_diameter_mm if outer_diameter_mm else None
    beta = float("nan")
    if q_known and math.isfinite(o):
        est["outer"] = 2 * o / q_known
        sd["outer"] = math.hypot(0.5 / o, 0.003)
    if back_lit and math.isfinite(s):
        if q_known:
            beta, a, u = solve_lamp(v, s, w, outer_over_inner=q_known, n_glass=n_glass)
            if math.isfinite(a):
                est["stripe"] = 2 * a
                sd["stripe"] = math.hypot(u, 0.005, STRIPE_CENTROID_PX / (2 * s))
        elif math.isfinite(o) and 0 < s < o:
            def mismatch(q: float) -> float:
                _, a_q, _ = solve_lamp(v, s, w, outer_over_inner=q, n_glass=n_glass)
                return o / a_q - q if math.isfinite(a_q) else float("nan")
            qs = np.arange(1.3, 3.01, 0.1)
            ms = np.array([mismatch(float(q)) for q in qs])
            sign = np.flatnonzero(np.isfinite(ms[:-1]) & np.isfinite(ms[1:]) & (np.sign(ms[:-1]) != np.sign(ms[1:])))
            if len(sign):
                i = int(sign[0])
                q = float(bisect(mismatch, qs[i], qs[i + 1], xtol=1e-4))
                beta, a, u = solve_lamp(v, s, w, outer_over_inner=q, n_glass=n_glass)
                est["stripe + outer"] = 2 * a
                sd["stripe + outer"] = math.hypot(u, 0.005, STRIPE_CENTROID_PX / (2 * s))
        if "stripe" not in est and "stripe + outer" not in est:
            beta, a, u = solve_lamp(v, s, w, outer_over_inner=TYPICAL_OUTER_OVER_INNER, n_glass=n_glass)
            if math.isfinite(a):
                est["stripe"] = 2 * a
                # and the wall's thickness assumed
                sd["stripe"] = math.hypot(u, 0.02, STRIPE_CENTROID_PX / (2 * s))
    if math.isfinite(v) and v > 0:
        est["contents"] = 2 * v
        sd["contents"] = math.hypot(CONTENTS_EDGE_PX / (2 * v), 0.01)
        if back_lit:  # only a lower bound: the lamp's size, which nothing here measures, narrows it
            sd["contents"] = math.hypot(sd["contents"], BACK_LIT_CONTENTS_SD)
    warnings: list[str] = []
    if back_lit and "contents" in est:
        # the contents cannot be seen wider than the bore: an estimate below that is a misread wall
        for m in [m for m in est if m != "contents" and est[m] < 0.97 * est["contents"]]:
            warnings.append(f"the {m} estimate of the bore ({est.pop(m):.1f} px) is narrower than the contents "
                            f"({est['contents']:.1f} px) and was set aside")
    if q_known and "outer" in est and "stripe" in est:
        # two independent measures of the same bore (the silhouette's edges; the stripes through the glass with
        # the wall's thickness known): their inverse-variance mean, neither preferred a priori — on renderers of
        # different optics the silhouette read 1.4 % narrow or 4.7 % wide, the stripes within 1 %
        w_o, w_s = sd["outer"] ** -2, sd["stripe"] ** -2
        est["outer and stripe"] = (w_o * est["outer"] + w_s * est["stripe"]) / (w_o + w_s)
        sd["outer and stripe"] = (w_o + w_s) ** -0.5
    order = (("outer and stripe", "outer", "stripe + outer", "stripe", "contents") if back_lit
             else ("contents", "outer"))
    method = next((m for m in order if m in est), None)
    if method is None:
        return BoreEstimate(float("nan"), "none", est, warnings=("the tube's bore could not be measured",))
    chosen = est[method]
    # independent pairs: the stripe-based estimates share the stripe, the outer-based ones the silhouette;
    # in back light the contents are only a lower bound
    families = {"outer": "silhouette", "stripe + outer": "stripe", "stripe": "stripe", "contents": "contents"}
    if method == "outer and stripe":  # the combination's check is its two parts' agreement
        others = [est["outer"]]
        chosen_for_agreement = est["stripe"]
    else:
        others = [est[m] for m in est if m in families and families[m] != families[method]
                  and not (back_lit and m == "contents")]
        chosen_for_agreement = chosen
    agreement = max((abs(e / chosen_for_agreement - 1) for e in others), default=float("nan"))
    rel_sd = sd[method]
    if math.isfinite(agreement):
        rel_sd = max(rel_sd, agreement / 2)
    frac = v * 2 / chosen if chosen > 0 else float("nan")
    return BoreEstimate(float(chosen), method, est, float(agreement), float(rel_sd), float(frac), tuple(warnings),
                        beta)
