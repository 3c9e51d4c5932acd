"""An optical renderer of movies of a glass tube, for validating the tube model (issue 16, item 6).

Independent of grainplug on purpose: it imports nothing from it, and it works
differently from the method it checks. grainplug's tube model uses closed-form
deflections of the principal ray (no partial reflections); here rays are traced
step by step through the cross-section with vector Snell's law, **both** the
reflected and the refracted branch are followed at every interface with
unpolarised Fresnel weights (total internal reflection included), and the light
each branch finally collects is summed:

* a back-light: a uniform diffuse lamp of angular half-size ``beta`` behind the tube
  (soft 1 deg edge), or none;
* front lamps: two lamps on the camera's side at +-35 deg, 10 deg half-size;
* otherwise the dark room;
* inside the bore, a plug (a dense bed of glass beads) stops every ray that reaches
  it and returns its own light: a faint glow in back light, diffuse scattering of
  the front lamps in front light; a bubble is air.

This gives, per lighting, two radiance profiles across the tube (bore full of air,
bore full of grains). The movie is built from them: each pixel's distance across
the axis (tilted, off-centre tubes) picks the profile value, averaged over the
pixel's footprint; its position along the axis and the time decide plug or bubble
(plugs move at a constant celerity). Then the camera: vignetting, lamp flicker,
Gaussian optical blur, shot and read noise, 8 or 12 bits, and optionally a lossy
codec (H.264 at crf 28, or MJPEG).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class Lighting:
    """What lights the tube.

    Attributes
    ----------
    kind : {"back", "front"}
        A lamp behind the tube, or lamps beside the camera (and a dark backdrop).
    beta_deg : float
        Back-light's angular half-size.
    """

    kind: str = "back"
    beta_deg: float = 25.0

    def radiance(self, d: np.ndarray) -> np.ndarray:
        """Light arriving along direction ``-d`` for rays leaving the tube along ``d`` (unit, (n, 2): x, z)."""
        theta = np.degrees(np.arctan2(d[:, 0], d[:, 1]))  # 0 = away from the camera, towards the back
        room = np.full(len(d), 0.02)
        if self.kind == "back":
            lamp = 1.0 / (1.0 + np.exp((np.abs(theta) - self.beta_deg) / 0.25))
            return room + (1.0 - 0.02) * lamp
        towards_camera = 180.0 - np.abs(theta)
        lamp = 1.0 / (1.0 + np.exp((np.abs(towards_camera - 35.0) - 10.0) / 0.25))
        return room + 3.0 * lamp

    def plug_radiance(self) -> float:
        """A dense bed of beads: a faint glow of the back-light through it, or the front lamps scattered."""
        return 0.04 if self.kind == "back" else 0.5


def trace(x_mm: np.ndarray, *, inner_radius: float, outer_radius: float, n_glass: float, lighting: Lighting,
          bore: str, max_depth: int = 12, min_weight: float = 1e-4) -> tuple[np.ndarray, np.ndarray]:
    """Radiance seen by camera rays at ``x_mm`` from the axis, and the weight of light that left the tube.

    Parameters
    ----------
    x_mm : ndarray
        Distances of the camera rays from the axis (the camera looks along +z).
    inner_radius, outer_radius, n_glass : float
        The tube.
    lighting : Lighting
        The lamps.
    bore : {"air", "plug"}
        What fills the bore.
    max_depth : int
        Interfaces followed along any branch.
    min_weight : float
        Branches weaker than this are dropped.

    Returns
    -------
    radiance : ndarray
        Sum over the branches of weight x the light each collected.
    escaped : ndarray
        Sum of the weights of the branches that left the tube or were absorbed
        (1 up to the dropped branches: energy is conserved at each interface).
    """
    a, b, n = float(inner_radius), float(outer_radius), float(n_glass)
    x = np.asarray(x_mm, dtype=float)
    origin = np.column_stack([x, np.full(len(x), -10.0 * b)])
    p, d = origin.copy(), np.tile([0.0, 1.0], (len(x), 1))
    w = np.ones(len(x))
    medium = np.zeros(len(x), int)  # 0 outside, 1 glass, 2 bore
    src = np.arange(len(x))
    radiance = np.zeros(len(x))
    escaped = np.zeros(len(x))
    index = np.array([1.0, n, 1.0])
    plug_light = lighting.plug_radiance()
    for _ in range(max_depth + 1):
        if not len(src):
            break
        t_best = np.full(len(src), np.inf)
        r_hit = np.zeros(len(src))
        for r in (a, b):
            pd = np.sum(p * d, axis=1)
            c = np.sum(p * p, axis=1) - r * r
            disc = pd * pd - c
            ok = disc > 0
            sq = np.sqrt(np.where(ok, disc, 0.0))
            for t in (-pd - sq, -pd + sq):
                better = ok & (t > 1e-10) & (t < t_best)
                t_best = np.where(better, t, t_best)
                r_hit = np.where(better, r, r_hit)
        leaving = ~np.isfinite(t_best)
        # a branch with nothing ahead has left the tube (it can only be outside): it sees the lamps
        np.add.at(radiance, src[leaving], w[leaving] * lighting.radiance(d[leaving]))
        np.add.at(escaped, src[leaving], w[leaving])
        keep = ~leaving
        p, d, w, medium, src, t_best, r_hit = (p[keep], d[keep], w[keep], medium[keep], src[keep], t_best[keep],
                                              r_hit[keep])
        p = p + t_best[:, None] * d
        normal = p / np.linalg.norm(p, axis=1)[:, None]
        outward = np.sum(d * normal, axis=1) > 0
        on_outer = r_hit == b
        # the medium on the far side of the interface
        beyond = np.where(on_outer, np.where(outward, 0, 1), np.where(outward, 1, 2))
        n1, n2 = index[medium], index[beyond]
        facing = np.where(outward[:, None], -normal, normal)  # against the ray
        cosi = -np.sum(d * facing, axis=1)
        eta = n1 / n2
        k = 1.0 - eta * eta * (1.0 - cosi * cosi)
        tir = k < 0
        cost = np.sqrt(np.where(tir, 0.0, k))
        rs = (n1 * cosi - n2 * cost) / (n1 * cosi + n2 * cost)
        rp = (n2 * cosi - n1 * cost) / (n2 * cosi + n1 * cost)
        refl = np.where(tir, 1.0, 0.5 * (rs * rs + rp * rp))
        d_refl = d + 2.0 * cosi[:, None] * facing
        d_tran = eta[:, None] * d + (eta * cosi - cost)[:, None] * facing
        # the transmitted branch; into a plug it stops there and returns the bed's light
        w_tran = w * (1.0 - refl)
        into_plug = (beyond == 2) & (bore == "plug") & ~tir
        np.add.at(radiance, src[into_plug], w_tran[into_plug] * plug_light)
        np.add.at(escaped, src[into_plug], w_tran[into_plug])
        go_t = ~tir & ~into_plug & (w_tran > min_weight)
        go_r = w * refl > min_weight
        p = np.concatenate([p[go_r], p[go_t]])
        d = np.concatenate([d_refl[go_r], d_tran[go_t]])
        d /= np.linalg.norm(d, axis=1)[:, None]
        w = np.concatenate([(w * refl)[go_r], w_tran[go_t]])
        medium = np.concatenate([medium[go_r], beyond[go_t]])
        src = np.concatenate([src[go_r], src[go_t]])
    return radiance, escaped


@dataclass(frozen=True)
class Profiles:
    """Radiance across the tube (mm from the axis, symmetric) with the bore full of air and of grains."""

    x_mm: np.ndarray
    air: np.ndarray
    plug: np.ndarray


def profiles(*, inner_diameter_mm: float = 3.0, outer_diameter_mm: float = 5.5, n_glass: float = 1.47,
             lighting: Lighting = Lighting(), step_mm: float = 0.0025) -> Profiles:
    """The two radiance profiles, out to 1.6 outer radii (the background beyond)."""
    b = outer_diameter_mm / 2
    x = np.arange(0.0, 1.6 * b, step_mm) + step_mm / 2
    kw = {"inner_radius": inner_diameter_mm / 2, "outer_radius": b, "n_glass": n_glass, "lighting": lighting}
    air, _ = trace(x, bore="air", **kw)
    plug, _ = trace(x, bore="plug", **kw)
    return Profiles(x, air, plug)


@dataclass(frozen=True)
class Truth:
    """What the rendered movie holds."""

    mm_per_px: float
    fps: float
    celerity_m_s: float
    plug_length_mm: float
    bore_px: float
    outer_px: float
    visible_fraction: float
    n_frames: int
    shape: tuple[int, int]


def visible_fraction(prof: Profiles, inner_radius: float) -> float:
    """Share of the bore's width where plugs and bubbles differ by more than half their largest difference."""
    diff = np.abs(prof.air - prof.plug)
    inside = prof.x_mm < inner_radius
    seen = inside & (diff > 0.5 * diff[inside].max())
    return float(prof.x_mm[seen].max() / inner_radius) if seen.any() else 0.0


def render_movie(path: str | Path, *, rng: np.random.Generator, fmt: str = "tif", height_px: int = 400,
                 width_px: int = 120, mm_per_px: float = 0.15, inner_diameter_mm: float = 3.0,
                 outer_diameter_mm: float = 5.5, n_glass: float = 1.47, lighting: Lighting = Lighting(),
                 orientation: str = "vertical", tilt_deg: float = 0.0, offset_px: float = 0.0,
                 blur_px: float = 0.8, noise: float = 0.01, bit_depth: int = 8, vignetting: float = 0.0,
                 flicker: float = 0.0, n_frames: int = 150, fps: float = 250.0, celerity_m_s: float = -0.05,
                 plug_mm: float = 25.0, bubble_mm: float = 18.0, level: float = 0.75) -> Truth:
    """Write a movie of plugs moving in the tube, and return its truth.

    ``height_px`` is the frame's extent along the tube, ``width_px`` across it
    (a horizontal tube's frame is ``width_px`` high). ``level`` is the back-light's
    (or the brightest front-lit plug's) share of the sensor's range.
    """
    prof = profiles(inner_diameter_mm=inner_diameter_mm, outer_diameter_mm=outer_diameter_mm, n_glass=n_glass,
                    lighting=lighting)
    # each pixel averages the profile over its width: a box filter of one pixel on the fine grid
    box = max(1, int(round(mm_per_px / (prof.x_mm[1] - prof.x_mm[0]))))
    kern = np.ones(box) / box
    air = np.convolve(np.concatenate([prof.air[::-1], prof.air]), kern, mode="same")
    plug = np.convolve(np.concatenate([prof.plug[::-1], prof.plug]), kern, mode="same")
    xs = np.concatenate([-prof.x_mm[::-1], prof.x_mm])
    h, w = height_px, width_px
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    tilt = math.radians(tilt_deg)
    cx, cy = (w - 1) / 2 + offset_px, (h - 1) / 2
    # distances across and along the axis (mm); the axis passes through the frame's centre + offset
    across = ((xx - cx) * math.cos(tilt) - (yy - cy) * math.sin(tilt)) * mm_per_px
    along = ((xx - cx) * math.sin(tilt) + (yy - cy) * math.cos(tilt)) * mm_per_px + cy * mm_per_px
    far = np.abs(across) >= xs[-1]
    img_air = np.where(far, prof.air[-1], np.interp(across, xs, air))
    img_plug = np.where(far, prof.plug[-1], np.interp(across, xs, plug))
    in_bore = np.abs(across) < inner_diameter_mm / 2
    # plugs along the tube: a random sequence long enough for the whole movie
    span = h * mm_per_px + abs(celerity_m_s) * 1000 * n_frames / fps + 4 * (plug_mm + bubble_mm)
    starts, lengths, s = [], [], -2 * (plug_mm + bubble_mm) - abs(celerity_m_s) * 1000 * n_frames / fps
    while s < span:
        ln = plug_mm * (1 + 0.06 * rng.standard_normal())
        starts.append(s)
        lengths.append(ln)
        s += ln + bubble_mm * (1 + 0.1 * rng.standard_normal())
    starts, lengths = np.array(starts), np.array(lengths)
    r2 = ((xx - (w - 1) / 2) ** 2 + (yy - (h - 1) / 2) ** 2) / (((w - 1) / 2) ** 2 + ((h - 1) / 2) ** 2)
    light = 1.0 - vignetting * r2
    top = 2**bit_depth - 1
    scale = level * top / max(float(prof.air.max()), float(prof.plug.max()), 1e-9)
    seen: set[int] = set()
    view = h * mm_per_px
    frames = []
    sub = np.array([-0.375, -0.125, 0.125, 0.375]) * mm_per_px  # 4 samples along each pixel
    for k in range(n_frames):
        shift = celerity_m_s * 1000 * k / fps
        frac = np.zeros((h, w))
        for ds in sub:
            pos = along + ds - shift
            i = np.searchsorted(starts, pos, side="right") - 1
            frac += (i >= 0) & (pos < starts[np.clip(i, 0, None)] + lengths[np.clip(i, 0, None)])
        frac /= len(sub)
        frac = np.where(in_bore, frac, 0.0)
        for j in np.flatnonzero((starts + shift >= 0) & (starts + shift + lengths <= view)):
            seen.add(int(j))
        img = (img_air * (1 - frac) + img_plug * frac) * light
        img *= 1.0 + flicker * math.sin(2 * math.pi * 100.0 * k / fps + 0.3)
        if blur_px > 0:
            import cv2

            img = cv2.GaussianBlur(img, (0, 0), blur_px)
        img = img * scale
        img = img + rng.normal(0.0, 1.0, img.shape) * np.sqrt((noise * top) ** 2 + np.maximum(img, 0) * 0.02)
        img = np.clip(np.round(img), 0, top)
        img = img.astype(np.uint8 if bit_depth == 8 else np.uint16)
        frames.append(img if orientation == "vertical" else np.ascontiguousarray(img.T))
    # the truth's celerity sign: positive along increasing row (vertical) or column (horizontal)
    _write(Path(path), frames, fmt=fmt, fps=fps)
    return Truth(mm_per_px, fps, celerity_m_s, float(np.mean(lengths[sorted(seen)])) if seen else float("nan"),
                 inner_diameter_mm / mm_per_px, outer_diameter_mm / mm_per_px,
                 visible_fraction(prof, inner_diameter_mm / 2), n_frames,
                 frames[0].shape[:2])


def _write(path: Path, frames: list[np.ndarray], *, fmt: str, fps: float) -> None:
    if fmt == "tif":
        import tifffile

        with tifffile.TiffWriter(path) as tif:
            for k, f in enumerate(frames):
                tif.write(f, contiguous=True, metadata={"fps": fps} if k == 0 else None)
        return
    import av

    codec, opts, pix = {"h264": ("libx264", {"crf": "28", "preset": "veryfast"}, "yuv420p"),
                        "mjpeg": ("mjpeg", {"q:v": "6"}, "yuvj420p")}[fmt]
    h, w = frames[0].shape[:2]
    hh, ww = h - h % 2, w - w % 2
    with av.open(str(path), "w") as out:
        stream = out.add_stream(codec, rate=int(round(fps)))
        stream.width, stream.height, stream.pix_fmt = ww, hh, pix
        stream.options = opts
        for f in frames:
            g = f[:hh, :ww]
            if g.dtype != np.uint8:
                g = (g >> 4).astype(np.uint8)
            frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(g), format="gray")
            for packet in stream.encode(frame):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)


#: the matrix of issue 16, item 3: name -> keyword arguments of :func:`render_movie`
CASES: dict[str, dict[str, object]] = {
    **{f"back-lit, lamp {b} deg": {"lighting": Lighting("back", float(b))} for b in (15, 20, 25, 35, 50, 70)},
    "front-lit, bright plugs": {"lighting": Lighting("front")},
    "bore 15 px": {"mm_per_px": 0.2, "width_px": 80},
    "bore 60 px, 200 px frame": {"mm_per_px": 0.05, "width_px": 200, "height_px": 900},
    "bore fills 90 % of the frame": {"mm_per_px": 0.05, "width_px": 67, "height_px": 900},
    "tilted +5 deg": {"tilt_deg": 5.0, "width_px": 140},
    "tilted -5 deg, lamp 35 deg": {"tilt_deg": -5.0, "width_px": 140, "lighting": Lighting("back", 35.0)},
    "off-centre by 30 px": {"offset_px": 30.0, "width_px": 180},
    "vignetting 30 %, flicker 5 %": {"vignetting": 0.3, "flicker": 0.05},
    "12-bit": {"bit_depth": 12},
    "blur 1.5 px, noise 3 %": {"blur_px": 1.5, "noise": 0.03},
    "H.264 crf 28": {"fmt": "h264"},
    "H.264 crf 28, front-lit": {"fmt": "h264", "lighting": Lighting("front")},
    "MJPEG": {"fmt": "mjpeg"},
    "horizontal tube": {"orientation": "horizontal"},
    "thick wall (7 mm outside)": {"outer_diameter_mm": 7.0, "width_px": 140},
    "thin wall (4.5 mm outside)": {"outer_diameter_mm": 4.5},
    "soda-lime glass (n = 1.52)": {"n_glass": 1.52},
}

#: file name suffix of each format
SUFFIX = {"tif": ".tif", "h264": ".mp4", "mjpeg": ".avi"}
