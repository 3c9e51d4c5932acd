"""The scale from a calibration image: a checkerboard or a dot grid held at the tube's plane.

The pattern's points are found (a checkerboard's inner corners: scikit-image's
Harris peaks refined to sub-pixel saddle points; or the dots' centroids), indexed on
their lattice by growing from the centre (so that neither the board's size nor a
hidden part of it needs to be known), then a plane-to-image homography is fitted to
them by least squares (OpenCV). Its local derivative gives the mm per
pixel along the image's axes at the pattern's centre, the spread of that derivative
over the pattern says how much the scale varies over the field by perspective, and the
fit's residuals give the scale's uncertainty. The lens's radial distortion (k1, k2 about
the frame's centre) is fitted with the homography (:mod:`grainplug.calibration.distortion`),
so that the scale is known anywhere in the frame (:meth:`Calibration.scale_at`); what
remains is measured between each point's lattice neighbours (a smooth surface fitted to
the measured scale over the map's) and corrects the scale at the centre (docs/calibration.md,
"Lens distortion"). Graph paper and rulers: :func:`_grating`.
"""

from __future__ import annotations

import dataclasses
import itertools
import logging
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import GrainplugError
from ..warning_codes import CODES, coded
from .distortion import PlaneMap, fit_points, frame_centre_and_radius

log = logging.getLogger(__name__)

#: version of the calibration.json layout
CALIBRATION_FORMAT = 1
#: the scale may vary over the pattern by this much before a warning
SCALE_VARIATION_WARN = 0.005
PATTERNS = ("auto", "checkerboard", "dots", "graph", "ruler")
#: in auto mode, a lattice whose x and y scales differ by this share or more is not taken (a misread lattice)
ASPECT_LIMIT_AUTO = 0.1
#: with the pattern named, pixels this far from square are still refused (a lattice read wrongly)
ASPECT_LIMIT_NAMED = 0.5


class CalibrationError(GrainplugError):
    """The calibration image holds no usable pattern."""


@dataclass(frozen=True)
class Calibration:
    """What a calibration image says about the scale.

    Attributes
    ----------
    mm_per_px : float
        Scale at the pattern's centre (geometric mean of the two axes).
    mm_per_px_x, mm_per_px_y : float
        mm spanned by one pixel along the image's columns (x) and rows (y).
    jacobian_mm_per_px : tuple of tuple of float
        Local derivative of plane position (mm) with respect to image position (px)
        at the pattern's centre, ``[[dX/dx, dX/dy], [dY/dx, dY/dy]]``: the mm per
        pixel in any direction of the image.
    rel_sd : float
        Relative standard uncertainty of ``mm_per_px`` from the fit's residuals.
    tilt_deg : float
        Angle of the pattern's rows (or columns, whichever is nearer) to the image's rows,
        degrees in [-45, 45), counter-clockwise positive.
    scale_variation : float
        (max - min) / mean of the local scale over the pattern: perspective or lens
        distortion. Above 0.5 % a warning says so.
    rms_residual_px : float
        Root mean square distance between the points found and the fitted homography
        (0 for graph paper and rulers, measured from their lines' frequency, not points).
    n_points : int
        Points used in the fit.
    pattern : str
        ``"checkerboard"``, ``"dots"``, ``"graph"`` (graph paper) or ``"ruler"``.
    pitch_mm : float
        Distance between neighbouring points on the pattern, as given.
    image_shape : tuple of int
        ``(height, width)`` of the calibration image.
    centre_px : tuple of float
        Where in the image the pattern's centre is (x, y).
    homography : tuple of tuple of float
        3 x 3 map from the pattern's plane (mm) to the image (px).
    image : dict
        Identity of the calibration image (name, size in bytes, sha256).
    warnings : tuple of str
        What is doubtful, each with the fix.
    points_px : tuple of (float, float)
        The pattern's points found in the image (x, y), for drawing them over it.
    source : str
        The calibration file this was read from (absolute path, set by
        :func:`grainplug.load_calibration`), for the analysis's provenance; empty when made
        in memory. Not written into the calibration file, and not compared.
    distortion_k1, distortion_k2 : float
        The lens's radial distortion fitted with the map (0 for a pinhole, and in files written
        before it was fitted): an image point ``p`` is seen where a pinhole would put
        ``c + (p - c)(1 + k1 rho^2 + k2 rho^4)``, ``rho = |p - c| / distortion_radius_px``
        (:mod:`grainplug.calibration.distortion`); ``homography`` then maps the plane to those
        undistorted pixels. ``k1 > 0`` is barrel distortion.
    distortion_centre_px : tuple of float or None
        The distortion's centre ``c`` (x, y), the frame's centre; None in files written before the
        distortion was fitted.
    distortion_radius_px : float
        The radius of ``rho = 1``: from the centre to the frame's corner (0 when not fitted).
    levels : tuple of int
        Graph paper and rulers: every how many finest lines (ticks) a bolder (longer) one was seen,
        e.g. ``(5, 10)``; empty for checkerboards and dot grids.
    """

    mm_per_px: float
    mm_per_px_x: float
    mm_per_px_y: float
    jacobian_mm_per_px: tuple[tuple[float, float], tuple[float, float]]
    rel_sd: float
    tilt_deg: float
    scale_variation: float
    rms_residual_px: float
    n_points: int
    pattern: str
    pitch_mm: float
    image_shape: tuple[int, int]
    centre_px: tuple[float, float]
    homography: tuple[tuple[float, ...], ...]
    image: dict[str, object] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()
    points_px: tuple[tuple[float, float], ...] = ()
    source: str = field(default="", compare=False)
    distortion_k1: float = 0.0
    distortion_k2: float = 0.0
    distortion_centre_px: tuple[float, float] | None = None
    distortion_radius_px: float = 0.0
    levels: tuple[int, ...] = ()

    def mm_per_px_along(self, direction_xy: tuple[float, float]) -> float:
        """mm per pixel along an image direction ``(dx, dy)`` (e.g. the tube's axis)."""
        u = np.asarray(direction_xy, float)
        u = u / np.hypot(*u)
        return float(np.hypot(*(np.asarray(self.jacobian_mm_per_px) @ u)))

    def plane_map(self) -> PlaneMap:
        """The map from the calibration image's pixels to the pattern's plane (mm): the lens's distortion undone,
        then the homography (:class:`grainplug.calibration.distortion.PlaneMap`)."""
        centre = self.distortion_centre_px or (0.0, 0.0)
        return PlaneMap(np.asarray(self.homography, float), float(self.distortion_k1), float(self.distortion_k2),
                        (float(centre[0]), float(centre[1])), float(self.distortion_radius_px) or 1.0)

    @property
    def corner_distortion(self) -> float:
        """The lens's distortion at the frame's corners as optics states it: (r_image - r_pinhole) / r_pinhole,
        negative for barrel, positive for pincushion (0 when none was fitted)."""
        return 1.0 / (1.0 + self.distortion_k1 + self.distortion_k2) - 1.0

    def scale_at(self, x_px: float | np.ndarray, y_px: float | np.ndarray,
                 direction_xy: tuple[float, float]) -> float | np.ndarray:
        """mm per pixel along an image direction at image points, through the lens's distortion and perspective.

        Equal to :meth:`mm_per_px_along` at the pattern's centre; elsewhere that value times the fitted map's
        change of scale between the centre and the point (a ruler: along its length, pixels taken as square).

        Parameters
        ----------
        x_px, y_px : float or ndarray
            Image points (px), in the calibration image's frame.
        direction_xy : (float, float)
            The direction ``(dx, dy)`` (e.g. the tube's axis).

        Returns
        -------
        float or ndarray
            mm per px at each point (a float for scalar coordinates).
        """
        x, y = np.broadcast_arrays(np.asarray(x_px, float), np.asarray(y_px, float))
        pm = self.plane_map()
        pts = np.column_stack([x.ravel(), y.ravel()])
        local = pm.scale_along(pts, direction_xy)
        at_centre = float(pm.scale_along(np.asarray([self.centre_px], float), direction_xy)[0])
        out = (self.mm_per_px_along(direction_xy) * local / at_centre).reshape(x.shape)
        return float(out) if out.ndim == 0 else out

    def plane_mm(self, points_px: np.ndarray) -> np.ndarray:
        """Where image points (N, 2) lie on the pattern's plane (mm), through the distortion and the homography,
        rescaled so that the map's scale at the pattern's centre is :attr:`mm_per_px`."""
        pm = self.plane_map()
        at_centre = float(pm.scale(np.asarray([self.centre_px], float))[0])
        return pm.to_plane(np.asarray(points_px, float).reshape(-1, 2)) * (self.mm_per_px / at_centre)

    def as_dict(self) -> dict[str, object]:
        """JSON-ready, with the layout's version."""
        d = dataclasses.asdict(self)
        d.pop("source")  # where a file is, is not in it
        d["warning_codes"] = [getattr(w, "code", None) for w in self.warnings]
        return {"format": "grainplug-calibration", "version": CALIBRATION_FORMAT, **d}

    @classmethod
    def from_dict(cls, data: dict[str, object]) -> Calibration:
        """The calibration written by :meth:`as_dict`.

        Raises
        ------
        CalibrationError
            When ``data`` is not a calibration of a layout this version reads.
        """
        if data.get("format") != "grainplug-calibration":
            raise CalibrationError("this JSON is not a grainplug calibration — make one with `grainplug calibrate`")
        if data.get("version") != CALIBRATION_FORMAT:
            raise CalibrationError(f"calibration layout version {data.get('version')} is not "
                                   f"{CALIBRATION_FORMAT} — redo it with this grainplug (`grainplug calibrate`)")
        names = {f.name for f in dataclasses.fields(cls)}
        try:
            kw = {k: v for k, v in data.items() if k in names}
            kw["jacobian_mm_per_px"] = tuple(tuple(float(x) for x in row) for row in kw["jacobian_mm_per_px"])
            kw["homography"] = tuple(tuple(float(x) for x in row) for row in kw["homography"])
            kw["image_shape"] = tuple(int(x) for x in kw["image_shape"])
            kw["centre_px"] = tuple(float(x) for x in kw["centre_px"])
            codes = list(data.get("warning_codes") or [])
            kw["warnings"] = tuple(coded(c, w) if isinstance(c, str) and c in CODES else w
                                   for w, c in itertools.zip_longest(kw.get("warnings", ()), codes[:len(
                                       kw.get("warnings", ()))]))
            kw["points_px"] = tuple(tuple(float(x) for x in p) for p in kw.get("points_px", ()))
            if kw.get("distortion_centre_px") is not None:
                kw["distortion_centre_px"] = tuple(float(x) for x in kw["distortion_centre_px"])
            for name in ("distortion_k1", "distortion_k2", "distortion_radius_px"):
                if name in kw:
                    kw[name] = float(kw[name])
            kw["levels"] = tuple(int(x) for x in kw.get("levels", ()))
            cal = cls(**kw)
        except (KeyError, TypeError, ValueError) as exc:
            raise CalibrationError(f"the calibration is incomplete or damaged ({exc}) — redo it with "
                                   "`grainplug calibrate`") from None
        if not (math.isfinite(cal.mm_per_px) and cal.mm_per_px > 0):
            raise CalibrationError(f"the calibration's scale {cal.mm_per_px} mm/px is not a positive number — redo it")
        return cal


def calibrate_image(image: np.ndarray, *, pitch_mm: float, pattern: str = "auto",
                    identity: dict[str, object] | None = None) -> Calibration:
    """The scale from an image of a checkerboard or a dot grid.

    Parameters
    ----------
    image : ndarray, (H, W) or (H, W, 3), uint8 or uint16
        The calibration image.
    pitch_mm : float
        Distance between neighbouring corners (checkerboard: the side of a square),
        dot centres, or the finest lines or ticks (graph paper, ruler: 1 mm), in mm.
    pattern : {"auto", "checkerboard", "dots", "graph", "ruler"}
        Which pattern to look for; ``"auto"`` tries the checkerboard, the dots, then
        line gratings (graph paper if two families of lines are seen, else a ruler).
    identity : dict, optional
        The image's identity (name, size, hash) to keep with the result.

    Returns
    -------
    Calibration

    Raises
    ------
    CalibrationError
        When no pattern of at least 9 points (in 2 rows or more) is found, nor lines
        with the evidence :func:`_grating` asks for (the message says which test failed).

    Notes
    -----
    With ``H`` the homography from plane coordinates ``(X, Y)`` (mm) to image
    coordinates ``(x, y)`` (px), fitted by least squares to the points, the local scale
    at an image point is the inverse of the derivative of ``H`` there:
    ``J = (dH/d(X, Y))^-1`` in mm/px; the reported scale is
    ``sqrt(|det J|)`` at the pattern's centre. Its uncertainty is that of the scale of an
    affine fit to the same points, from the residuals' variance and the points' spread
    (ordinary least squares).
    """
    if pattern not in PATTERNS:
        raise CalibrationError(f"unknown pattern {pattern!r}: choose one of {', '.join(PATTERNS)}")
    if not (math.isfinite(pitch_mm) and pitch_mm > 0):
        raise CalibrationError(f"the pattern's pitch must be a positive length in mm, got {pitch_mm}")
    grey = _grey8(image)
    finders = {"checkerboard": _checkerboard_points, "dots": _dot_points}
    fits, rejected = [], []
    for kind in (("checkerboard", "dots") if pattern == "auto" else (pattern,)):
        if kind not in finders:
            continue
        found = finders[kind](grey)
        if found is None:
            continue
        index, points = found
        if kind == "checkerboard" and not _alternates(grey, index, points):
            # corners on a lattice whose squares are all alike: line crossings (graph paper), not a board
            log.info("a lattice of %d corners whose squares do not alternate: not a checkerboard", len(points))
            if pattern == "checkerboard":
                raise CalibrationError(
                    f"a lattice of {len(points)} corners was found, but its squares are not alternately dark and "
                    "light: it is not a checkerboard (graph paper's crossings?) — name the right pattern "
                    "(--pattern graph) or photograph a checkerboard")
            continue
        cal = _fit(index * pitch_mm, points, pitch_mm=pitch_mm, kind=kind, shape=grey.shape,
                   identity=identity or {})
        # a lattice read wrongly (the corners between dots taken for a board...) is not square
        # (lens distortion bends the lattice by a few per cent of its pitch: allowed, and warned of)
        # (pixels far from square are believed when the pattern is named: auto mode must tell readings apart)
        pitch_px = pitch_mm / cal.mm_per_px
        aspect = round(abs(cal.mm_per_px_x / cal.mm_per_px_y - 1), 6)  # 10 % is 10 %, not 0.0999999
        if aspect < (ASPECT_LIMIT_AUTO if pattern == "auto" else ASPECT_LIMIT_NAMED) \
                and cal.rms_residual_px < max(1.0, 0.06 * pitch_px):
            fits.append(cal)
        else:
            rejected.append(cal)
    if not fits and rejected and (pattern != "auto" or len(rejected[0].points_px) >= 20):
        # a lattice of points was there: reading the image as lines instead would mislead
        cal = rejected[0]
        name = "dot grid" if cal.pattern == "dots" else cal.pattern
        ratio = cal.mm_per_px_x / cal.mm_per_px_y
        if pattern == "auto" and cal.rms_residual_px < max(1.0, 0.06 * pitch_mm / cal.mm_per_px) \
                and abs(ratio - 1) < ASPECT_LIMIT_NAMED:
            raise CalibrationError(
                f"a {name} was found but its {cal.n_points} points make pixels {100 * abs(ratio - 1):.0f} % from "
                f"square (x:y scales {ratio:.3f}) — if the camera's pixels are that shape, name the pattern "
                f"(pattern=\"{cal.pattern}\") to accept it; else check that the pattern is flat and square and the "
                "pitch is right, or give mm_per_px= to the analysis")
        raise CalibrationError(
            f"a {name} was found but its {cal.n_points} points do not fit a flat square pattern "
            f"({cal.rms_residual_px:.1f} px off, x:y scales {ratio:.3f}) — check that the pattern is flat and "
            "square and the pitch is right, or give mm_per_px= to the analysis")
    why = ""
    if not fits and pattern in ("auto", "graph", "ruler"):
        grating = _grating(grey, pitch_mm=pitch_mm, kind=pattern, identity=identity or {})
        if isinstance(grating, Calibration):
            fits.append(grating)
        elif grating:
            why = f" ({grating})"
    if not fits:
        what = {"auto": "checkerboard, dot grid, graph paper or ruler", "checkerboard": "checkerboard",
                "dots": "dot grid", "graph": "graph paper (two families of lines)", "ruler": "ruler's ticks"}[pattern]
        raise CalibrationError(f"no {what} was found in the image{why} — make sure the pattern "
                               "is in focus, evenly lit and fills a good part of the frame")
    # the lattice of most points: a few corners of a dot grid's edges taken for a board lose to its dots (a
    # checkerboard's squares are not taken for dots: a dot must be round); a tie goes to the checkerboard
    return max(fits, key=lambda c: (c.n_points, c.pattern == "checkerboard"))


#: a scale from lines is refused when its relative standard uncertainty exceeds this
GRATING_MAX_REL_SD = 0.01
#: ... or when it varies over the pattern by more than this (perspective of 10 deg: 2-3 %)
GRATING_MAX_VARIATION = 0.25


def _grating(grey: np.ndarray, *, pitch_mm: float, kind: str, identity: dict[str, object]) -> Calibration | str:
    """The scale from line gratings (graph paper, a ruler's ticks); see :mod:`grainplug.calibration.periodic`.

    Lines are believed only on evidence: each family's peak must stand
    ``MIN_PEAK_TO_NOISE`` times above the transform's median at the same spatial
    frequency, span ``MIN_LINES`` lines or more, and the parts of the image (tiles,
    stretches along a ruler) must agree on the spacing about the fitted map (perspective and
    the lens's distortion) within ``MAX_PART_MISFIT_BINS`` of a part's frequency bin; the
    scale's uncertainty and its variation over the pattern must stay under
    ``GRATING_MAX_REL_SD`` and ``GRATING_MAX_VARIATION``. Noise, a movie of the tube, a
    speckled beam or a checkerboard's diagonals pass none or few of these.

    The lines are then read at their finest level (:func:`_grating_levels`): the pitch given is
    that of the finest lines (ticks), which graph paper and rulers mark by bolder (longer) lines
    every 5th or 10th; lines without that hierarchy, or with bolder ones every 2nd only (the 5 mm
    level of graph paper whose 1 mm lines are not seen), are refused.

    Returns
    -------
    Calibration or str
        The calibration, or why the lines were not believed ("" when none were seen at all).
    """
    from .periodic import MIN_LINES, MIN_PEAK_TO_NOISE, Gratings, find_gratings

    found = find_gratings(grey, families=1 if kind == "ruler" else 2)
    if found is None or (kind == "graph" and len(found.freqs) < 2):
        return ""
    graph = len(found.freqs) == 2
    lines = "lines" if graph else "ticks"
    spacing = 1.0 / float(np.hypot(*found.freqs[0]))
    for snr, count in zip(found.peak_to_noise, found.lines, strict=True):
        if snr < MIN_PEAK_TO_NOISE:
            return (f"the strongest repeat, every {spacing:.3g} px, stands only {snr:.0f} times above the image's "
                    f"noise; {lines} stand {MIN_PEAK_TO_NOISE:.0f} times or more")
        if count < MIN_LINES / 2:  # graph paper's bold lines may be found first: MIN_LINES of the finest, below
            return (f"the strongest repeat, every {spacing:.3g} px, makes only {count:.0f} {lines}; "
                    f"at least {MIN_LINES} are needed")
    if graph:  # the second family's axis, oriented so that the map keeps the image's handedness
        f1, f2 = found.freqs
        if f1[0] * f2[1] - f1[1] * f2[0] < 0:
            found = dataclasses.replace(found, freqs=[f1, -f2])
    mapped = _grating_map(grey, found, graph=graph)
    if isinstance(mapped, str):
        return f"the strongest repeat, every {spacing:.3g} px, is not a pattern of {lines}: {mapped}"
    levels = _grating_levels(grey, found, mapped.fold_map, graph=graph)
    if isinstance(levels, str):
        return levels
    finer, phases, bolder = levels
    if min(found.lines) * finer < MIN_LINES:
        return (f"the strongest repeat, every {spacing / finer:.3g} px, makes only {min(found.lines) * finer:.0f} "
                f"{lines}; at least {MIN_LINES} are needed")
    if abs(finer - 1) > 1e-9:  # the finest lines, measured again at their own frequency
        base = mapped.plane_map
        fine = Gratings([np.asarray(f, float) * finer for f in found.freqs], found.support, found.box,
                        found.peak_to_noise, found.lines)
        refined = _grating_map(grey, fine, graph=graph, start=base, factor=finer)
        mapped = refined if not isinstance(refined, str) else _scaled_fit(mapped, finer)
    pm = _whole_image_level(grey, found, mapped, finer=finer, graph=graph)
    y0, y1, x0, x1 = found.box
    centre = np.array([0.5 * (x0 + x1 - 1), 0.5 * (y0 + y1 - 1)])
    J = pitch_mm * pm.jacobian(centre.reshape(1, 2))[0]
    scale = float(math.sqrt(abs(np.linalg.det(J))))
    local = pm.scale(mapped.centres) * pitch_mm if len(mapped.centres) else np.array([scale])
    variation = float((local.max() - local.min()) / local.mean()) if len(local) > 1 else 0.0

    rel_sd = float(math.hypot(mapped.rel_sd, 1e-4))
    H = np.diag([pitch_mm, pitch_mm, 1.0]) @ np.linalg.inv(pm.homography)  # ideal px -> plane mm
    homography = np.linalg.inv(H)
    f1 = J[0] / pitch_mm
    u = f1 / np.hypot(*f1)
    perp = np.array([-u[1], u[0]])
    tilt = math.degrees(math.atan2(-perp[1], perp[0]))  # the lines' direction, as the board's rows
    tilt = (tilt + 45.0) % 90.0 - 45.0
    mm_x, mm_y = float(np.hypot(*J[:, 0])), float(np.hypot(*J[:, 1]))
    points = _grating_points(pm, phases, found.box, graph=graph, support=found.support, centre=centre)
    warnings: list[str] = []
    said = _distortion_warning(pm.k1, pm.k2)
    if said:
        warnings.append(said)
    if not graph:
        warnings.append("a ruler gives the scale along its length only: pixels are taken as square — lay the "
                        "ruler along the tube's axis (or use graph paper or a checkerboard)")
    if rel_sd > GRATING_MAX_REL_SD or variation > GRATING_MAX_VARIATION:
        return (f"the {lines} every {spacing:.3g} px give a scale uncertain by {100 * rel_sd:.2g} % that varies by "
                f"{100 * variation:.2g} % over the image; at most {100 * GRATING_MAX_REL_SD:g} % and "
                f"{100 * GRATING_MAX_VARIATION:g} % are accepted")
    if variation > SCALE_VARIATION_WARN:
        warnings.append(f"the scale varies by {100 * variation:.1f} % over the pattern (perspective or lens "
                        "distortion): hold the pattern square to the camera, at the tube's plane, and use the "
                        "scale where the tube is")
    if graph and abs(mm_x / mm_y - 1) > 0.01:
        warnings.append(f"pixels are not square here ({mm_x:.5g} x {mm_y:.5g} mm): the scale along the tube "
                        "is taken along its axis")
    return Calibration(
        mm_per_px=scale, mm_per_px_x=mm_x, mm_per_px_y=mm_y,
        jacobian_mm_per_px=((float(J[0, 0]), float(J[0, 1])), (float(J[1, 0]), float(J[1, 1]))),
        rel_sd=rel_sd, tilt_deg=float(tilt), scale_variation=variation, rms_residual_px=0.0,
        n_points=len(points), pattern="graph" if graph else "ruler", pitch_mm=float(pitch_mm),
        image_shape=(int(grey.shape[0]), int(grey.shape[1])), centre_px=(float(centre[0]), float(centre[1])),
        homography=tuple(tuple(float(x) for x in row) for row in homography), image=dict(identity),
        warnings=tuple(warnings), points_px=tuple((float(x), float(y)) for x, y in points),
        distortion_k1=float(pm.k1), distortion_k2=float(pm.k2), distortion_centre_px=tuple(pm.centre),
        distortion_radius_px=float(pm.radius), levels=tuple(bolder),
    )


@dataclass(frozen=True)
class _GratingFit:
    """A map fitted to line gratings' local frequencies (plane unit: one period of the lines fitted)."""

    plane_map: PlaneMap
    centres: np.ndarray
    misfit: float
    rel_sd: float
    fold_map: PlaneMap  # with the lens's terms whether or not they are significant: to align the fold


#: the whole image's peak sets the map's level when the lines' frequency spreads over less than this many of its
#: bins (variation x lines): the peak is then the lines' mean frequency, more precise than the parts'
WHOLE_IMAGE_SPREAD_BINS = 0.5


def _whole_image_level(grey: np.ndarray, found, mapped: _GratingFit, *, finer: float, graph: bool) -> PlaneMap:
    """The fitted map, its level set by the whole image's peak when the scale varies little over the lines.

    Each part's peak is pulled a little by the sidebands of the bolder lines every 5th and 10th (a tenth of
    the frequency away, a bin or two in a part); the whole image resolves them. When the frequency spreads
    over less than ``WHOLE_IMAGE_SPREAD_BINS`` of the whole image's bins, its peak is the mean of the map's
    frequency over the lines (weighted as in the transform), and each family's axis of the map is rescaled to
    it: the map keeps its shape (perspective, distortion), the whole image its level. With more spread (a lens
    distorting by a percent or more), the peak is no longer the mean, and the map is kept as fitted.
    """
    from .periodic import _prepare, _refine, _window

    pm = mapped.plane_map
    h, w = grey.shape
    yy, xx = np.mgrid[0:h:4, 0:w:4]
    weight = (_window(grey.shape) * found.support)[::4, ::4]
    keep = weight > 1e-3 * weight.max()
    pts = np.column_stack([xx[keep], yy[keep]]).astype(float)
    wts = weight[keep]
    J = pm.jacobian(pts)  # rows: the families' frequencies (finest periods per px)
    families = 2 if graph else 1
    mags = np.hypot(J[:, :families, 0], J[:, :families, 1])
    spread = float(np.max((mags.max(axis=0) - mags.min(axis=0)) / np.mean(mags, axis=0)))
    log.debug("frequency spread %.3g over %.0f lines", spread, min(found.lines) * finer)
    if spread * min(found.lines) * finer >= WHOLE_IMAGE_SPREAD_BINS:
        return pm
    gw = _prepare(grey) * _window(grey.shape) * found.support
    bin_size = 0.5 / max(grey.shape)
    factors = []
    for k in range(families):
        mean = np.sum(J[:, k, :] * wts[:, None], axis=0) / wts.sum()
        peak = _refine(gw, mean, bin_size)
        factors.append(float(np.hypot(*peak) / np.hypot(*mean)))
    if not graph:
        factors.append(factors[0])
    log.info("the whole image's peak sets the lines' level: %s", [f"{f - 1:+.2e}" for f in factors])
    H = np.asarray(pm.homography) @ np.diag([1.0 / factors[0], 1.0 / factors[1], 1.0])
    return dataclasses.replace(pm, homography=H)


def _scaled_fit(mapped: _GratingFit, factor: float) -> _GratingFit:
    """The same map with its plane unit ``factor`` times finer."""
    pm = mapped.plane_map
    H = np.asarray(pm.homography) @ np.diag([1.0 / factor, 1.0 / factor, 1.0])
    return dataclasses.replace(mapped, plane_map=dataclasses.replace(pm, homography=H))


def _grating_map(grey: np.ndarray, found, *, graph: bool, start: PlaneMap | None = None,
                 factor: float = 1.0) -> _GratingFit | str:
    """The map (perspective and the lens's distortion) whose derivative matches the lines' local frequencies.

    The frequencies are measured in tiles (stretches along a ruler), each started where the map fitted
    so far puts it (``start``, scaled by ``factor``; else the whole image's), twice. Returns why the lines
    are not believed when their parts disagree about the map by more than ``MAX_PART_MISFIT_BINS``.
    """
    from .distortion import fit_gradients
    from .periodic import MAX_PART_MISFIT_BINS, model_misfit, tile_frequencies

    period = 1.0 / float(np.hypot(*found.freqs[0]))
    y0, y1, x0, x1 = found.box
    if graph:
        grid = int(np.clip(min(y1 - y0, x1 - x0) / max(64.0, 10 * period), 3, 6))
    else:
        length = max(y1 - y0, x1 - x0)
        grid = int(np.clip(length / max(48.0, 8 * period), 5, 10))
    shape = grey.shape
    model = start
    mfactor = factor
    fitted = None
    # started from the whole image's frequencies: coarse tiles first, then the grid from the map they give;
    # from a map already fitted: the grid at once
    for tiles in ((grid,) if start is not None else (3 if graph else 5, grid)):
        predict = None
        if model is not None:
            def predict(c: np.ndarray, m: PlaneMap = model, k: float = mfactor) -> np.ndarray:
                J = m.jacobian(np.asarray(c, float).reshape(1, 2))[0] * k
                return J[: 2 if graph else 1]
        centres, freqs, sizes, weights = tile_frequencies(grey, found, grid=tiles, predict=predict)
        n_min = 9 if graph else 6
        distortion = len(centres) >= n_min and _reach(centres, shape) >= MIN_REACH_DISTORTION
        if len(centres) < 4:
            return "it fills too little of the image to be checked"
        try:
            fitted = fit_gradients(centres, freqs, shape=shape, weights=weights, ruler=not graph, distortion=False)
            richest = fitted
            if distortion:  # the lens's terms only when the parts ask for them (an F test), not to fit their noise
                bent = fit_gradients(centres, freqs, shape=shape, weights=weights, ruler=not graph, distortion=True)
                n_obs = len(centres) * (2 if graph else 1) * 2
                rss0, rss1 = fitted.rms**2 * n_obs, bent.rms**2 * n_obs
                dof = max(n_obs - len(bent.params), 1)
                richest = bent
                if rss1 <= 0 or (rss0 - rss1) / 2 / (rss1 / dof) > DISTORTION_F:
                    fitted = bent
        except (np.linalg.LinAlgError, ValueError):
            return "no smooth map of the image fits its parts' spacings"
        model, mfactor = richest.plane_map, 1.0
    # the evidence: the parts agree with the map; a map without the lens's terms that does not fit them gives
    # way to the one with (an F test short of significance does not make a misfitting map right)
    def misfit_of(fit) -> tuple[float, np.ndarray]:
        J = fit.plane_map.jacobian(centres)
        rows = J[:, 0, :] if not graph else J.reshape(len(centres), 4)
        return model_misfit(freqs, rows, sizes, n_params=len(fit.params)), rows

    misfit, rows = misfit_of(fitted)
    if not misfit <= MAX_PART_MISFIT_BINS and richest is not fitted:
        fitted = richest
        misfit, rows = misfit_of(fitted)
    if not misfit <= MAX_PART_MISFIT_BINS:
        if not math.isfinite(misfit):
            return "it fills too little of the image to be checked"
        return (f"its spacing differs between parts of the image by {misfit:.2f} of a frequency bin about the "
                f"best smooth map, lines agree within {MAX_PART_MISFIT_BINS:g}")
    # the scale's uncertainty: the parts' relative scatter about the map, as the standard error of their mean
    families = 2 if graph else 1
    model_mag = np.concatenate([np.hypot(rows[:, 2 * k], rows[:, 2 * k + 1]) for k in range(families)])
    mag = np.concatenate([np.hypot(freqs[:, 2 * k], freqs[:, 2 * k + 1]) for k in range(families)])
    resid = mag / model_mag - 1
    dof = max(len(resid) - len(fitted.params), 1)
    rel_sd = math.sqrt(float(resid @ resid) / dof / len(centres))
    return _GratingFit(fitted.plane_map, centres, misfit, rel_sd, richest.plane_map)


def _grating_levels(grey: np.ndarray, found, pm: PlaneMap, *,
                    graph: bool) -> tuple[float, list[float], list[int]] | str:
    """The lines' hierarchy: how many finest lines per line fitted, where they are, and every how many a bolder one.

    The pattern's whole period is found by phase dispersion
    (:func:`grainplug.calibration.periodic.coarsest_period`), the image folded over it through the fitted
    map (:func:`grainplug.calibration.periodic.fold`), and the fold read by
    :func:`grainplug.calibration.periodic.read_levels`.

    Returns
    -------
    (finer, phases, bolder) or str
        ``finer`` finest lines per period fitted, each family's finest lines' phase (in their own
        periods), the levels of bolder lines among them; or why the lines are refused.
    """
    import cv2

    from .periodic import coarsest_period, fold, read_levels

    h, w = grey.shape
    yy, xx = np.mgrid[0:h, 0:w]
    mask = found.support > 0.5
    period = 1.0 / float(np.hypot(*found.freqs[0]))
    if not graph:  # a ruler's longer ticks reach beyond the band of its shortest ones
        along = max(float(found.lines[0]) * period, 1.0)
        thickness = float(mask.sum()) / along
        k = max(3, int(round(1.5 * thickness + 2 * period)) | 1)
        mask = cv2.dilate(mask.astype(np.uint8), np.ones((k, k), np.uint8)) > 0
    pts = np.column_stack([xx[mask], yy[mask]]).astype(float)
    plane = np.full((h, w, 2), np.nan)
    plane[mask] = pm.to_plane(pts)
    bins = max(4, int(period))  # bins of a pixel or more: a ruler along the rows fills no finer ones
    # each pixel against its surroundings over a period (the paper, the bench, the light's gradient)
    g = grey.astype(np.float32)
    detail = (g - cv2.GaussianBlur(g, (0, 0), period)).astype(np.float64)[mask]
    read, spans = [], []
    for axis in range(2 if graph else 1):
        coordinate = plane[..., axis][mask]
        span = coarsest_period(coordinate, detail, bins=bins, period_px=period)
        read.append(read_levels(fold(detail, coordinate, span=span, bins=bins, period_px=period)))
        spans.append(span)
    finer = {r.finer / sp for r, sp in zip(read, spans, strict=True)}
    lines = "lines" if graph else "ticks"
    what = "graph paper's" if graph else "a ruler's"
    if max(finer) > 1.02 * min(finer):
        return (f"{what} two families of lines, every {period:.3g} px, show finer lines in one direction only "
                "— retake the image in focus and evenly lit")
    m = read[0].finer / spans[0]  # finest lines per period fitted
    bolder = sorted(set.intersection(*[set(r.bolder) for r in read]))
    fine_px = period / m
    if 5 in bolder or 10 in bolder:
        phases = [float(np.mod(r.phase * m, 1.0)) for r in read]
        log.info("%s: finest %s every %.3g px, %.3g per period fitted, bolder every %s", what, lines, fine_px, m,
                 bolder)
        return m, phases, bolder
    if bolder == [2]:
        return (f"{what} {lines} were found every {fine_px:.3g} px with every 2nd bolder (longer): that is its 5 mm "
                f"level (10 mm every 2nd), its finest {lines} are not seen (too faint, or too fine at this "
                "magnification) — photograph it closer, in focus and evenly lit; or, if those are 5 mm apart, give "
                f"the analysis --mm-per-px {5.0 / fine_px:.4g}")
    return (f"{lines} were found every {fine_px:.3g} px, but no bolder (longer) one every 5th or 10th: graph paper "
            "and rulers mark their 5 and 10 mm lines so, and without them the lines seen may be those 5 or 10 mm "
            "apart (the finest not seen) — photograph the pattern closer, in focus and evenly lit, or use a "
            "checkerboard")


def _grating_points(pm: PlaneMap, phases: list[float], box: tuple[int, int, int, int], *, graph: bool,
                    support: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Where the finest lines cross (graph paper) or the ticks are (a ruler, across the middle of its box), for
    the figure: the fitted map's integer lines (in finest periods, at the lines' phase) seen in the image."""
    y0, y1, x0, x1 = box
    corners = np.array([[x0, y0], [x1, y0], [x0, y1], [x1, y1], [0.5 * (x0 + x1), y0], [0.5 * (x0 + x1), y1],
                        [x0, 0.5 * (y0 + y1)], [x1, 0.5 * (y0 + y1)]], dtype=float)
    span = pm.to_plane(corners)
    k1 = np.arange(np.floor(span[:, 0].min()) - 1, np.ceil(span[:, 0].max()) + 2) + phases[0]
    if graph:
        k2 = np.arange(np.floor(span[:, 1].min()) - 1, np.ceil(span[:, 1].max()) + 2) + phases[1]
        if len(k1) * len(k2) > 40000:
            return np.zeros((0, 2))
        K1, K2 = np.meshgrid(k1, k2)
        plane = np.column_stack([K1.ravel(), K2.ravel()])
    else:
        mid = pm.to_plane(centre.reshape(1, 2))[0, 1]
        plane = np.column_stack([k1, np.full(len(k1), mid)])
    pts = pm.to_image(plane)
    inside = (pts[:, 0] >= x0) & (pts[:, 0] < x1) & (pts[:, 1] >= y0) & (pts[:, 1] < y1)
    pts = pts[inside]
    if graph:  # only where the paper is
        on = support[pts[:, 1].astype(int), pts[:, 0].astype(int)] > 0.25
        pts = pts[on]
    return pts[:5000]


# -- finding the points -----------------------------------------------------------------------
def _grey8(image: np.ndarray) -> np.ndarray:
    """8-bit grey, stretched between the 0.5th and 99.5th percentiles."""
    img = np.asarray(image, dtype=np.float64)
    if img.ndim == 3:
        img = img[..., :3].mean(axis=2)
    if img.ndim != 2 or min(img.shape) < 16:
        raise CalibrationError(f"a calibration image must be a 2-D picture of at least 16 x 16 pixels, got shape "
                               f"{np.shape(image)}")
    lo, hi = np.percentile(img, [0.5, 99.5])
    if not hi > lo:
        raise CalibrationError("the calibration image is uniform — it shows no pattern")
    return np.clip((img - lo) * (255.0 / (hi - lo)), 0, 255).astype(np.uint8)


def _checkerboard_points(grey: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Inner corners of a checkerboard, ``(index (N, 2), image points (N, 2))``, any board size.

    Harris corner peaks (scikit-image) refined to sub-pixel saddle points
    (:func:`skimage.feature.corner_subpix`), kept where the image around them has the
    two-fold symmetry of an inner corner (dark, light, dark, light around a circle: the
    second Fourier harmonic of the circle's profile dominates; the board's outer
    corners, a quarter dark, have a dominant first harmonic), then indexed on their
    lattice (:func:`index_lattice`). The peaks are looked for in the image as it is and
    smoothed by a Gaussian of 1 px (in a noisy, low-contrast image the noise's own
    corners outnumber the board's and hide its pitch); the larger lattice is kept. The
    corners are always refined in the image as it is.
    """
    g = grey.astype(np.float64) / 255.0
    best = None
    for smooth_px in (0.0, 1.0):
        found = _checkerboard_corners(g, smooth_px=smooth_px)
        if found is not None and (best is None or len(found[0]) > len(best[0])):
            best = found
    return best


def _checkerboard_corners(g: np.ndarray, *, smooth_px: float) -> tuple[np.ndarray, np.ndarray] | None:
    """:func:`_checkerboard_points` with the peaks looked for in ``g`` smoothed by ``smooth_px``.

    A corner nearer the image's edge than the refinement's half-window (or the symmetry
    test's circle) is dropped: :func:`skimage.feature.corner_subpix` pads the image with
    zeros, whose edge pulls such a corner by several pixels (a board larger than the frame
    had its corners along the edge 3.5-5 px off, and a false "not flat" warning).
    """
    import cv2
    from skimage.feature import corner_harris, corner_peaks, corner_subpix

    detect = cv2.GaussianBlur(g, (0, 0), smooth_px) if smooth_px > 0 else g
    peaks = corner_peaks(corner_harris(detect, sigma=2), min_distance=4, threshold_rel=0.02)
    if len(peaks) < 9:
        return None
    gaps = np.sort(np.hypot(*(peaks[:, None, :] - peaks[None, :, :]).transpose(2, 0, 1)), axis=1)[:, 1]
    pitch = float(np.median(gaps))
    window = max(5, int(0.6 * pitch) | 1)
    radius = pitch / 3
    margin = max((window - 1) // 2, math.ceil(radius)) + 1
    h, w = g.shape

    def inside(rc: np.ndarray) -> np.ndarray:
        return ((rc[:, 0] >= margin) & (rc[:, 0] <= h - 1 - margin)
                & (rc[:, 1] >= margin) & (rc[:, 1] <= w - 1 - margin))

    peaks = peaks[inside(peaks)]
    if len(peaks) < 9:
        return None
    refined = corner_subpix(detect, peaks, window_size=window, alpha=0.99)
    refined = refined[~np.isnan(refined).any(axis=1)]
    refined = refined[inside(refined)]
    if len(refined) < 9:
        return None
    inner = refined[_x_corners(g, refined, radius=radius)]
    return index_lattice(inner[:, ::-1]) if len(inner) >= 9 else None


def _alternates(grey: np.ndarray, index: np.ndarray, points: np.ndarray) -> bool:
    """Whether a lattice of corners bounds squares alternately dark and light, each even (a checkerboard).

    Each square whose four corners were found is sampled at 3 x 3 points over its middle half
    (bilinear between its corners); the squares of the two colours must differ by more than 3
    times the spread of the samples within a square and of the squares within a colour, and by
    10 grey levels. Graph paper's crossings bound squares of paper crossed by lines (or, taken
    along the diagonals, squares with a crossing in the middle), all alike or uneven. True when
    fewer than 4 squares can be checked.
    """
    from scipy import ndimage

    where = {(int(i), int(j)): k for k, (i, j) in enumerate(np.rint(index).astype(int))}
    g = grey.astype(np.float64)
    a, b = np.meshgrid([0.25, 0.5, 0.75], [0.25, 0.5, 0.75])
    a, b = a.ravel(), b.ravel()
    means, spreads, parity = [], [], []
    for (i, j), k in where.items():
        ks = [where.get(q) for q in ((i + 1, j), (i, j + 1), (i + 1, j + 1))]
        if None in ks:
            continue
        p00, p10, p01, p11 = points[[k, *ks]]
        xy = (np.outer((1 - a) * (1 - b), p00) + np.outer(a * (1 - b), p10) + np.outer((1 - a) * b, p01)
              + np.outer(a * b, p11))
        v = ndimage.map_coordinates(g, [xy[:, 1], xy[:, 0]], order=1, mode="nearest")
        means.append(float(v.mean()))
        spreads.append(float(v.std()))
        parity.append((i + j) % 2)
    if len(means) < 4 or len(set(parity)) < 2:
        return True
    v, p = np.asarray(means), np.asarray(parity)
    dark, light = v[p == 0], v[p == 1]
    spread = max(math.sqrt(0.5 * (float(np.var(dark)) + float(np.var(light)))), float(np.median(spreads)))
    gap = abs(float(dark.mean()) - float(light.mean()))
    return gap > 3 * spread and gap > 10.0


def _x_corners(g: np.ndarray, rc: np.ndarray, *, radius: float) -> np.ndarray:
    """Which points ``(row, col)`` are inner (X-shaped) checkerboard corners."""
    from scipy import ndimage

    theta = np.linspace(0.0, 2.0 * np.pi, 32, endpoint=False)
    rows = rc[:, :1] + radius * np.sin(theta)
    cols = rc[:, 1:] + radius * np.cos(theta)
    ring = ndimage.map_coordinates(g, [rows.ravel(), cols.ravel()], order=1, mode="nearest").reshape(rows.shape)
    f = np.abs(np.fft.rfft(ring, axis=1))
    # a board's corner is a square wave of two cycles around the ring: no fourth harmonic; where two lines cross
    # (graph paper, one line bolder than the other) the fourth is as strong as the second
    return (f[:, 2] > f[:, 1]) & (f[:, 2] > 2 * f[:, 3]) & (f[:, 2] > 2 * f[:, 4])


def _dot_points(grey: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Centres of dots (dark on light or light on dark) indexed on their lattice."""
    from scipy import ndimage

    best = None
    thr = _otsu(grey)
    for dark in (True, False):
        mask = grey < thr if dark else grey > thr
        labels, n = ndimage.label(mask)
        if n < 9:
            continue
        idx = np.arange(1, n + 1)
        area = ndimage.sum_labels(mask, labels, idx)
        weights = (255.0 - grey if dark else grey.astype(np.float64))
        cy, cx = np.array(ndimage.center_of_mass(weights * mask, labels, idx)).T
        # dots: blobs of the typical size, not touching the border, compact
        med = np.median(area[area >= 6]) if np.any(area >= 6) else 0
        box = ndimage.find_objects(labels)
        keep = []
        for k, sl in enumerate(box):
            if not (0.4 * med <= area[k] <= 2.5 * med) or med < 6:
                continue
            h, w = sl[0].stop - sl[0].start, sl[1].stop - sl[1].start
            touches = sl[0].start == 0 or sl[1].start == 0 or sl[0].stop == grey.shape[0] or sl[1].stop == grey.shape[1]
            if touches or area[k] < 0.45 * h * w or max(h, w) > 3 * min(h, w):
                continue
            # round, not square: area against the circle through the farthest pixel (a disc ~0.9,
            # a square 2/pi = 0.64: a checkerboard's squares are not dots)
            rr, cc = np.nonzero(labels[sl] == k + 1)
            r_max = np.sqrt(((rr + sl[0].start - cy[k]) ** 2 + (cc + sl[1].start - cx[k]) ** 2).max()) + 0.5
            if area[k] < 0.75 * np.pi * r_max**2:
                continue
            keep.append(k)
        if len(keep) < 9:
            continue
        pts = np.stack([cx[keep], cy[keep]], axis=1)
        indexed = index_lattice(pts)
        if indexed is not None and (best is None or len(indexed[0]) > len(best[0])):
            best = indexed
    return best


def _otsu(grey: np.ndarray) -> float:
    from skimage.filters import threshold_otsu

    return float(threshold_otsu(grey))


def index_lattice(points: np.ndarray, *, tolerance: float = 0.3) -> tuple[np.ndarray, np.ndarray] | None:
    """Integer lattice indices of points on a (perspective-distorted) square grid.

    Grows from the point nearest the centroid: a neighbour of an indexed point found
    within ``tolerance`` of a lattice step of it (the local steps, updated as the growth
    moves, so that perspective is followed) gets the neighbouring index.

    Returns
    -------
    (index (M, 2), points (M, 2)) of the points reached, or None when fewer than 9.
    """
    from scipy.spatial import cKDTree

    pts = np.asarray(points, float)
    if len(pts) < 9:
        return None
    tree = cKDTree(pts)
    _, nn = tree.query(pts, k=5)
    steps = (pts[nn[:, 1:]] - pts[:, None, :]).reshape(-1, 2)
    lengths = np.hypot(*steps.T)
    pitch = float(np.median(np.sort(lengths.reshape(len(pts), 4), axis=1)[:, 0]))
    # the two lattice directions: angles of the short steps, folded to [0, 180)
    short = steps[lengths < 1.3 * pitch]
    ang = np.degrees(np.arctan2(short[:, 1], short[:, 0])) % 180.0

    def wrapped(a: np.ndarray, ref: float) -> np.ndarray:  # a - ref folded to [-90, 90)
        return (a - ref + 90.0) % 180.0 - 90.0

    hist, edges = np.histogram(ang, bins=36, range=(0, 180))
    peak = float(edges[np.argmax(hist)] + 2.5)
    near = np.abs(wrapped(ang, peak)) < 10
    a1 = peak + float(np.median(wrapped(ang[near], peak)))
    far = np.abs(wrapped(ang, a1)) > 45
    if far.sum() < 3:
        return None
    a2 = a1 + 90.0 + float(np.median(wrapped(ang[far], a1 + 90.0)))
    u = pitch * np.array([math.cos(math.radians(a1)), math.sin(math.radians(a1))])
    v = pitch * np.array([math.cos(math.radians(a2)), math.sin(math.radians(a2))])
    start = int(np.argmin(np.hypot(*(pts - pts.mean(axis=0)).T)))
    index = {start: (0, 0)}
    local = {start: (u, v)}
    queue = [start]
    taken = {(0, 0)}
    while queue:
        k = queue.pop(0)
        i, j = index[k]
        lu, lv = local[k]
        for di, dj, step in ((1, 0, lu), (-1, 0, -lu), (0, 1, lv), (0, -1, -lv)):
            if (i + di, j + dj) in taken:
                continue
            dist, m = tree.query(pts[k] + step)
            if m in index or dist > tolerance * np.hypot(*step):
                continue
            index[m] = (i + di, j + dj)
            taken.add((i + di, j + dj))
            found = pts[m] - pts[k]
            nu, nv = (found * di, lv) if di else (lu, found * dj)
            local[m] = (np.asarray(nu, float), np.asarray(nv, float))
            queue.append(m)
    if len(index) < 9:
        return None
    keys = np.array(list(index))
    ij = np.array([index[k] for k in keys], float)
    ij, found = _drop_inconsistent(ij, pts[keys])
    if len(ij) < 9:
        return None
    ij -= ij.min(axis=0)
    if len(np.unique(ij[:, 0])) < 2 or len(np.unique(ij[:, 1])) < 2:  # a strip of 2 rows is a lattice too
        return None
    return ij, found


#: a point farther than this share of the local pitch from where its lattice neighbours put it is dropped
INCONSISTENT_SHARE = 0.05
#: ... or farther than this many robust standard deviations of all points' such distances
INCONSISTENT_SD = 6.0


def _drop_inconsistent(ij: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The points that sit where their lattice neighbours put them.

    Each point is predicted from the points within two lattice steps of it by the homography
    (OpenCV, least squares) that maps their indices to the image: exact under perspective,
    and lens distortion bends a lattice little over two steps. The point farthest from its
    prediction is dropped while that distance exceeds both ``INCONSISTENT_SHARE`` of the
    local pitch and ``INCONSISTENT_SD`` robust standard deviations of all the points'
    distances (and 0.3 px): a speck of noise, or the board's edge, taken for a corner within
    the indexing's tolerance (30 % of the pitch) would otherwise pull the fit and raise a
    false "not flat" warning. Points with fewer than 6 neighbours are kept as they are.
    """
    import cv2

    ij = np.asarray(ij, float)
    pts = np.asarray(pts, float)
    keep = np.ones(len(ij), bool)
    lookup = {(int(i), int(j)): k for k, (i, j) in enumerate(ij)}
    offsets = [(di, dj) for di in range(-2, 3) for dj in range(-2, 3) if (di, dj) != (0, 0)]

    def misfit(k: int) -> tuple[float, float]:
        i, j = int(ij[k, 0]), int(ij[k, 1])
        nb = [(di, dj, m) for di, dj in offsets if (m := lookup.get((i + di, j + dj))) is not None and keep[m]]
        d = np.array([(di, dj) for di, dj, _ in nb], float).reshape(-1, 2)
        if len(nb) < 6 or len(np.unique(d[:, 0])) < 2 or len(np.unique(d[:, 1])) < 2:
            return 0.0, 0.0
        H, _ = cv2.findHomography(d, pts[[m for *_, m in nb]], 0)
        if H is None or not np.all(np.isfinite(H)) or abs(H[2, 2]) < 1e-12:
            return 0.0, 0.0
        predicted = H[:2, 2] / H[2, 2]
        D = (H[:2, :2] * H[2, 2] - np.outer(H[:2, 2], H[2, :2])) / H[2, 2] ** 2  # d(x, y)/d(i, j) at the point
        return float(np.hypot(*(predicted - pts[k]))), float(np.sqrt(abs(np.linalg.det(D))))

    while keep.sum() >= 9:
        alive = np.flatnonzero(keep)
        checked = np.array([misfit(k) for k in alive])
        dist, pitch = checked[:, 0], checked[:, 1]
        sd = 1.4826 * float(np.median(dist[pitch > 0])) if np.any(pitch > 0) else 0.0
        limit = np.maximum.reduce([INCONSISTENT_SHARE * pitch, np.full(len(alive), INCONSISTENT_SD * sd),
                                   np.full(len(alive), 0.3)])
        bad = (pitch > 0) & (dist > limit)
        if not bad.any():
            break
        keep[alive[np.argmax(np.where(bad, dist / limit, 0.0))]] = False
    return ij[keep], pts[keep]


# -- the fit ----------------------------------------------------------------------------------
#: the lens's distortion is fitted when the points reach this far from the frame's centre (share of its corner's
#: distance) and number at least MIN_POINTS_DISTORTION
MIN_REACH_DISTORTION = 0.3
MIN_POINTS_DISTORTION = 16
#: a lens distorting more than this at the frame's corners (either sign) is said
DISTORTION_SAY = 0.005
#: the lens's two terms are kept when they lower the residuals (points', or lines' parts') this much: F statistic
#: of the two terms (else the homography alone: the terms would fit the noise)
DISTORTION_F = 10.0


def _reach(points: np.ndarray, shape: tuple[int, int]) -> float:
    """How far the points reach from the frame's centre, as a share of its corner's distance."""
    centre, radius = frame_centre_and_radius(shape)
    return float(np.max(np.hypot(*(np.asarray(points, float) - np.asarray(centre)).T)) / radius)


def _distortion_warning(k1: float, k2: float) -> str | None:
    corner = 1.0 / (1.0 + k1 + k2) - 1.0
    if abs(corner) <= DISTORTION_SAY:
        return None
    kind = "barrel" if corner < 0 else "pincushion"
    return coded("calibration.lens_distortion",
                 f"the lens distorts the image by {100 * corner:+.1f} % at the frame's corners ({kind}; fitted k1 "
                 f"{k1:+.4f}, k2 {k2:+.4f}): the scale is corrected at the pattern's centre, and the analysis "
                 "takes it where the tube is (Calibration.scale_at)")


def _fit(world: np.ndarray, image_pts: np.ndarray, *, pitch_mm: float, kind: str, shape: tuple[int, int],
         identity: dict[str, object]) -> Calibration:
    fit = fit_points(world, image_pts, shape=shape, distortion=False)
    distortion = False
    if len(world) >= MIN_POINTS_DISTORTION and _reach(image_pts, shape) >= MIN_REACH_DISTORTION:
        # the lens's terms when the points ask for them (an F test), not to fit their noise
        bent = fit_points(world, image_pts, shape=shape, distortion=True)
        n_obs = 2 * len(world)
        rss0, rss1 = fit.rms**2 * n_obs, bent.rms**2 * n_obs
        if rss1 <= 0 or (rss0 - rss1) / 2 / (rss1 / max(n_obs - len(bent.params), 1)) > DISTORTION_F:
            fit, distortion = bent, True
    pm = fit.plane_map
    if not np.all(np.isfinite(pm.homography)):
        raise CalibrationError("the pattern's points do not fit a plane seen by a camera — retake the image")
    proj = pm.to_image(world)
    rms = fit.rms
    centre_world = world.mean(axis=0)
    centre = pm.to_image(centre_world.reshape(1, 2))[0]
    J = pm.jacobian(centre.reshape(1, 2))[0]
    mm_x, mm_y = float(np.hypot(*J[:, 0])), float(np.hypot(*J[:, 1]))
    scale = float(math.sqrt(abs(np.linalg.det(J))))
    local = pm.scale(image_pts)
    variation = float((local.max() - local.min()) / local.mean())
    # what the fitted map cannot show (a lens's distortion of another form, a card not flat): the scale measured
    # between each point's lattice neighbours, against the map's at the same place
    # (with the lens's distortion fitted, the map holds it: the field then only adds its noise to the scale, and
    # is kept for the variation it measures)
    field_fit = _local_scale_field(world, image_pts, proj, pitch_mm=pitch_mm)
    if field_fit is not None:
        at_centre, field_sd, field_variation = field_fit(centre)
        if not distortion:
            J = J * at_centre
            mm_x, mm_y, scale = mm_x * at_centre, mm_y * at_centre, scale * at_centre
        variation = max(variation, field_variation)
    # pattern rows in the image: the image of the plane's X axis
    d = pm.to_image(np.array([centre_world, centre_world + np.array([pitch_mm, 0.0])]))
    tilt = float(math.degrees(math.atan2(-(d[1, 1] - d[0, 1]), d[1, 0] - d[0, 0])))
    tilt = (tilt + 45.0) % 90.0 - 45.0  # a square grid looks the same turned by a quarter
    rel_sd = _affine_scale_rel_sd(world, image_pts, residual_mm=rms * scale)
    if distortion:  # the distortion's coefficients are uncertain too
        def centre_scale(m: PlaneMap) -> float:
            return float(m.scale(m.to_image(centre_world.reshape(1, 2)))[0])

        rel_sd = max(rel_sd, fit.rel_sd_of(centre_scale))
    if field_fit is not None and not distortion:
        rel_sd = math.hypot(rel_sd, field_sd)
    warnings = []
    said = _distortion_warning(pm.k1, pm.k2)
    if said:
        warnings.append(said)
    # with the lens's distortion fitted, what varies beyond it (the pattern's perspective, the field's own
    # variation) is what holding the pattern square would fix; the lens's part is taken out where the tube is
    beyond_lens = variation
    if distortion:
        flat = dataclasses.replace(pm, k1=0.0, k2=0.0).scale(image_pts)
        beyond_lens = float((flat.max() - flat.min()) / flat.mean())
        if field_fit is not None:
            beyond_lens = max(beyond_lens, field_variation - (variation - beyond_lens))
    if beyond_lens > SCALE_VARIATION_WARN:
        warnings.append(f"the scale varies by {100 * variation:.1f} % over the pattern (perspective or lens "
                        "distortion): hold the pattern square to the camera, at the tube's plane, and use the "
                        "scale where the tube is")
    if abs(mm_x / mm_y - 1) > 0.01:
        warnings.append(f"pixels are not square here ({mm_x:.5g} x {mm_y:.5g} mm): the scale along the tube "
                        "is taken along its axis")
    if rms > 0.5:
        warnings.append(f"the points lie {rms:.2f} px from the fitted plane on average (lens distortion, or a "
                        "pattern that is not flat)")
    return Calibration(
        mm_per_px=scale, mm_per_px_x=mm_x, mm_per_px_y=mm_y,
        jacobian_mm_per_px=((float(J[0, 0]), float(J[0, 1])), (float(J[1, 0]), float(J[1, 1]))),
        rel_sd=rel_sd, tilt_deg=tilt, scale_variation=variation, rms_residual_px=rms, n_points=len(world),
        pattern=kind, pitch_mm=float(pitch_mm), image_shape=(int(shape[0]), int(shape[1])),
        centre_px=(float(centre[0]), float(centre[1])),
        homography=tuple(tuple(float(x) for x in row) for row in pm.homography), image=dict(identity),
        warnings=tuple(warnings), points_px=tuple((float(x), float(y)) for x, y in image_pts),
        distortion_k1=float(pm.k1), distortion_k2=float(pm.k2), distortion_centre_px=tuple(pm.centre),
        distortion_radius_px=float(pm.radius),
    )


def _local_scale_field(world: np.ndarray, image_pts: np.ndarray, proj: np.ndarray, *, pitch_mm: float):
    """The measured scale over the pattern relative to the homography's, as a smooth surface.

    At every point whose four lattice neighbours were found, the local scale is
    ``sqrt|det D|`` with ``D`` the central differences of the neighbours' positions (mm per
    px), measured on the points found and on the homography's projections of the same
    points (so that the finite-difference error cancels in their ratio). A quadratic
    surface in image coordinates is fitted to the ratio (a plane when the points do not
    spread in two directions) and to the measured scale.

    Returns
    -------
    callable or None
        ``f(centre_xy) -> (ratio at centre, its standard error, relative range of the
        fitted measured scale over the points)``; None when fewer than 6 points have their
        four neighbours.
    """
    idx = np.rint(world / pitch_mm).astype(np.int64)
    where = {(int(i), int(j)): k for k, (i, j) in enumerate(idx)}
    rows = []
    for k, (i, j) in enumerate(idx):
        nb = [where.get(q) for q in ((i + 1, j), (i - 1, j), (i, j + 1), (i, j - 1))]
        if None not in nb:
            rows.append((k, *nb))
    if len(rows) < 6:
        return None
    r = np.array(rows)

    def scale(p: np.ndarray) -> np.ndarray:
        a = (p[r[:, 1]] - p[r[:, 2]]) / (2 * pitch_mm)  # px per mm along the lattice's two axes
        b = (p[r[:, 3]] - p[r[:, 4]]) / (2 * pitch_mm)
        return 1.0 / np.sqrt(np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]))

    measured = scale(image_pts.astype(np.float64))
    ratio = measured / scale(proj.astype(np.float64))
    xy = image_pts[r[:, 0]].astype(np.float64)
    c0 = xy.mean(axis=0)
    half = max(float(np.abs(xy - c0).max()), 1.0)

    n_terms = 6 if len(xy) >= 12 else 3  # quadratic, or a plane for few points

    def basis(q: np.ndarray) -> np.ndarray:
        u, v = ((q - c0) / half).T
        return np.column_stack([np.ones_like(u), u, v, u * u, u * v, v * v])[:, :n_terms]

    B = basis(xy)
    coef, *_ = np.linalg.lstsq(B, ratio, rcond=1e-6)
    resid = ratio - B @ coef
    sigma2 = float(resid @ resid) / max(1, len(xy) - n_terms)
    cov = sigma2 * np.linalg.pinv(B.T @ B, rcond=1e-6)
    mcoef, *_ = np.linalg.lstsq(B, measured, rcond=1e-6)
    smooth = B @ mcoef

    def at(centre_xy: np.ndarray) -> tuple[float, float, float]:
        b = basis(np.asarray(centre_xy, float).reshape(1, 2))[0]
        value = float(b @ coef)
        sd = math.sqrt(max(float(b @ cov @ b), 0.0)) / value
        return value, sd, float((smooth.max() - smooth.min()) / smooth.mean())

    return at


def _inverse_jacobian(H: np.ndarray, w: np.ndarray) -> np.ndarray:
    """d(plane mm)/d(image px) at plane point ``w``: the inverse of the homography's derivative."""
    X, Y = float(w[0]), float(w[1])
    num = H[:2] @ np.array([X, Y, 1.0])
    den = float(H[2] @ np.array([X, Y, 1.0]))
    d = (H[:2, :2] * den - np.outer(num, H[2, :2])) / den**2  # d(x, y)/d(X, Y)
    return np.linalg.inv(d)


def _affine_scale_rel_sd(world: np.ndarray, image_pts: np.ndarray, *, residual_mm: float) -> float:
    """Relative standard error of sqrt|det A| of the least-squares affine map image -> plane, with
    the points' scatter about the fitted homography (``residual_mm``, rms of both coordinates
    together) as the noise: the points' spread sets the leverage, the homography the noise."""
    n = len(world)
    X = np.column_stack([image_pts, np.ones(n)])
    coef, *_ = np.linalg.lstsq(X, world, rcond=None)  # (3, 2): plane = X @ coef
    sigma2 = residual_mm**2 / 2 * n / max(1, n - 4)  # per coordinate, for the homography's 8 parameters
    cov = sigma2 * np.linalg.inv(X.T @ X)  # same for both output columns
    A = coef[:2].T  # plane = A @ (x, y) + t
    det = float(np.linalg.det(A))
    # d det / d A = det * inv(A).T; the two rows of A are independent with covariance cov[:2, :2]
    g = det * np.linalg.inv(A).T
    var_det = float(g[0] @ cov[:2, :2] @ g[0] + g[1] @ cov[:2, :2] @ g[1])
    return float(0.5 * math.sqrt(max(var_det, 0.0)) / abs(det))
