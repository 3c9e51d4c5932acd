"""An independent renderer of grains falling through a tube with a KNOWN MASS FLOW RATE (issue 35, item 3).

It shares no code with :mod:`grainplug`, ``tests/compactness_render.py``, ``tests/creep_render.py`` or
``tests/lab_nuisances.py``: the movie is made of *particles*, not of fields.

Physics
-------
A vertical tube of bore ``bore_mm`` (axis ``z`` downwards, image rows increasing) holds spherical grains of
diameter ``grain_mm``. Their centres are uniform in the bore's cross-section (radius ``bore_mm / 2``) and
each has an axial position ``z_i(t)``. The plug *pattern* is a rigid chain of plugs (compactness
``c_plug``) and bubbles (``c_bubble``) of random lengths, drawn in the pattern's frame
``zeta = z - U t - a(t)``, with ``U`` the celerity (negative: the pattern climbs) and ``a(t)`` an optional
oscillation ``oscillation_mm * sin(2 pi oscillation_hz t + phi)`` shared by the pattern and every grain.

In the pattern's frame the flow is steady, so the grains' flux through it is the same everywhere:
``q' = c_p (v_p - U) = c_b (v_b - U)`` (the jump condition at every edge). Each grain carries a label
``m_i`` on the *mass coordinate* ``M(zeta) = int_0^zeta c`` (length of solid per unit bore area); the
labels are Poisson (uniform, density ``A / V_grain`` per unit ``M``) and all advance at ``dm/dt = q'``, so
``zeta_i(t) = M^-1(m_i + q' t)``: inside a plug a grain creeps downstream at ``v_p`` (the plug's texture is
rigid), at the plug's lower edge it leaves and falls through the bubble at ``v_b = U + q' / c_b``, and it
joins the next plug at its upper edge. ``v_b`` follows from mass conservation; it is not imposed.

Light: the camera looks across the tube in back light at ``mm_per_px``. A grain's optical depth at a point
of its projected disc is ``sigma * (chord through the sphere) / d``; a pixel's transmitted light is
``lamp(row, col) * glass(col) * exp(-sum tau)``. The grains are splatted (bilinearly, at their sub-pixel
positions) on the pixel grid and blurred by the sphere's projected-chord kernel; since the centres are uniform
in the disc, the mean optical depth at column ``x`` is Beer-Lambert's ``sigma * c * chord(x) / d`` by itself.
``sigma`` is chosen so that a packed chord through the centre transmits ``packed_centre_transmission``.
Outside the bore: dark glass walls, then the bare lamp. Camera: optional shake (sub-pixel, both axes),
Gaussian noise, rounding to 8 bits; TIFF stack (ImageJ metadata with the frame interval) or H.264.

Truth is counted
----------------
Two counts are given: at one section (below), and at every row boundary of the view, averaged over them
(``view_mass_flow_rate_g_s``: the flux through the view during the record, what a measurement over the
whole view and record can know; over a short record the flux through one section differs from the next,
as the view's content changes).

The section is the boundary between the middle two rows (``z_s = height_px / 2 * mm_per_px``, in the lab
frame; camera shake does not move it). For every grain, between consecutive frames, a change of side of
``z_s`` counts +1 (downwards) or -1 (upwards); the mass flow rate is (down - up) * grain mass / record
duration ``(n_frames - 1) / fps``, in g/s, with ``rho_s = 2500 kg/m^3``. Nothing of the formula is used for
it: the self-test checks it against the jump-condition flux ``rho_s A (c_p v_p + U (c_mean - c_p))``, with
``c_mean`` the time-mean compactness at the section (from the pattern's time fraction there), plus, when the
pattern oscillates, ``rho_s A <c(z_s, t) a'(t)>`` over the record (zero on average, but not over a finite
record: the plug edges pass the section at some phase of the oscillation; the truth reports it as
``oscillation_mass_flow_rate_g_s``; the oscillating cases last whole periods to keep it small).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import ndimage

#: grain density (kg/m^3)
RHO_S = 2500.0


@dataclass(frozen=True)
class FluxScene:
    """What is in the tube and how it is filmed (lengths in mm, speeds in mm/s, downstream positive)."""

    fps: float = 250.0
    n_frames: int = 500
    height_px: int = 640
    width_px: int = 96
    mm_per_px: float = 0.1
    bore_mm: float = 3.0
    grain_mm: float = 0.3
    c_plug: float = 0.58
    c_bubble: float = 0.03
    creep_mm_s: float = 5.0            # v_p, the plug grains' speed
    celerity_mm_s: float = -45.0       # U, the pattern's speed (negative: climbing)
    plug_mm: tuple[float, float] = (15.0, 35.0)
    bubble_mm: tuple[float, float] = (10.0, 25.0)
    oscillation_mm: float = 0.0        # amplitude of the pattern-and-grains oscillation
    oscillation_hz: float = 6.0
    shake_px: float = 0.0              # camera shake, peak on each axis
    packed_centre_transmission: float = 0.25   # light through a packed chord at the centre (sets sigma)
    noise: float = 2.0
    lamp: float = 210.0
    fmt: str = "tif"                   # "tif" | "h264"
    crf: int = 20

    @property
    def fall_mm_s(self) -> float:
        """``v_b`` from the jump condition ``c_b (v_b - U) = c_p (v_p - U)``."""
        u = self.celerity_mm_s
        return u + self.c_plug * (self.creep_mm_s - u) / self.c_bubble


@dataclass(frozen=True)
class FluxTruth:
    """The known answer (speeds in m/s, downstream positive; the mass flow rate counted, in g/s)."""

    mass_flow_rate_g_s: float
    view_mass_flow_rate_g_s: float     # counted at every row boundary of the view, averaged over them
    crossings_down: int
    crossings_up: int
    duration_s: float
    grain_mass_g: float
    section_row: int                   # the section is the boundary above this row
    section_mm: float
    c_plug: float
    c_bubble: float
    creep_m_s: float                   # v_p
    celerity_m_s: float                # U
    fall_m_s: float                    # v_b
    mean_compactness_at_section: float     # from the pattern's time fraction at the section
    counted_compactness_at_section: float  # from the grains inside +-1 mm of the section, time-mean
    plug_fraction_at_section: float
    jump_mass_flow_rate_g_s: float     # rho_s A (c_p v_p + U (c_mean - c_p)), for comparison only
    oscillation_mass_flow_rate_g_s: float  # rho_s A <c(z_s, t) a'(t)>: what the oscillation adds over this record
    plug_lengths_mm: tuple[float, ...]
    bubble_lengths_mm: tuple[float, ...]
    mm_per_px: float
    bore_mm: float
    grain_mm: float
    packed_centre_transmission: float
    sigma: float                       # optical depth of a sphere's diametral chord
    plug_mask: np.ndarray = field(repr=False)  # T x H bool: where the pattern is plug (shake ignored)


# ----------------------------------------------------------------------------------------------- geometry
def _area(s: FluxScene) -> float:
    return math.pi * (0.5 * s.bore_mm) ** 2


def _grain_volume(s: FluxScene) -> float:
    return math.pi * s.grain_mm ** 3 / 6.0


def _sigma(s: FluxScene) -> float:
    """Per-grain optical depth along a diameter such that a packed centre chord transmits the target."""
    tau_centre = -math.log(s.packed_centre_transmission)
    return tau_centre * s.grain_mm / (s.c_plug * s.bore_mm)


def _cross_section(rng: np.random.Generator, n: int, radius: float) -> np.ndarray:
    """The horizontal image coordinate ``x`` (mm from the axis) of ``n`` points uniform in a disc."""
    r = radius * np.sqrt(rng.random(n))
    return r * np.cos(rng.uniform(0.0, 2.0 * math.pi, n))


def _sphere_kernel(s: FluxScene, sigma: float) -> np.ndarray:
    """Optical depth of one grain centred on a pixel centre (supersampled 8x over each pixel area)."""
    a = 0.5 * s.grain_mm / s.mm_per_px                          # radius, px
    k = int(math.ceil(a)) + 1
    sub = (np.arange(8) + 0.5) / 8.0 - 0.5
    off = np.arange(-k, k + 1)
    yy = (off[:, None] + sub[None, :]).ravel()
    r2 = (yy[:, None] ** 2 + yy[None, :] ** 2) / a ** 2
    prof = np.sqrt(np.clip(1.0 - r2, 0.0, None))                # chord / d
    n = 2 * k + 1
    kern = prof.reshape(n, 8, n, 8).mean(axis=(1, 3))
    # integral over the disc of chord/d = V / d (mm^2), in pixel areas
    target = sigma * _grain_volume(s) / s.grain_mm / s.mm_per_px ** 2
    return kern * (target / kern.sum())


def _lamp(s: FluxScene, rows: np.ndarray, cols_mm: np.ndarray) -> np.ndarray:
    """The back light seen through the empty tube: a smooth lamp, the bore, the dark walls."""
    h = s.height_px
    yr = rows / h - 0.5
    lamp = s.lamp * (1.0 - 0.18 * yr ** 2 + 0.03 * yr)[:, None] * (1.0 - 0.02 * (cols_mm / s.bore_mm) ** 2)
    r = np.abs(cols_mm) / (0.5 * s.bore_mm)
    glass = np.where(r < 1.0, 0.93 - 0.18 * np.clip(r, 0, 1) ** 6, 1.0)   # darker near the bore's edge
    glass = np.where((r >= 1.0) & (r < 1.0 + 0.7 / (0.5 * s.bore_mm)), 0.2, glass)   # 0.7 mm walls
    return lamp * glass[None, :]


def _optical_depth(s: FluxScene, z_mm: np.ndarray, x_mm: np.ndarray, kern: np.ndarray,
                   dy_px: float = 0.0, dx_px: float = 0.0) -> np.ndarray:
    """Sum of the grains' optical depths on the pixel grid (H x W); pixel ``(r, c)`` covers
    ``z in [r, r+1) * mm_per_px`` and ``x in [c - W/2, c + 1 - W/2) * mm_per_px``."""
    h, w = s.height_px, s.width_px
    pad = kern.shape[0]
    py = z_mm / s.mm_per_px - 0.5 + dy_px + pad                 # pixel-centre coordinates, padded grid
    px = x_mm / s.mm_per_px + 0.5 * w - 0.5 + dx_px + pad
    H, W = h + 2 * pad, w + 2 * pad
    keep = (py >= 0) & (py < H - 1) & (px >= 0) & (px < W - 1)
    py, px = py[keep], px[keep]
    iy, ix = np.floor(py).astype(np.intp), np.floor(px).astype(np.intp)
    fy, fx = py - iy, px - ix
    grid = np.zeros(H * W)
    base = iy * W + ix
    for oy, ox, wt in ((0, 0, (1 - fy) * (1 - fx)), (0, 1, (1 - fy) * fx), (1, 0, fy * (1 - fx)), (1, 1, fy * fx)):
        grid += np.bincount(base + oy * W + ox, weights=wt, minlength=H * W)
    tau = ndimage.convolve(grid.reshape(H, W), kern, mode="constant")
    return tau[pad:pad + h, pad:pad + w]


# ----------------------------------------------------------------------------------------------- kinematics
def _pattern(rng: np.random.Generator, s: FluxScene, lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:
    """Alternating bubble/plug intervals covering ``[lo, hi]`` (pattern frame, mm): edges and compactness."""
    edges = [lo - rng.uniform(0.0, s.plug_mm[1] + s.bubble_mm[1])]
    comp = []
    plug = bool(rng.random() < 0.5)
    while edges[-1] < hi:
        length = rng.uniform(*(s.plug_mm if plug else s.bubble_mm))
        edges.append(edges[-1] + length)
        comp.append(s.c_plug if plug else s.c_bubble)
        plug = not plug
    return np.asarray(edges), np.asarray(comp)


def _shake(rng: np.random.Generator, s: FluxScene, t: np.ndarray) -> np.ndarray:
    """Camera shake (2 x T, px): a few incommensurate sines and a little jitter, peak ``shake_px``."""
    out = np.zeros((2, len(t)))
    if s.shake_px <= 0:
        return out
    for ax in range(2):
        for amp, f in zip((1.0, 0.6, 0.35), rng.uniform(2.0, 35.0, 3), strict=True):
            out[ax] += amp * np.sin(2 * math.pi * f * t + rng.uniform(0, 2 * math.pi))
        out[ax] += 0.25 * rng.standard_normal(len(t))
        out[ax] *= s.shake_px / max(float(np.abs(out[ax]).max()), 1e-9)
    return out


@dataclass(frozen=True)
class _Flow:
    t: np.ndarray             # frame times, s
    shift: np.ndarray         # U t + a(t), mm: the pattern frame's displacement
    edges: np.ndarray         # pattern edges (pattern frame, mm)
    comp: np.ndarray          # compactness between edges
    mass: np.ndarray          # M at the edges
    labels: np.ndarray        # grains' mass labels at t = 0
    x: np.ndarray             # grains' image-plane coordinate, mm from the axis
    q: float                  # q' = dm/dt (mm/s)
    phase: float              # the oscillation's phase


def _shift(s: FluxScene, phase: float, t: np.ndarray) -> np.ndarray:
    """The pattern frame's displacement ``U t + a(t)`` (mm) at times ``t``."""
    osc = s.oscillation_mm * np.sin(2 * math.pi * s.oscillation_hz * t + phase) if s.oscillation_mm > 0 else 0 * t
    return s.celerity_mm_s * t + osc


def _flow(rng: np.random.Generator, s: FluxScene) -> _Flow:
    t = np.arange(s.n_frames) / s.fps
    phase = float(rng.uniform(0.0, 2 * math.pi))
    shift = _shift(s, phase, t)
    margin = 3.0 * s.grain_mm + 2.0
    view = s.height_px * s.mm_per_px
    lo, hi = -margin - shift.max(), view + margin - shift.min()
    edges, comp = _pattern(rng, s, lo - 5.0, hi + 5.0)
    mass = np.concatenate([[0.0], np.cumsum(comp * np.diff(edges))])
    q = s.c_plug * (s.creep_mm_s - s.celerity_mm_s)
    duration = t[-1] - t[0] if len(t) > 1 else 0.0
    per_mass = _area(s) / _grain_volume(s)                       # grains per unit M (mm)
    m_lo, m_hi = mass[0] - q * duration, mass[-1]
    n = int(rng.poisson(per_mass * (m_hi - m_lo)))
    labels = np.sort(rng.uniform(m_lo, m_hi, n))
    x = _cross_section(rng, n, 0.5 * s.bore_mm)
    return _Flow(t=t, shift=shift, edges=edges, comp=comp, mass=mass, labels=labels, x=x, q=q, phase=phase)


def _positions(f: _Flow, k: int) -> np.ndarray:
    """Every grain's lab position ``z`` (mm, downwards) at frame ``k``."""
    zeta = np.interp(f.labels + f.q * f.t[k], f.mass, f.edges)
    return zeta + f.shift[k]


# ----------------------------------------------------------------------------------------------- rendering
def _camera(s: FluxScene, clean: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    return np.clip(np.rint(clean + rng.normal(0.0, s.noise, clean.shape)), 0, 255).astype(np.uint8)


def _cols_mm(s: FluxScene, dx_px: float = 0.0) -> np.ndarray:
    return (np.arange(s.width_px) + 0.5 - 0.5 * s.width_px + dx_px) * s.mm_per_px


def render_frames(scene: FluxScene, seed: int = 0) -> tuple[np.ndarray, FluxTruth]:
    """The movie (``T x H x W`` uint8) and its truth."""
    s = scene
    rng = np.random.default_rng(seed)
    f = _flow(rng, s)
    shake = _shake(rng, s, f.t)
    sigma = _sigma(s)
    kern = _sphere_kernel(s, sigma)
    h, w = s.height_px, s.width_px
    rows = np.arange(h, dtype=float)
    z_s = 0.5 * h * s.mm_per_px
    view_lo, view_hi = -2.0 * s.grain_mm - 1.0, h * s.mm_per_px + 2.0 * s.grain_mm + 1.0
    frames = np.empty((s.n_frames, h, w), np.uint8)
    down = up = 0
    prev_below = None
    net_boundaries = 0              # crossings of every row boundary (rows 1 .. h-1 of the view), net downwards
    prev_idx = None
    near = []                       # grains within +-1 mm of the section, each frame
    plug_mask = np.zeros((s.n_frames, h), bool)
    row_mid = (rows + 0.5) * s.mm_per_px
    is_plug = f.comp >= 0.5 * (s.c_plug + s.c_bubble)
    for k in range(s.n_frames):
        z = _positions(f, k)
        below = z > z_s
        if prev_below is not None:
            down += int(np.count_nonzero(below & ~prev_below))
            up += int(np.count_nonzero(~below & prev_below))
        prev_below = below
        idx = np.clip(np.floor(z / s.mm_per_px), 0, h - 1).astype(np.int64)  # boundaries above the grain
        if prev_idx is not None:
            net_boundaries += int((idx - prev_idx).sum())
        prev_idx = idx
        near.append(int(np.count_nonzero(np.abs(z - z_s) < 1.0)))
        i = np.clip(np.searchsorted(f.edges, row_mid - f.shift[k], "right") - 1, 0, len(f.comp) - 1)
        plug_mask[k] = is_plug[i]
        vis = (z > view_lo) & (z < view_hi)
        dy, dx = shake[0, k], shake[1, k]
        tau = _optical_depth(s, z[vis], f.x[vis], kern, dy, dx)
        light = _lamp(s, rows + dy, _cols_mm(s, -dx))
        frames[k] = _camera(s, light * np.exp(-tau), rng)
    duration = (s.n_frames - 1) / s.fps
    m_grain = RHO_S * _grain_volume(s) * 1e-9 * 1e3            # g
    rate = (down - up) * m_grain / duration if duration > 0 else 0.0
    view_rate = net_boundaries / (h - 1) * m_grain / duration if duration > 0 else 0.0
    # the pattern's time fraction of plug at the section, finely sampled in time
    tt = np.linspace(0.0, duration, 40 * max(s.n_frames, 2))
    sh = _shift(s, f.phase, tt)
    j = np.clip(np.searchsorted(f.edges, z_s - sh, "right") - 1, 0, len(f.comp) - 1)
    c_at = f.comp[j]
    frac = float(np.mean(is_plug[j]))
    c_mean = float(np.mean(c_at))
    area = _area(s)
    jump = RHO_S * area * 1e-6 * (s.c_plug * s.creep_mm_s + s.celerity_mm_s * (c_mean - s.c_plug)) * 1e-3 * 1e3
    da = 2 * math.pi * s.oscillation_hz * s.oscillation_mm * np.cos(2 * math.pi * s.oscillation_hz * tt + f.phase)
    osc_term = RHO_S * area * 1e-6 * float(np.mean(c_at * da)) * 1e-3 * 1e3 if s.oscillation_mm > 0 else 0.0
    counted_c = float(np.mean(near)) * _grain_volume(s) / (area * 2.0)
    # the plugs and bubbles that are seen: those meeting the field of view at some time
    seen_lo, seen_hi = -f.shift.max(), h * s.mm_per_px - f.shift.min()
    seen = (f.edges[1:] > seen_lo) & (f.edges[:-1] < seen_hi)
    lengths = np.diff(f.edges)
    truth = FluxTruth(
        mass_flow_rate_g_s=float(rate), view_mass_flow_rate_g_s=float(view_rate), crossings_down=down,
        crossings_up=up, duration_s=float(duration),
        grain_mass_g=float(m_grain), section_row=h // 2, section_mm=float(z_s),
        c_plug=s.c_plug, c_bubble=s.c_bubble, creep_m_s=s.creep_mm_s / 1e3, celerity_m_s=s.celerity_mm_s / 1e3,
        fall_m_s=s.fall_mm_s / 1e3, mean_compactness_at_section=c_mean,
        counted_compactness_at_section=counted_c, plug_fraction_at_section=frac,
        jump_mass_flow_rate_g_s=float(jump), oscillation_mass_flow_rate_g_s=float(osc_term),
        plug_lengths_mm=tuple(float(v) for v in lengths[seen & is_plug]),
        bubble_lengths_mm=tuple(float(v) for v in lengths[seen & ~is_plug]),
        mm_per_px=s.mm_per_px, bore_mm=s.bore_mm, grain_mm=s.grain_mm,
        packed_centre_transmission=s.packed_centre_transmission, sigma=sigma, plug_mask=plug_mask,
    )
    return frames, truth


def write_movie(path: str | Path, frames: np.ndarray, *, fps: float, fmt: str = "tif", crf: int = 20) -> None:
    """Write ``frames`` (uint8 ``T x H x W``) as an ImageJ TIFF stack (frame interval in its metadata) or an
    H.264 MP4 (libx264, yuv420p, even size)."""
    path = Path(path)
    if fmt == "tif":
        import tifffile

        tifffile.imwrite(path, frames, imagej=True, metadata={"axes": "TYX", "finterval": 1.0 / fps})
        return
    if fmt != "h264":
        raise ValueError(f"unknown format {fmt!r}")
    import av

    _, h, w = frames.shape
    h, w = h - h % 2, w - w % 2
    container = av.open(str(path), mode="w")
    try:
        stream = container.add_stream("libx264", rate=int(round(fps)))
        stream.width, stream.height, stream.pix_fmt = w, h, "yuv420p"
        stream.options = {"crf": str(crf), "preset": "fast"}
        for img in frames:
            container.mux(stream.encode(av.VideoFrame.from_ndarray(np.ascontiguousarray(img[:h, :w]), format="gray")))
        container.mux(stream.encode(None))
    finally:
        container.close()


def render_movie(path: str | Path, scene: FluxScene, seed: int = 0) -> FluxTruth:
    """Render ``scene`` with ``seed``, write it to ``path`` and return the truth."""
    frames, truth = render_frames(scene, seed)
    write_movie(path, frames, fps=scene.fps, fmt=scene.fmt, crf=scene.crf)
    return truth


# ----------------------------------------------------------------------------------------------- references
def empty_image(scene: FluxScene, seed: int = 0, *, exposures: int = 8) -> np.ndarray:
    """The tube with no grains (mean of ``exposures`` noisy frames, rounded to uint8)."""
    rng = np.random.default_rng(seed + 7919)
    light = _lamp(scene, np.arange(scene.height_px, dtype=float), _cols_mm(scene))
    acc = np.mean([_camera(scene, light, rng).astype(float) for _ in range(exposures)], axis=0)
    return np.clip(np.rint(acc), 0, 255).astype(np.uint8)


def packed_image(scene: FluxScene, seed: int = 0, *, exposures: int = 8) -> tuple[np.ndarray, float]:
    """The tube full of still grains at compactness ``scene.c_plug`` (mean of ``exposures`` noisy frames,
    uint8) and the compactness actually rendered (the grains' volume over the tube's, over the view)."""
    s = scene
    rng = np.random.default_rng(seed + 104729)
    lo, hi = -2.0, s.height_px * s.mm_per_px + 2.0
    n = int(rng.poisson(s.c_plug * _area(s) * (hi - lo) / _grain_volume(s)))
    z = rng.uniform(lo, hi, n)
    x = _cross_section(rng, n, 0.5 * s.bore_mm)
    tau = _optical_depth(s, z, x, _sphere_kernel(s, _sigma(s)))
    light = _lamp(s, np.arange(s.height_px, dtype=float), _cols_mm(s)) * np.exp(-tau)
    acc = np.mean([_camera(s, light, rng).astype(float) for _ in range(exposures)], axis=0)
    inside = (z >= 0) & (z < s.height_px * s.mm_per_px)
    c = float(np.count_nonzero(inside) * _grain_volume(s) / (_area(s) * s.height_px * s.mm_per_px))
    return np.clip(np.rint(acc), 0, 255).astype(np.uint8), c


def write_references(folder: str | Path, scene: FluxScene, seed: int = 0) -> tuple[Path, Path, float]:
    """Write ``empty.tif`` and ``packed.tif`` (single frames) into ``folder``; return their paths and the packed
    compactness."""
    import tifffile

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    empty_path, packed_path = folder / "empty.tif", folder / "packed.tif"
    tifffile.imwrite(empty_path, empty_image(scene, seed))
    packed, c = packed_image(scene, seed)
    tifffile.imwrite(packed_path, packed)
    return empty_path, packed_path, c


# ----------------------------------------------------------------------------------------------- cases
#: the validation cases: (name, scene, seed)
CASES: tuple[tuple[str, FluxScene, int], ...] = (
    ("flux: creep 4 mm/s, climb 30 mm/s, 250 fps, TIFF",
     FluxScene(creep_mm_s=4.0, celerity_mm_s=-30.0, c_bubble=0.02), 1),
    ("flux: creep 6 mm/s, climb 65 mm/s, 250 fps, TIFF",
     FluxScene(creep_mm_s=6.0, celerity_mm_s=-65.0, c_bubble=0.04), 2),
    ("flux: creep 5 mm/s, climb 45 mm/s, 500 fps, TIFF",
     FluxScene(fps=500.0, n_frames=1000, c_bubble=0.03), 3),
    ("flux: creep 5 mm/s, climb 45 mm/s, 250 fps, H.264",
     FluxScene(fmt="h264"), 4),
    ("flux: creep 4 mm/s, climb 65 mm/s, 500 fps, H.264",
     FluxScene(fps=500.0, n_frames=1000, creep_mm_s=4.0, celerity_mm_s=-65.0, c_bubble=0.04, fmt="h264"), 5),
    ("flux: oscillating 1 mm at 6 Hz, creep 5 mm/s, climb 30 mm/s, TIFF",
     FluxScene(n_frames=501, celerity_mm_s=-30.0, c_bubble=0.02, oscillation_mm=1.0, oscillation_hz=6.0), 6),
    ("flux: shake 1.5 px, creep 5 mm/s, climb 45 mm/s, 250 fps, H.264",
     FluxScene(shake_px=1.5, fmt="h264"), 7),
)

#: further scenes for a benchmark, not to tune on: (name, scene, seed)
HELD_OUT: tuple[tuple[str, FluxScene, int], ...] = (
    ("held-out: 0.25 mm grains, c_b 0.015, short plugs, 400 fps, TIFF",
     FluxScene(fps=400.0, n_frames=800, grain_mm=0.25, c_bubble=0.015, creep_mm_s=4.5, celerity_mm_s=-35.0,
               plug_mm=(12.0, 22.0), bubble_mm=(8.0, 15.0), c_plug=0.56), 101),
    ("held-out: 0.4 mm grains, c_b 0.05, long plugs, 300 fps, H.264",
     FluxScene(fps=300.0, n_frames=600, grain_mm=0.4, c_bubble=0.05, creep_mm_s=5.5, celerity_mm_s=-60.0,
               plug_mm=(25.0, 40.0), bubble_mm=(15.0, 25.0), c_plug=0.6, fmt="h264", crf=23), 102),
    ("held-out: darker packing (15 %), creep 6 mm/s, climb 50 mm/s, 250 fps, TIFF",
     FluxScene(creep_mm_s=6.0, celerity_mm_s=-50.0, c_bubble=0.035, packed_centre_transmission=0.15,
               c_plug=0.57), 103),
    ("held-out: oscillating 0.6 mm at 9 Hz, shake 1 px, climb 40 mm/s, 500 fps, H.264",
     FluxScene(fps=500.0, n_frames=1001, creep_mm_s=4.0, celerity_mm_s=-40.0, c_bubble=0.025,
               oscillation_mm=0.6, oscillation_hz=9.0, shake_px=1.0, packed_centre_transmission=0.33,
               fmt="h264"), 104),
)


def case(name: str) -> tuple[FluxScene, int]:
    """The scene and seed of the case (or held-out scene) called ``name``."""
    table = {n: (sc, sd) for n, sc, sd in CASES + HELD_OUT}
    return table[name]
