"""Calibration images seen through a lens that distorts, and graph paper and rulers with their hierarchy of lines.

Independent of grainplug (it imports nothing from it): each sub-pixel's ray is cast from a pinhole
camera onto a printed plane tilted in space, as in ``calibration_optics.py``, but through a lens whose
distortion is a *division model* about a centre that may be off the image's centre,

    ray direction = (p - c) / (1 - kappa * (|p - c| / R)^2),

with ``R`` the distance from ``c`` to the farthest corner of the frame. The distortion is given as
optics states it: ``distortion`` = (r_image - r_pinhole) / r_pinhole at that corner, negative for barrel
(the corners pulled in), positive for pincushion. grainplug fits another form (a polynomial about the
image's centre), so this renderer does not share its model.

Patterns (reflectance 0.9 paper):

- ``checkerboard``, ``dots``: as in calibration_optics;
- ``graph``: thin lines every ``pitch`` (``thin_width_mm`` wide, ``thin_contrast`` darker than the paper),
  bold lines every 5 pitches and bolder ones every 10 (``bold_ink``);
- ``ruler``: ticks every pitch, longer every 5 and 10, along the ruler's lower edge, over a grey bench.

The truth is the exact back-projection's derivative (central differences) at any pixel, so the scale
can be checked where the pattern's centre lands and along any line (the tube's axis).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage


@dataclass(frozen=True)
class LensCamera:
    """A pinhole camera with a distorting lens, looking along +Z at a plane; image x right, y down (px)."""

    shape: tuple[int, int]
    mm_per_px: float
    distance_mm: float = 300.0
    roll_deg: float = 0.0
    tilt_deg: float = 0.0
    tilt_axis_deg: float = 0.0
    distortion: float = 0.0
    centre_offset_px: tuple[float, float] = (0.0, 0.0)

    @property
    def focal_px(self) -> float:
        return self.distance_mm / self.mm_per_px

    def _frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        r, t, a = (math.radians(self.roll_deg), math.radians(self.tilt_deg), math.radians(self.tilt_axis_deg))
        e1 = np.array([math.cos(r), -math.sin(r), 0.0])
        e2 = np.array([math.sin(r), math.cos(r), 0.0])
        # tilt by t about an axis in the image plane at angle a from x
        k = np.array([math.cos(a), math.sin(a), 0.0])
        K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        rot = np.eye(3) + math.sin(t) * K + (1 - math.cos(t)) * K @ K
        e1, e2 = rot @ e1, rot @ e2
        return e1, e2, np.cross(e1, e2)

    def _kappa(self) -> tuple[float, np.ndarray, float]:
        h, w = self.shape
        c = np.array([(w - 1) / 2 + self.centre_offset_px[0], (h - 1) / 2 + self.centre_offset_px[1]])
        corners = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [-0.5, h - 0.5], [w - 0.5, h - 0.5]])
        R = float(np.max(np.hypot(*(corners - c).T)))
        # r_pinhole = r / (1 - kappa) at the corner; distortion = r / r_pinhole - 1 = -kappa
        return -self.distortion, c, R

    def plane_coords(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Plane coordinates (mm, relative to the point seen at the image's centre) of the rays through pixels."""
        kappa, c, R = self._kappa()
        h, w = self.shape
        u, v = x - c[0], y - c[1]
        g = 1.0 / (1.0 - kappa * (u**2 + v**2) / R**2)
        u, v = u * g + c[0] - (w - 1) / 2, v * g + c[1] - (h - 1) / 2
        e1, e2, n = self._frame()
        f = self.focal_px
        origin = np.array([0.0, 0.0, self.distance_mm])
        d = np.stack([u / f, v / f, np.ones_like(u)], axis=-1)
        t = (n @ origin) / (d @ n)
        p = d * t[..., None] - origin
        return p @ e1, p @ e2

    def jacobian(self, x: float, y: float, step: float = 1e-3) -> np.ndarray:
        """d(plane X, Y mm)/d(image x, y px) at a pixel: the true scale there in every direction."""
        cols = []
        for dx, dy in ((step, 0.0), (0.0, step)):
            a = self.plane_coords(np.array([x + dx]), np.array([y + dy]))
            b = self.plane_coords(np.array([x - dx]), np.array([y - dy]))
            cols.append([(a[0][0] - b[0][0]) / (2 * step), (a[1][0] - b[1][0]) / (2 * step)])
        return np.array(cols).T

    def scale_along(self, x: float, y: float, direction: tuple[float, float]) -> float:
        """True mm per px at a pixel along an image direction."""
        u = np.asarray(direction, float) / math.hypot(*direction)
        return float(np.hypot(*(self.jacobian(x, y) @ u)))

    def mm_between(self, a: tuple[float, float], b: tuple[float, float]) -> float:
        """True distance (mm) on the plane between the points seen at pixels a and b."""
        X, Y = self.plane_coords(np.array([a[0], b[0]], float), np.array([a[1], b[1]], float))
        return float(math.hypot(X[1] - X[0], Y[1] - Y[0]))


def reflectance(X: np.ndarray, Y: np.ndarray, *, pattern: str, pitch_mm: float, n: tuple[int, int],
                thin_contrast: float = 0.3, thin_width_mm: float = 0.1, bold_ink: float = 0.3,
                bold_width_mm: float = 0.25, ten_width_mm: float = 0.35, five: bool = True) -> np.ndarray:
    """The printed card's reflectance at plane points (X, Y mm from the pattern's centre)."""
    u, v = X / pitch_mm, Y / pitch_mm
    paper = 0.9
    inside = (np.abs(u) < n[0] / 2) & (np.abs(v) < n[1] / 2)
    if pattern == "checkerboard":
        ink = inside & ((np.floor(u + n[0] / 2) + np.floor(v + n[1] / 2)) % 2 == 0)
        return np.where(ink, 0.08, paper)
    if pattern == "dots":
        su, sv = u + (n[0] - 1) / 2, v + (n[1] - 1) / 2
        iu, iv = np.round(su), np.round(sv)
        ok = (iu >= 0) & (iu <= n[0] - 1) & (iv >= 0) & (iv <= n[1] - 1)
        return np.where(ok & ((su - iu) ** 2 + (sv - iv) ** 2 < 0.3**2), 0.08, paper)
    if pattern == "graph":
        out = np.full(X.shape, paper)

        def near(w: np.ndarray, every: int, width_mm: float) -> np.ndarray:
            return np.abs(w / every - np.round(w / every)) * every * pitch_mm < width_mm / 2

        thin = near(u, 1, thin_width_mm) | near(v, 1, thin_width_mm)
        out = np.where(inside & thin, paper - thin_contrast, out)
        if five:
            bold = near(u, 5, bold_width_mm) | near(v, 5, bold_width_mm)
            out = np.where(inside & bold, bold_ink, out)
        ten = near(u, 10, ten_width_mm) | near(v, 10, ten_width_mm)
        out = np.where(inside & ten, bold_ink - 0.1, out)
        return np.where(inside, out, 0.45)  # the card on a grey bench
    if pattern == "ruler":  # along X; ticks hang from the upper edge (v = -n[1]/2)
        k = np.round(u)
        length = np.where(k % 10 == 0, 0.5, np.where(k % 5 == 0, 0.35, 0.22)) * n[1]
        tick = (np.abs(u - k) * pitch_mm < thin_width_mm / 2 + 0.01) & (v < -n[1] / 2 + length)
        edge = np.abs(v + n[1] / 2) * pitch_mm < 0.08
        ink = inside & (tick | edge)
        return np.where(inside, np.where(ink, 0.1, 0.85), 0.3)
    raise ValueError(pattern)


def render(*, pattern: str = "checkerboard", pitch_mm: float = 2.0, n: tuple[int, int] = (12, 9),
           mm_per_px: float = 0.1, shape: tuple[int, int] = (480, 640), distortion: float = 0.0,
           centre_offset_px: tuple[float, float] = (0.0, 0.0), roll_deg: float = 0.0, tilt_deg: float = 0.0,
           tilt_axis_deg: float = 0.0, distance_mm: float = 300.0, blur_px: float = 0.7, noise: float = 0.01,
           ss: int = 3, rng: np.random.Generator, **ink: float) -> tuple[np.ndarray, LensCamera]:
    """An 8-bit image of the pattern through the lens, and the camera (for the truth at any pixel)."""
    cam = LensCamera(shape, mm_per_px, distance_mm=distance_mm, roll_deg=roll_deg, tilt_deg=tilt_deg,
                     tilt_axis_deg=tilt_axis_deg, distortion=distortion, centre_offset_px=centre_offset_px)
    h, w = shape
    offs = (np.arange(ss) + 0.5) / ss - 0.5
    img = np.zeros(shape)
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    for dy in offs:
        for dx in offs:
            X, Y = cam.plane_coords(x + dx, y + dy)
            img += reflectance(X, Y, pattern=pattern, pitch_mm=pitch_mm, n=n, **ink)
    img /= ss * ss
    if blur_px > 0:
        img = ndimage.gaussian_filter(img, blur_px)
    img = img * 0.9 * 255 + rng.normal(0.0, noise * 255, shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8), cam
