"""The tube's refraction formulas against a second method: rays traced step by step with vector Snell's law."""

from __future__ import annotations

import numpy as np
import pytest

from grainplug.calibration.refraction import (
    deflection_deg,
    lamp_table,
    radius_ratio_from_stripe,
    stripe_radius,
    visible_fraction,
)


def _trace(x: float, a: float, b: float, n: float) -> float:
    """Deflection (deg, positive away from the axis) of the ray leaving the camera at ``x``: a 2-D march
    through the circles r = b and r = a, refracting where Snell allows and reflecting where it does not."""
    p = np.array([x, -4.0 * b])
    d = np.array([0.0, 1.0])
    index = {"out": 1.0, "glass": n, "bore": 1.0}
    medium = "out"
    for _ in range(10):
        hits = []
        for r in (a, b):
            bb = p @ d
            c = p @ p - r * r
            disc = bb * bb - c
            if disc <= 0:
                continue
            for t in (-bb - np.sqrt(disc), -bb + np.sqrt(disc)):
                if t > 1e-12:
                    hits.append((t, r))
        if not hits:
            break
        t, r = min(hits)
        p = p + t * d
        normal = p / np.linalg.norm(p)
        outward = normal @ d > 0
        if r == b:
            nxt = "out" if (medium == "glass" and outward) else "glass"
        else:
            nxt = "glass" if medium == "bore" else "bore"
        nrm = -normal if outward else normal  # against the ray
        eta = index[medium] / index[nxt]
        cosi = -(nrm @ d)
        k = 1 - eta * eta * (1 - cosi * cosi)
        if k < 0:  # total internal reflection
            d = d + 2 * cosi * nrm
        else:
            d = eta * d + (eta * cosi - np.sqrt(k)) * nrm
            medium = nxt
        if medium == "out":
            break
    return float(np.degrees(np.arctan2(d[0], d[1])) * np.sign(x))


@pytest.mark.parametrize(("a", "b", "n"), [(1.5, 2.75, 1.47), (1.5, 2.5, 1.52), (1.0, 3.0, 1.46), (2.0, 2.6, 1.47)])
def test_the_closed_form_deflection_equals_a_step_by_step_trace(a, b, n):
    xs = np.concatenate([np.linspace(0.01, b * 0.999, 60), [a * 0.999, a * 1.001, n * a * 0.999, n * a * 1.001]])
    xs = xs[xs < b]
    for x in xs:
        assert deflection_deg(x, inner_radius=a, outer_radius=b, n_glass=n) == pytest.approx(
            _trace(x, a, b, n), abs=1e-6)


def test_a_glass_only_ray_is_bent_like_through_a_solid_rod():
    a, b, n = 1.0, 3.0, 1.5
    x = np.linspace(n * a + 0.01, b * 0.999, 20)
    theta1, theta2 = np.arcsin(x / b), np.arcsin(x / (n * b))
    np.testing.assert_allclose(deflection_deg(x, inner_radius=a, outer_radius=b, n_glass=n),
                               -np.degrees(2 * (theta1 - theta2)), atol=1e-9)


def test_deflection_is_odd_in_x_and_undefined_outside_the_tube():
    d = deflection_deg(np.array([-1.2, 1.2, 0.0, 3.0]), inner_radius=1.5, outer_radius=2.75)
    assert d[0] == pytest.approx(-d[1]) and d[2] == 0 and np.isnan(d[3])


def test_the_stripe_lies_where_totally_reflected_rays_go_straight_on():
    a, b, n = 1.5, 2.75, 1.47
    x0 = stripe_radius(inner_radius=a, outer_radius=b, n_glass=n)
    assert a < x0 < n * a
    assert _trace(x0, a, b, n) == pytest.approx(0.0, abs=1e-6)
    # its position in bore radii hardly depends on the wall's thickness (1.37-1.43 for OD/ID 1.67-2.33)
    ks = [stripe_radius(inner_radius=1.0, outer_radius=q, n_glass=n) for q in (5 / 3, 2.0, 7 / 3)]
    assert 1.36 < min(ks) and max(ks) < 1.44 and ks == sorted(ks)
    # and the outer/inner ratio is read back from it
    assert radius_ratio_from_stripe(x0 / b, n_glass=n) == pytest.approx(a / b, rel=1e-6)


def test_the_visible_share_of_a_back_lit_bore_grows_with_the_lamp():
    # the figures of issue 16 for a 3/5.5 mm tube, n = 1.47 (an independent ray trace, not ours)
    expected = {15: 0.65, 20: 0.75, 25: 0.82, 30: 0.87, 35: 0.91, 50: 0.97}
    for beta, share in expected.items():
        assert visible_fraction(beta, inner_radius=1.5, outer_radius=2.75) == pytest.approx(share, abs=0.012)
    assert visible_fraction(80, inner_radius=1.5, outer_radius=2.75) == 1.0


def test_the_lamp_table_agrees_with_the_direct_functions():
    t = lamp_table(2.75 / 1.5, beta_deg=np.array([15.0, 25.0, 35.0]))
    for beta, f in zip(t.beta_deg, t.visible_fraction, strict=True):
        assert f == pytest.approx(visible_fraction(beta, inner_radius=1.0, outer_radius=2.75 / 1.5), abs=2e-3)
    # the bright band straddles the stripe, and the wall rays at its ends leave at the lamp's edge
    x0 = stripe_radius(inner_radius=1.0, outer_radius=2.75 / 1.5)
    for beta, mid, w in zip(t.beta_deg, t.band_mid, t.band_width, strict=True):
        lo, hi = mid - w / 2, mid + w / 2
        assert lo < x0 < hi
        for edge in (lo, hi):
            assert abs(_trace(edge * 1.5, 1.5, 2.75, 1.47)) == pytest.approx(beta, abs=0.5)
