"""A lens's radial distortion and the map from image pixels to the calibration pattern's plane.

A camera that sees a flat pattern through a lens maps each pixel ``p`` to the pattern's plane in two
steps: the lens's radial distortion is undone about its centre ``c``,

    q = c + (p - c) (1 + k1 rho^2 + k2 rho^4),      rho = |p - c| / R,

(``R`` the distance from ``c`` to the frame's corner, so that ``k1`` and ``k2`` do not depend on the
image's size; ``k1 > 0`` is barrel distortion: the frame's corners see farther out than a pinhole
would), then a homography takes the ideal pixel ``q`` to the plane (mm). This is OpenCV's camera
model (``cv2.calibrateCamera`` with k1, k2 and no tangential terms) written from the image to the
plane rather than the other way, with the radius in units of the frame's half diagonal instead of
the focal length (which one view of a flat pattern does not fix): OpenCV's ``k1`` is this one
times ``(f / R)^2`` with the opposite sign, to first order.

The centre ``c`` is the frame's centre: for one view of a flat pattern a shift of the centre is,
to first order, a change of perspective, which the homography takes up (both give the same map
over the pattern, which is what the scale needs).

Two fits are offered, both least squares (``scipy.optimize.least_squares``):

- :func:`fit_points`: to points whose plane positions are known (a checkerboard's corners, a dot
  grid's centres), residuals in pixels;
- :func:`fit_gradients`: to the local spatial frequencies of line gratings (graph paper, a ruler),
  which are the rows of the map's derivative (the lines' positions are known only up to a
  translation, which a derivative does not see).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PlaneMap:
    """Image pixels to the pattern's plane: radial undistortion, then a homography.

    Attributes
    ----------
    homography : ndarray, (3, 3)
        From the plane (mm) to ideal (undistorted) pixels.
    k1, k2 : float
        Radial distortion coefficients (see the module's docstring; 0 for a pinhole).
    centre : tuple of float
        The distortion's centre ``(x, y)`` in px.
    radius : float
        The radius (px) of ``rho = 1``: the distance from the centre to the frame's corner.
    """

    homography: np.ndarray
    k1: float = 0.0
    k2: float = 0.0
    centre: tuple[float, float] = (0.0, 0.0)
    radius: float = 1.0

    @property
    def inverse(self) -> np.ndarray:
        """The homography from ideal pixels to the plane."""
        return np.linalg.inv(self.homography)

    def undistort(self, p: np.ndarray) -> np.ndarray:
        """Ideal pixels ``q`` of image points ``p`` (N, 2)."""
        p = np.asarray(p, float).reshape(-1, 2)
        d = (p - np.asarray(self.centre)) / self.radius
        r2 = np.sum(d * d, axis=1, keepdims=True)
        return np.asarray(self.centre) + d * self.radius * (1 + self.k1 * r2 + self.k2 * r2 * r2)

    def distort(self, q: np.ndarray) -> np.ndarray:
        """Image points of ideal pixels ``q`` (N, 2): the inverse of :meth:`undistort` (Newton on the radius)."""
        q = np.asarray(q, float).reshape(-1, 2)
        c = np.asarray(self.centre)
        dq = (q - c) / self.radius
        rq = np.hypot(dq[:, 0], dq[:, 1])
        r = rq.copy()
        for _ in range(30):
            f = r * (1 + self.k1 * r**2 + self.k2 * r**4) - rq
            df = 1 + 3 * self.k1 * r**2 + 5 * self.k2 * r**4
            step = f / np.where(np.abs(df) > 1e-9, df, 1e-9)
            r = r - step
            if np.all(np.abs(step) < 1e-12):
                break
        ratio = np.where(rq > 0, r / np.where(rq > 0, rq, 1.0), 1.0)
        return c + dq * ratio[:, None] * self.radius

    def undistort_jacobian(self, p: np.ndarray) -> np.ndarray:
        """dq/dp at image points (N, 2, 2)."""
        p = np.asarray(p, float).reshape(-1, 2)
        d = p - np.asarray(self.centre)
        r2 = np.sum(d * d, axis=1) / self.radius**2
        s = 1 + self.k1 * r2 + self.k2 * r2 * r2
        g = (2 * self.k1 + 4 * self.k2 * r2) / self.radius**2
        return s[:, None, None] * np.eye(2) + g[:, None, None] * d[:, :, None] * d[:, None, :]

    def to_plane(self, p: np.ndarray) -> np.ndarray:
        """Plane coordinates (mm) of image points (N, 2)."""
        q = self.undistort(p)
        h = np.column_stack([q, np.ones(len(q))]) @ self.inverse.T
        return h[:, :2] / h[:, 2:]

    def to_image(self, w: np.ndarray) -> np.ndarray:
        """Image points of plane points (N, 2)."""
        w = np.asarray(w, float).reshape(-1, 2)
        h = np.column_stack([w, np.ones(len(w))]) @ np.asarray(self.homography).T
        return self.distort(h[:, :2] / h[:, 2:])

    def jacobian(self, p: np.ndarray) -> np.ndarray:
        """d(plane mm)/d(image px) at image points (N, 2, 2)."""
        p = np.asarray(p, float).reshape(-1, 2)
        return homography_jacobian(self.inverse, self.undistort(p)) @ self.undistort_jacobian(p)

    def scale(self, p: np.ndarray) -> np.ndarray:
        """The local scale ``sqrt|det J|`` (mm per px) at image points (N,)."""
        return np.sqrt(np.abs(np.linalg.det(self.jacobian(p))))

    def scale_along(self, p: np.ndarray, direction_xy: tuple[float, float]) -> np.ndarray:
        """mm per px along an image direction at image points (N,)."""
        u = np.asarray(direction_xy, float)
        u = u / np.hypot(*u)
        return np.hypot(*(self.jacobian(p) @ u).T)


def homography_jacobian(G: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The derivative of the homography ``G`` at points ``q`` (N, 2, 2)."""
    q = np.asarray(q, float).reshape(-1, 2)
    qh = np.column_stack([q, np.ones(len(q))])
    num = qh @ G[:2].T  # (N, 2)
    den = qh @ G[2]  # (N,)
    return (G[:2, :2][None] * den[:, None, None] - num[:, :, None] * G[2, :2][None, None, :]) / den[:, None, None] ** 2


def frame_centre_and_radius(shape: tuple[int, int]) -> tuple[tuple[float, float], float]:
    """The distortion's centre (the frame's centre) and the radius of its corners, px."""
    h, w = shape
    return ((w - 1) / 2.0, (h - 1) / 2.0), math.hypot(w / 2.0, h / 2.0)


@dataclass(frozen=True)
class Fit:
    """A fitted :class:`PlaneMap`, its residuals and what is needed for the uncertainty of what it gives.

    Attributes
    ----------
    plane_map : PlaneMap
    rms : float
        Root mean square residual (px for points; relative frequency for gradients).
    params : ndarray
        The fitted parameters.
    cov : ndarray
        Their covariance (from the residuals' scatter).
    build : callable
        ``build(params) -> PlaneMap``, to propagate the covariance to any quantity.
    """

    plane_map: PlaneMap
    rms: float
    params: np.ndarray
    cov: np.ndarray
    build: object

    def rel_sd_of(self, quantity) -> float:
        """Relative standard deviation of ``quantity(plane_map) -> float`` from the parameters' covariance."""
        base = float(quantity(self.plane_map))
        grad = np.zeros(len(self.params))
        for i in range(len(self.params)):
            h = 1e-6 * max(1.0, abs(float(self.params[i])))
            up = self.params.copy()
            up[i] += h
            grad[i] = (float(quantity(self.build(up))) - base) / h
        var = float(grad @ self.cov @ grad)
        return math.sqrt(max(var, 0.0)) / abs(base) if base else math.inf


def _covariance(res, n_obs: int) -> np.ndarray:
    J = res.jac
    dof = max(n_obs - J.shape[1], 1)
    sigma2 = float(res.fun @ res.fun) / dof
    return sigma2 * np.linalg.pinv(J.T @ J, rcond=1e-10)


def fit_points(world: np.ndarray, image_pts: np.ndarray, *, shape: tuple[int, int],
               distortion: bool = True) -> Fit:
    """The map from the image to the plane that best puts the points where they were found.

    Parameters
    ----------
    world : ndarray, (N, 2)
        The points' plane positions (mm).
    image_pts : ndarray, (N, 2)
        Where they were found in the image (px).
    shape : (int, int)
        The image's ``(height, width)`` (the distortion's centre and radius).
    distortion : bool
        Fit k1 and k2 (else a pinhole: a homography alone).

    Returns
    -------
    Fit
        ``rms`` in px: the points' distance from where the fitted map puts them.
    """
    import cv2
    from scipy.optimize import least_squares

    world = np.asarray(world, float)
    pts = np.asarray(image_pts, float)
    centre, radius = frame_centre_and_radius(shape)
    c = np.asarray(centre)
    wm = world.mean(axis=0)
    ws = float(np.sqrt(np.mean(np.sum((world - wm) ** 2, axis=1)))) or 1.0
    T = np.array([[1 / ws, 0, -wm[0] / ws], [0, 1 / ws, -wm[1] / ws], [0, 0, 1]])  # world -> normalised
    N = np.array([[radius, 0, c[0]], [0, radius, c[1]], [0, 0, 1]])  # normalised ideal -> ideal px
    wn = (world - wm) / ws
    pn = (pts - c) / radius
    H0, _ = cv2.findHomography(wn, pn, 0)
    if H0 is None or not np.all(np.isfinite(H0)) or abs(H0[2, 2]) < 1e-12:
        H0 = np.eye(3)
    H0 = H0 / H0[2, 2]
    n_k = 2 if distortion else 0

    def build(theta: np.ndarray) -> PlaneMap:
        Hn = np.append(theta[:8], 1.0).reshape(3, 3)
        k = np.concatenate([theta[8:], np.zeros(2 - n_k)])
        return PlaneMap(N @ Hn @ T, float(k[0]), float(k[1]), centre, radius)

    whn = np.column_stack([wn, np.ones(len(wn))])
    r2 = np.sum(pn * pn, axis=1, keepdims=True)

    def residuals(theta: np.ndarray) -> np.ndarray:
        Hn = np.append(theta[:8], 1.0).reshape(3, 3)
        h = whn @ Hn.T
        proj = h[:, :2] / h[:, 2:]
        q = pn * (1 + (theta[8] * r2 + theta[9] * r2 * r2 if n_k else 0.0))
        return ((q - proj) * radius).ravel()

    theta0 = np.concatenate([H0.ravel()[:8], np.zeros(n_k)])
    res = least_squares(residuals, theta0, method="lm", x_scale="jac")
    pm = build(res.x)
    rms = float(np.sqrt(np.mean(np.sum((pm.to_image(world) - pts) ** 2, axis=1))))
    return Fit(pm, rms, res.x, _covariance(res, res.fun.size), build)


def fit_gradients(centres: np.ndarray, rows: np.ndarray, *, shape: tuple[int, int], weights: np.ndarray | None = None,
                  ruler: bool = False, distortion: bool = True) -> Fit:
    """The map whose derivative best matches the measured local frequencies of line gratings.

    A family of lines ``X = const`` (``X`` in line periods) has, at image point ``p``, the spatial
    frequency vector ``grad X(p)``: the first row of the map's derivative (the second family's,
    the second row). The homography is fitted with its translation fixed (the plane's origin at
    the frame's centre: a derivative does not see where the lines are).

    Parameters
    ----------
    centres : ndarray, (n, 2)
        Where each frequency was measured (px).
    rows : ndarray, (n, 2 * families)
        The families' frequency vectors there (cycles/px), end to end.
    shape : (int, int)
        The image's ``(height, width)``.
    weights : ndarray, (n,), optional
        How much each measure counts (the lines' share of its part).
    ruler : bool
        One family (a ruler's ticks): the other axis is taken square to it and the perspective
        along the ruler only.
    distortion : bool
        Fit k1 and k2.

    Returns
    -------
    Fit
        ``rms``: the frequencies' relative scatter about the fitted map; the map's plane unit is
        one period of the lines.
    """
    from scipy.optimize import least_squares

    centres = np.asarray(centres, float).reshape(-1, 2)
    rows = np.asarray(rows, float).reshape(len(centres), -1)
    w = np.ones(len(centres)) if weights is None else np.asarray(weights, float)
    w = np.sqrt(w / w.max())
    centre, radius = frame_centre_and_radius(shape)
    c = np.asarray(centre)
    N = np.array([[1 / radius, 0, -c[0] / radius], [0, 1 / radius, -c[1] / radius], [0, 0, 1]])  # ideal px -> q'
    f0 = float(np.median(np.hypot(rows[:, 0], rows[:, 1])))
    n_k = 2 if distortion else 0
    if ruler:
        m0 = np.median(rows[:, :2], axis=0) * radius
        u = m0 / np.hypot(*m0)
        theta0 = np.concatenate([m0, [0.0], np.zeros(n_k)])
    else:
        M0 = np.median(rows, axis=0).reshape(2, 2) * radius
        theta0 = np.concatenate([M0.ravel(), [0.0, 0.0], np.zeros(n_k)])

    def build(theta: np.ndarray) -> PlaneMap:
        if ruler:
            m1 = theta[:2]
            G = np.array([[m1[0], m1[1], 0.0], [-m1[1], m1[0], 0.0], [theta[2] * u[0], theta[2] * u[1], 1.0]])
            k = theta[3:]
        else:
            G = np.array([[theta[0], theta[1], 0.0], [theta[2], theta[3], 0.0], [theta[4], theta[5], 1.0]])
            k = theta[6:]
        k = np.concatenate([k, np.zeros(2 - len(k))])
        Gp = G @ N  # ideal px -> plane (periods)
        return PlaneMap(np.linalg.inv(Gp), float(k[0]), float(k[1]), centre, radius)

    def residuals(theta: np.ndarray) -> np.ndarray:
        J = build(theta).jacobian(centres)  # (n, 2, 2)
        model = J[:, 0, :] if ruler else J.reshape(len(centres), 4)
        return ((model - rows[:, : model.shape[1]]) / f0 * w[:, None]).ravel()

    res = least_squares(residuals, theta0, method="lm", x_scale="jac")
    pm = build(res.x)
    rms = float(np.sqrt(np.mean(res.fun**2)))
    return Fit(pm, rms, res.x, _covariance(res, res.fun.size), build)
