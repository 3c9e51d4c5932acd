"""How a thick-walled glass tube bends the rays that cross it (2-D cross-section).

The camera looks at the tube from far away, perpendicular to its axis. A ray that
leaves the camera at a distance ``x`` from the axis (measured in the tube's plane)
crosses the outer wall (radius ``b``), the glass (index ``n``) and, if it gets
there, the bore (radius ``a``, air). These functions give where it goes; the tube
model (:mod:`grainplug.calibration.tube_model`) uses them to turn what a back-lit
tube looks like into the bore's width in pixels.

Notes
-----
At a circular interface centred on the axis, Snell's law conserves ``n p``, the
ray's index times its distance of closest approach to the axis ``p``. The ray
leaving the camera at ``x`` therefore has ``p = x`` in air and ``p = x / n`` in
the glass, which sorts the rays into three zones:

* ``|x| < a``: the ray enters the bore; its chord through the bore lies at
  distance ``x`` from the axis, as if there were no glass (the bore is not
  magnified in outline);
* ``a < |x| < n a``: the ray meets the inner wall beyond the critical angle and
  is totally reflected;
* ``n a < |x| < b``: the ray crosses glass only.

The ray's direction after the tube follows from the polar angle ``phi`` that its
path sweeps from far away to its closest approach (half the path, by symmetry):
a straight segment of closest approach ``p`` sweeps ``arccos(p / r)`` from radius
``r`` to its closest point, so

.. math::

    \\phi = \\tfrac{\\pi}{2} - \\arccos\\tfrac{x}{b} + \\arccos\\tfrac{x}{n b}
            - \\arccos\\tfrac{x}{n a} + \\left[\\arccos\\tfrac{x}{a}\\right]_{|x| < a}

(the last term only for rays that enter the bore; a totally reflected ray turns
at ``r = a``; a glass-only ray keeps the first three terms). The deflection is
``theta = pi - 2 phi``: positive away from the axis (the bore is a diverging
lens), negative towards it (the glass is a converging one); a solid rod gives
the classic ``-2 (theta_1 - theta_2)``, ``sin theta_1 = x / b``,
``sin theta_2 = x / (n b)``.

In back light (a diffuse lamp of angular half-size ``beta`` behind the tube) a
ray shows the lamp when ``|theta| < beta`` and the dark room otherwise. Near the
axis the bore shows the lamp; towards its wall the rays leave at up to ~70 deg
and the bore looks dark, so only its central part is seen (about 65 % of its
width at ``beta = 15 deg``, 97 % at 50 deg for a 3/5.5 mm tube). Inside the zone
of total reflection the deflection changes sign: around that zero, whatever the
lamp's size, the wall shows a bright stripe. Its position ``x0`` depends only on
``a``, ``b`` and ``n`` (``x0 / a`` = 1.37-1.43 for outer/inner diameters of
1.67-2.33 at n = 1.47): it ties the picture to the bore's size without knowing
the lamp.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: refractive index of borosilicate glass (Duran, Pyrex) at visible wavelengths
BOROSILICATE_INDEX = 1.47


def bisect(f: Callable[[float], float], lo: float, hi: float, *, xtol: float = 1e-12) -> float:
    """A root of ``f`` between ``lo`` and ``hi`` (where ``f`` changes sign), by bisection.

    (scipy.optimize would do, but importing it costs a quarter of a second per run.)
    """
    f_lo = f(lo)
    for _ in range(200):
        if hi - lo <= xtol:
            break
        mid = 0.5 * (lo + hi)
        f_mid = f(mid)
        if (f_mid > 0) == (f_lo > 0):
            lo, f_lo = mid, f_mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def deflection_deg(x: np.ndarray | float, *, inner_radius: float, outer_radius: float,
                   n_glass: float = BOROSILICATE_INDEX) -> np.ndarray:
    """Deflection (degrees) of the ray that leaves the camera at ``x`` from the axis.

    Parameters
    ----------
    x : array_like
        Distance of the camera ray from the tube's axis (any length unit).
    inner_radius, outer_radius : float
        The bore's and the tube's radii (same unit as ``x``).
    n_glass : float
        Refractive index of the glass (the bore and the room are air).

    Returns
    -------
    ndarray
        Deflection in degrees: positive away from the axis, negative towards it;
        NaN outside the tube (``|x| >= outer_radius``).

    Notes
    -----
    Only the principal path (refraction where possible, total reflection where
    not) is followed; partial (Fresnel) reflections are left out. See the module's
    notes for the formula.
    """
    a, b, n = float(inner_radius), float(outer_radius), float(n_glass)
    if not 0 < a < b or n <= 1:
        raise ValueError(f"need 0 < inner radius < outer radius and n > 1, got {a}, {b}, {n}")
    u = np.abs(np.asarray(x, dtype=float))
    inside = u < b
    uc = np.where(inside, u, 0.0)
    phi = 0.5 * np.pi - np.arccos(uc / b) + np.arccos(uc / (n * b))
    reach_inner = uc < n * a
    phi = phi - np.where(reach_inner, np.arccos(np.minimum(uc / (n * a), 1.0)), 0.0)
    in_bore = uc < a
    phi = phi + np.where(in_bore, np.arccos(np.minimum(uc / a, 1.0)), 0.0)
    theta = np.degrees(np.pi - 2 * phi) * np.sign(np.asarray(x, dtype=float) + 0.0)
    theta = np.where(np.asarray(x, dtype=float) == 0, 0.0, theta)
    return np.where(inside, theta, np.nan)


def stripe_radius(*, inner_radius: float, outer_radius: float, n_glass: float = BOROSILICATE_INDEX) -> float:
    """Distance from the axis of the bright stripe: where the totally reflected rays go straight on.

    Parameters
    ----------
    inner_radius, outer_radius : float
        The bore's and the tube's radii.
    n_glass : float
        Refractive index of the glass.

    Returns
    -------
    float
        ``x0`` in ``(a, min(n a, b))`` where the deflection is zero, in the radii's
        unit; NaN when the deflection does not change sign there (a wall so thin
        that ``n a >= b`` and the glass-only zone is missing is still handled).
    """
    a, b, n = float(inner_radius), float(outer_radius), float(n_glass)
    hi = min(n * a, b) * (1 - 1e-9)
    lo = a * (1 + 1e-9)

    def f(x: float) -> float:
        return float(deflection_deg(x, inner_radius=a, outer_radius=b, n_glass=n))

    if not f(lo) > 0 > f(hi):
        return float("nan")
    return float(bisect(f, lo, hi, xtol=1e-12 * b))


def visible_fraction(beta_deg: float, *, inner_radius: float, outer_radius: float,
                     n_glass: float = BOROSILICATE_INDEX) -> float:
    """Share of the bore's width that shows a back-light of angular half-size ``beta_deg``.

    The deflection grows monotonically from the axis to the bore's wall; the bore
    shows the lamp where it is below ``beta``.
    """
    a, b, n = float(inner_radius), float(outer_radius), float(n_glass)
    edge = float(deflection_deg(a * (1 - 1e-12), inner_radius=a, outer_radius=b, n_glass=n))
    if beta_deg >= edge:
        return 1.0
    x = bisect(lambda u: float(deflection_deg(u, inner_radius=a, outer_radius=b, n_glass=n)) - beta_deg,
               0.0, a * (1 - 1e-12), xtol=1e-12 * a)
    return float(x / a)


def radius_ratio_from_stripe(stripe_over_outer: float, *, n_glass: float = BOROSILICATE_INDEX) -> float:
    """Inner/outer radius ratio ``a / b`` of a tube whose stripe lies at ``stripe_over_outer`` of its outer radius.

    Parameters
    ----------
    stripe_over_outer : float
        Measured ``x0 / b``.
    n_glass : float
        Refractive index of the glass.

    Returns
    -------
    float
        ``a / b``; NaN when no tube of ratio 0.2-0.95 has its stripe there.

    Notes
    -----
    ``x0 / b`` grows monotonically with ``a / b`` (slope ~1.2 near ``a / b = 0.55``),
    so a measured stripe position fixes the ratio well.
    """
    def g(ratio: float) -> float:
        return stripe_radius(inner_radius=ratio, outer_radius=1.0, n_glass=n_glass) - stripe_over_outer

    lo, hi = 0.2, 0.95
    try:
        glo, ghi = g(lo), g(hi)
    except ValueError:
        return float("nan")
    if not (np.isfinite(glo) and np.isfinite(ghi)) or glo * ghi > 0:
        return float("nan")
    return float(bisect(g, lo, hi, xtol=1e-10))


@dataclass(frozen=True)
class LampTable:
    """What a back-lit tube of given shape shows, for a range of lamp sizes (lengths in bore radii).

    Attributes
    ----------
    beta_deg : ndarray
        Lamp half-angles.
    visible_fraction : ndarray
        Share of the bore's width that shows the lamp (:func:`visible_fraction`).
    band_mid : ndarray
        Middle of the bright band in the wall (the stripe, or for large lamps the
        band that reaches out into the glass-only zone), in units of the inner
        radius; NaN where the wall shows no lamp.
    band_width : ndarray
        Its width, in inner radii.
    """

    beta_deg: np.ndarray
    visible_fraction: np.ndarray
    band_mid: np.ndarray
    band_width: np.ndarray


def lamp_table(outer_over_inner: float, *, n_glass: float = BOROSILICATE_INDEX,
               beta_deg: np.ndarray | None = None, samples: int = 1500) -> LampTable:
    """Visible bore and bright wall band of a back-lit tube, for every lamp half-angle in ``beta_deg``.

    Parameters
    ----------
    outer_over_inner : float
        ``b / a`` (= OD / ID).
    n_glass : float
        Refractive index of the glass.
    beta_deg : ndarray, optional
        Lamp half-angles (default 2-89 deg by 0.5 deg).
    samples : int
        Points across the wall at which the deflection is evaluated.

    Returns
    -------
    LampTable

    Notes
    -----
    The bright band is the connected set of wall rays (``a < |x| < b``) with
    ``|theta| < beta`` that contains the stripe's zero of deflection; a uniform
    lamp makes it uniformly bright, so its centroid is its middle.
    """
    betas = np.arange(2.0, 89.01, 0.5) if beta_deg is None else np.asarray(beta_deg, dtype=float)
    b = float(outer_over_inner)
    x = 1.0 + (b - 1.0) * (np.arange(samples) + 0.5) / samples
    d = deflection_deg(x, inner_radius=1.0, outer_radius=b, n_glass=n_glass)
    x0 = stripe_radius(inner_radius=1.0, outer_radius=b, n_glass=n_glass)
    core = np.abs(d)[None, :] < betas[:, None]
    mid = np.full(len(betas), np.nan)
    width = np.full(len(betas), np.nan)
    if np.isfinite(x0):
        k0 = min(max(int(np.searchsorted(x, x0)), 0), samples - 1)
        dark_in = ~core[:, : k0 + 1][:, ::-1]  # from the stripe's zero inwards
        dark_out = ~core[:, k0:]  # and outwards
        lo = np.where(dark_in.any(axis=1), k0 - dark_in.argmax(axis=1) + 1, 0)
        hi = np.where(dark_out.any(axis=1), k0 + dark_out.argmax(axis=1) - 1, samples - 1)
        lit = core[:, k0]
        half = 0.5 * (b - 1.0) / samples
        x_lo, x_hi = x[np.clip(lo, 0, samples - 1)] - half, x[np.clip(hi, 0, samples - 1)] + half
        mid = np.where(lit, 0.5 * (x_lo + x_hi), np.nan)
        width = np.where(lit, x_hi - x_lo, np.nan)
    xin = (np.arange(samples) + 0.5) / samples
    din = deflection_deg(xin, inner_radius=1.0, outer_radius=b, n_glass=n_glass)
    frac = np.interp(betas, np.maximum.accumulate(din), xin, left=0.0, right=1.0)
    frac = np.where(betas >= din[-1], 1.0, frac)
    return LampTable(betas, frac, mid, width)
