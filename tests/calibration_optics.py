"""Calibration images rendered by casting rays from a pinhole camera onto a printed plane.

Independent of grainplug's calibration code and of the images it was developed on
(those used a planar warp with a linear denominator): here each sub-pixel's ray is
intersected with a plane tilted in space, so perspective, roll and off-centre patterns
come from the geometry. The ground truth (mm per pixel at the pixel where the pattern's
centre lands) is the central difference of that same back-projection.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage


@dataclass(frozen=True)
class Truth:
    """Exact scale where the pattern's centre lands: ``jacobian`` = d(plane X, Y mm)/d(image x, y px)."""

    jacobian: np.ndarray
    centre_px: tuple[float, float]

    @property
    def mm_per_px(self) -> float:
        return float(math.sqrt(abs(np.linalg.det(self.jacobian))))

    @property
    def mm_per_px_x(self) -> float:
        return float(np.hypot(*self.jacobian[:, 0]))

    @property
    def mm_per_px_y(self) -> float:
        return float(np.hypot(*self.jacobian[:, 1]))


class Camera:
    """A pinhole camera looking along +Z at a plane; image x right, y down, in pixels."""

    def __init__(self, shape: tuple[int, int], *, mm_per_px: float, distance_mm: float, roll_deg: float,
                 tilt_deg: float, centre_px: tuple[float, float] | None, distortion: float = 0.0) -> None:
        self.h, self.w = shape
        self.k1 = distortion  # radial lens distortion: ray = pixel * (1 + k1 r^2), r in half-diagonals
        self.cx, self.cy = (self.w - 1) / 2, (self.h - 1) / 2
        self.f = distance_mm / mm_per_px
        r, t = math.radians(roll_deg), math.radians(tilt_deg)
        # plane axes: rolled in the image (counter-clockwise on screen: y is down), then tilted about x
        e1 = np.array([math.cos(r), -math.sin(r), 0.0])
        e2 = np.array([math.sin(r), math.cos(r), 0.0])
        tilt = np.array([[1, 0, 0], [0, math.cos(t), -math.sin(t)], [0, math.sin(t), math.cos(t)]])
        self.e1, self.e2 = tilt @ e1, tilt @ e2
        self.n = np.cross(self.e1, self.e2)
        px = centre_px if centre_px is not None else (self.cx, self.cy)
        ray = np.array([(px[0] - self.cx) / self.f, (px[1] - self.cy) / self.f, 1.0])
        self.origin = ray * distance_mm  # the pattern's centre, in space
        self.centre_px = (float(px[0]), float(px[1]))

    def plane_coords(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Plane coordinates (mm) seen by the rays through image points ``(x, y)``."""
        u, v = x - self.cx, y - self.cy
        if self.k1:  # barrel (k1 > 0: the edges see more of the plane per pixel) or pincushion
            g = 1 + self.k1 * (u**2 + v**2) / (self.cx**2 + self.cy**2)
            u, v = u * g, v * g
        d = np.stack([u / self.f, v / self.f, np.ones_like(x)], axis=-1)
        t = (self.n @ self.origin) / (d @ self.n)
        p = d * t[..., None] - self.origin
        return p @ self.e1, p @ self.e2

    def truth(self, step: float = 1e-3) -> Truth:
        x0, y0 = self.centre_px
        cols = []
        for dx, dy in ((step, 0.0), (0.0, step)):
            a = self.plane_coords(np.array([x0 + dx]), np.array([y0 + dy]))
            b = self.plane_coords(np.array([x0 - dx]), np.array([y0 - dy]))
            cols.append([(a[0][0] - b[0][0]) / (2 * step), (a[1][0] - b[1][0]) / (2 * step)])
        return Truth(np.array(cols).T, self.centre_px)


def reflectance(X: np.ndarray, Y: np.ndarray, *, pattern: str, pitch_mm: float, n: tuple[int, int]) -> np.ndarray:
    """Printed card: 0.08 (ink) to 0.9 (paper); a board of n squares or a grid of n dots, centred."""
    u, v = X / pitch_mm, Y / pitch_mm
    if pattern == "checkerboard":
        inside = (np.abs(u) < n[0] / 2) & (np.abs(v) < n[1] / 2)
        ink = inside & ((np.floor(u + n[0] / 2) + np.floor(v + n[1] / 2)) % 2 == 0)
    elif pattern == "graph":  # printed graph paper: thin lines every pitch, thicker ones every 10 pitches
        inside = (np.abs(u) < n[0] / 2) & (np.abs(v) < n[1] / 2)
        du, dv = np.abs(u - np.round(u)), np.abs(v - np.round(v))
        du10, dv10 = np.abs(u / 10 - np.round(u / 10)) * 10, np.abs(v / 10 - np.round(v / 10)) * 10
        ink = inside & ((du < 0.06) | (dv < 0.06) | (du10 < 0.12) | (dv10 < 0.12))
        return np.where(ink, 0.35, 0.9)  # pale ink, as on real graph paper
    elif pattern == "ruler":  # a white ruler along X: ticks every pitch, longer every 5 and 10, an edge
        inside = (np.abs(u) < n[0] / 2) & (v > -n[1] / 2) & (v < n[1] / 2)
        k = np.round(u)
        length = np.where(k % 10 == 0, 0.45, np.where(k % 5 == 0, 0.32, 0.22)) * n[1]
        tick = (np.abs(u - k) < 0.07) & (v > n[1] / 2 - length)
        edge = np.abs(v - n[1] / 2) < 0.05
        ink = inside & (tick | edge)
        return np.where(inside, np.where(ink, 0.08, 0.85), 0.3)  # the ruler over a grey bench
    else:
        su, sv = u + (n[0] - 1) / 2, v + (n[1] - 1) / 2  # dot i at su == i, for i in 0 .. n - 1
        iu, iv = np.round(su), np.round(sv)
        inside = (iu >= 0) & (iu <= n[0] - 1) & (iv >= 0) & (iv <= n[1] - 1)
        ink = inside & ((su - iu) ** 2 + (sv - iv) ** 2 < 0.3**2)
    return np.where(ink, 0.08, 0.9)


def render(*, pattern: str = "checkerboard", pitch_mm: float = 2.0, n: tuple[int, int] = (10, 8),
           mm_per_px: float = 0.05, shape: tuple[int, int] = (480, 640), roll_deg: float = 0.0,
           tilt_deg: float = 0.0, centre_px: tuple[float, float] | None = None, distance_mm: float = 300.0,
           blur_px: float = 0.8, noise: float = 0.01, bit_depth: int = 8, occlusion: float = 0.0,
           vignetting: float = 0.0, distortion: float = 0.0, ss: int = 4,
           rng: np.random.Generator) -> tuple[np.ndarray, Truth]:
    """An image of the pattern and the exact scale where its centre lands."""
    cam = Camera(shape, mm_per_px=mm_per_px, distance_mm=distance_mm, roll_deg=roll_deg, tilt_deg=tilt_deg,
                 centre_px=centre_px, distortion=distortion)
    h, w = shape
    offs = (np.arange(ss) + 0.5) / ss - 0.5
    img = np.zeros(shape)
    for dy in offs:
        for dx in offs:
            y, x = np.mgrid[0:h, 0:w].astype(np.float64)
            X, Y = cam.plane_coords(x + dx, y + dy)
            img += reflectance(X, Y, pattern=pattern, pitch_mm=pitch_mm, n=n)
    img /= ss * ss
    if occlusion > 0:  # an opaque dark bar across part of the pattern (a finger, the tube's holder)
        y, x = np.mgrid[0:h, 0:w]
        x0 = cam.centre_px[0] + 0.25 * n[0] * pitch_mm / mm_per_px * (1 - 2 * occlusion)
        img[(x > x0) & (np.abs(y - cam.centre_px[1]) < 0.6 * n[1] * pitch_mm / mm_per_px)] = 0.03
    if vignetting > 0:
        y, x = np.mgrid[0:h, 0:w]
        r2 = ((x - w / 2) ** 2 + (y - h / 2) ** 2) / (w**2 / 4 + h**2 / 4)
        img *= 1 - vignetting * r2
    if blur_px > 0:
        img = ndimage.gaussian_filter(img, blur_px)
    top = 2**bit_depth - 1
    img = img * 0.9 * top + rng.normal(0.0, noise * top, shape)
    img = np.clip(np.round(img), 0, top).astype(np.uint8 if bit_depth == 8 else np.uint16)
    return img, cam.truth()


#: hard but realistic cases: name -> keyword arguments of :func:`render`
CASES = {
    "square-on board": {},
    "rolled 25 deg": {"roll_deg": 25.0},
    "rolled -40 deg, 12-bit": {"roll_deg": -40.0, "bit_depth": 12},
    "tilted 10 deg": {"tilt_deg": 10.0, "distance_mm": 150.0},
    "tilted 10 deg, rolled, off-centre": {"tilt_deg": 10.0, "roll_deg": 12.0, "centre_px": (220.0, 260.0),
                                          "distance_mm": 150.0},
    "blurred and noisy": {"blur_px": 1.5, "noise": 0.03},
    "occluded 20 %": {"occlusion": 0.2},
    "vignetted": {"vignetting": 0.5},
    "large squares": {"mm_per_px": 0.04, "pitch_mm": 2.5, "n": (7, 5)},
    "dot grid": {"pattern": "dots", "n": (11, 8)},
    "dot grid rolled and tilted": {"pattern": "dots", "n": (11, 8), "roll_deg": -15.0, "tilt_deg": 8.0,
                                   "distance_mm": 150.0},
    "narrow strip": {"shape": (200, 1000), "n": (20, 3), "mm_per_px": 0.04},
    # a lens's radial distortion (the scale at the corners 3 % or 8 % off the centre's)
    "barrel distortion 3 %": {"n": (12, 9), "distortion": 0.03},
    "pincushion distortion 8 %, dots": {"pattern": "dots", "n": (12, 9), "distortion": -0.08},
}

#: graph paper (1 mm lines, thicker every 10) and rulers (1 mm ticks, longer every 5 and 10, on a bench)
GRATING_CASES = {
    "graph paper": {"pattern": "graph", "pitch_mm": 1.0, "n": (40, 30), "mm_per_px": 0.06},
    "graph paper rolled, tilted, blurred": {"pattern": "graph", "pitch_mm": 1.0, "n": (40, 30), "mm_per_px": 0.06,
                                            "roll_deg": 17.0, "tilt_deg": 8.0, "distance_mm": 200.0,
                                            "blur_px": 1.5, "noise": 0.03},
    "graph paper occluded": {"pattern": "graph", "pitch_mm": 1.0, "n": (40, 30), "mm_per_px": 0.06,
                             "occlusion": 0.2},
    "ruler": {"pattern": "ruler", "pitch_mm": 1.0, "n": (60, 8), "mm_per_px": 0.1},
    "ruler rolled -30 deg, blurred": {"pattern": "ruler", "pitch_mm": 1.0, "n": (60, 8), "mm_per_px": 0.1,
                                      "roll_deg": -30.0, "blur_px": 1.2, "noise": 0.02},
    "ruler tilted 10 deg, 12-bit, vignetted": {"pattern": "ruler", "pitch_mm": 1.0, "n": (60, 8),
                                               "mm_per_px": 0.1, "tilt_deg": 10.0, "distance_mm": 150.0,
                                               "bit_depth": 12, "vignetting": 0.3},
    "ruler, 5 px per mm, in a strip": {"pattern": "ruler", "pitch_mm": 1.0, "n": (100, 8), "mm_per_px": 0.2,
                                       "shape": (300, 800), "roll_deg": 3.0},
}
