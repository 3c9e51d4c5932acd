"""An independent renderer of packed grains creeping inside climbing plugs, for the grain-velocity tests.

It shares no code with :mod:`grainplug.synthetic`, ``tests/lab_nuisances.py`` or ``tests/compactness_render.py``.

A vertical glass tube (flow downwards, image rows increasing) is seen in back light. The grains are drawn
as discs (each absorbs like a sphere: along a chord ``sqrt(1 - r^2 / a^2)``) scattered at random, about three
layers deep, on a long strip that moves downwards at the grains' speed. The plug *pattern* (where the tube
is packed) is another set of intervals that climbs at the celerity: a row of the image shows the packed
strip where the pattern says plug, and a sparse strip of grains falling fast where it says bubble. So grains
join a plug at its top and rain off its bottom while the texture inside creeps downstream: the truth is
the strip's speed, known exactly.

In the oscillating cases the pattern and the packed strip move together (the grains move with the plugs):
position ``v t + A sin(2 pi f t + phi)`` (``phi`` at random); the truth is the grains' displacement over
the record over its duration.

Light through the bore is attenuated along the chord at each column (``exp(-k * chord / bore * density)``);
the walls are dark lines; a ruler with irregular ticks and specks sits beside the tube (it moves with the
camera, as everything does when the camera shakes). Shake is a few sinusoids plus jitter, both axes. The
camera adds noise and rounds to 8 bits; the movie is written as a TIFF stack or H.264.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy import ndimage


@dataclass(frozen=True)
class CreepScene:
    """What is filmed and how."""

    fps: float = 250.0
    n_frames: int = 500
    height_px: int = 640
    width_px: int = 96
    mm_per_px: float = 0.1
    bore_mm: float = 3.0
    grain_mm: float = 0.45          # grain diameter
    grain_mm_s: float = 5.0         # the packed grains' speed, downstream positive
    celerity_mm_s: float = -45.0    # the plug pattern's speed (negative: climbing)
    plug_mm: tuple[float, float] = (8.0, 20.0)
    bubble_mm: tuple[float, float] = (4.0, 10.0)
    fall_mm_s: float = 600.0        # grains raining through the bubbles
    oscillation_mm: float = 0.0     # amplitude of the pattern-and-grains oscillation (0: creep)
    oscillation_hz: float = 6.0
    texture: float = 1.0            # 1: discs as drawn; 0: a uniform packed bed (no texture)
    shake_px: float = 1.5
    noise: float = 2.0
    lamp: float = 200.0
    fmt: str = "tif"
    crf: int = 23


@dataclass(frozen=True)
class CreepTruth:
    """The known answer: the packed grains' mean velocity over the record (m/s, downstream positive: their
    displacement from the first frame to the last over the time between) and at each frame."""

    grain_velocity_m_s: float
    grain_velocity_per_frame_m_s: np.ndarray


def _discs(rng: np.random.Generator, rows: int, width: int, radius_px: float, layers: float) -> np.ndarray:
    """A strip ``rows x width`` of random sphere-like discs about ``layers`` deep, scaled to mean 1."""
    n = int(layers * rows * width / (math.pi * radius_px**2))
    field = np.zeros((rows, width))
    ys, xs = rng.uniform(0, rows, n), rng.uniform(0, width, n)
    k = int(math.ceil(radius_px)) + 1
    oy, ox = np.mgrid[-k:k + 1, -k:k + 1]
    for y, x in zip(ys, xs, strict=True):
        iy, ix = int(y), int(x)
        r2 = ((oy + iy - y + 0.5) ** 2 + (ox + ix - x + 0.5) ** 2) / radius_px**2
        prof = np.sqrt(np.clip(1.0 - r2, 0.0, None))
        y0, x0 = iy - k, ix - k
        sy = slice(max(y0, 0), min(y0 + 2 * k + 1, rows))
        sx = slice(max(x0, 0), min(x0 + 2 * k + 1, width))
        field[sy, sx] += prof[sy.start - y0:sy.stop - y0, sx.start - x0:sx.stop - x0]
    return field / max(field.mean(), 1e-12)


def _intervals(rng: np.random.Generator, total: float, plug: tuple[float, float],
               bubble: tuple[float, float]) -> np.ndarray:
    """Alternating plug intervals ``[start, stop)`` (px) covering ``[0, total)``."""
    out, u = [], float(rng.uniform(0, bubble[1]))
    while u < total:
        p = rng.uniform(*plug)
        out.append((u, u + p))
        u += p + rng.uniform(*bubble)
    return np.array(out)


def render_frames(scene: CreepScene, rng: np.random.Generator) -> tuple[np.ndarray, CreepTruth]:
    """The movie ``T x H x W`` (uint8) and its truth."""
    s = scene
    h, w, t_n = s.height_px, s.width_px, s.n_frames
    px_mm = 1.0 / s.mm_per_px
    t = np.arange(t_n) / s.fps
    phase = rng.uniform(0.0, 2 * math.pi) if s.oscillation_mm > 0 else 0.0  # the camera starts at any phase
    osc = s.oscillation_mm * np.sin(2 * math.pi * s.oscillation_hz * t + phase)
    grain_px = (s.grain_mm_s * t + osc) * px_mm              # packed strip displacement (down +)
    if s.oscillation_mm > 0:                                  # the plugs move with their grains
        pattern_px = grain_px.copy()
    else:
        pattern_px = s.celerity_mm_s * t * px_mm
    fall_px = s.fall_mm_s * t * px_mm
    span = lambda d: int(h + np.ptp(d) + 40)  # noqa: E731
    radius = 0.5 * s.grain_mm * px_mm
    bore = s.bore_mm * px_mm
    strip_w = int(math.ceil(bore)) + 4
    packed = _discs(rng, span(grain_px), strip_w, radius, 3.0)
    packed = 1.0 + s.texture * (packed - 1.0)
    falling = 0.06 * _discs(rng, span(fall_px), strip_w, radius, 0.15)
    plugs = _intervals(rng, span(pattern_px) * 1.0, tuple(px_mm * np.array(s.plug_mm)),
                       tuple(px_mm * np.array(s.bubble_mm)))
    ruler = rng.uniform(0.55, 1.0, int(h + 40))              # irregular ticks beside the tube
    ruler[rng.random(len(ruler)) < 0.6] = 1.0
    ruler = ndimage.gaussian_filter1d(ruler, 0.8)
    # camera shake: a few sines plus jitter, peak about shake_px on each axis
    shake = np.zeros((2, t_n))
    for ax in range(2):
        for f in rng.uniform(3.0, 40.0, 3):
            shake[ax] += np.sin(2 * math.pi * f * t + rng.uniform(0, 2 * math.pi))
        shake[ax] += 0.5 * rng.normal(size=t_n)
        shake[ax] *= s.shake_px / max(np.abs(shake[ax]).max(), 1e-9)
    xc = w / 2.0
    rows = np.arange(h, dtype=float)[:, None]
    cols = np.arange(w, dtype=float)[None, :]
    frames = np.empty((t_n, h, w), np.uint8)
    hi_g, hi_p, hi_f = grain_px.max(), pattern_px.max(), fall_px.max()
    starts, stops = plugs[:, 0], plugs[:, 1]
    for k in range(t_n):
        y = rows + shake[0, k] + 20.0
        x = cols + shake[1, k] - xc                          # from the tube's axis
        r = np.abs(x) / (bore / 2.0)
        chord = np.sqrt(np.clip(1.0 - r**2, 0.0, None))
        xs = np.broadcast_to(x + strip_w / 2.0, (h, w))
        # packed strip: what is at row y now was at y - displacement (down +)
        yy = np.broadcast_to(y + (hi_g - grain_px[k]), (h, w))
        dens_p = ndimage.map_coordinates(packed, [yy, xs], order=1, mode="nearest")
        yy = np.broadcast_to(y + (hi_f - fall_px[k]), (h, w))
        dens_f = ndimage.map_coordinates(falling, [yy, xs], order=1, mode="nearest")
        u = (y + (hi_p - pattern_px[k]))[:, 0]                # the pattern's own coordinate
        i = np.searchsorted(starts, u, "right") - 1
        ok = i >= 0
        ii = np.clip(i, 0, None)
        inside = ok & (u < stops[ii])
        # soft edges (about a grain): distance to the nearest edge of the interval
        d = np.where(inside, np.minimum(u - starts[ii], stops[ii] - u), 0.0)
        share = np.where(inside, np.clip(0.5 + d / (2 * radius), 0.0, 1.0), 0.0)[:, None]
        dens = share * dens_p + (1 - share) * dens_f
        light = s.lamp * (1 - 0.1 * ((rows / h) - 0.5) ** 2) * np.exp(-1.6 * chord * dens)
        wall = (r >= 1.0) & (r < 1.0 + 3.0 / (bore / 2.0))
        light = np.where(wall, 0.25 * s.lamp, light)
        side = np.clip(np.round(y).astype(int), 0, len(ruler) - 1)
        beside = (x > bore / 2.0 + 8) & (x < bore / 2.0 + 16)
        light = np.where(beside, light * ruler[side], light)
        light = light + rng.normal(0.0, s.noise, light.shape)
        frames[k] = np.clip(np.round(light), 0, 255).astype(np.uint8)
    v = np.gradient(grain_px, t) / px_mm / 1000.0 if t_n > 1 else np.zeros(t_n)
    # the record's mean: the grains' displacement over the record (with an oscillation, not quite grain_mm_s)
    mean = float((grain_px[-1] - grain_px[0]) / (t[-1] - t[0]) / px_mm / 1000.0) if t_n > 1 else 0.0
    return frames, CreepTruth(grain_velocity_m_s=mean, grain_velocity_per_frame_m_s=v)


def write_movie(path: str | Path, frames: np.ndarray, *, fps: float, fmt: str = "tif", crf: int = 23) -> None:
    """Write ``frames`` (uint8, ``T x H x W``) as a TIFF stack or an H.264 MP4 (libx264, yuv420p)."""
    path = Path(path)
    if fmt == "tif":
        import tifffile

        with tifffile.TiffWriter(path) as tif:
            for k, f in enumerate(frames):
                tif.write(f, contiguous=True, metadata={"fps": fps} if k == 0 else None)
        return
    if fmt != "h264":
        raise ValueError(f"unknown format {fmt!r}")
    import av

    h, w = frames.shape[1] - frames.shape[1] % 2, frames.shape[2] - frames.shape[2] % 2
    with av.open(str(path), "w") as out:
        stream = out.add_stream("libx264", rate=int(round(fps)))
        stream.width, stream.height, stream.pix_fmt = w, h, "yuv420p"
        stream.options = {"crf": str(crf), "preset": "veryfast"}
        for f in frames:
            for packet in stream.encode(av.VideoFrame.from_ndarray(np.ascontiguousarray(f[:h, :w]), format="gray")):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)


def render_movie(path: str | Path, scene: CreepScene, seed: int = 0) -> CreepTruth:
    """Render ``scene`` with ``seed`` and write it to ``path``; return the truth."""
    frames, truth = render_frames(scene, np.random.default_rng(seed))
    write_movie(path, frames, fps=scene.fps, fmt=scene.fmt, crf=scene.crf)
    return truth


#: the validation cases: (name, scene)
CASES: tuple[tuple[str, CreepScene], ...] = (
    ("creep 4 mm/s, climb 30 mm/s, 250 fps, TIFF", CreepScene(grain_mm_s=4.0, celerity_mm_s=-30.0)),
    ("creep 6 mm/s, climb 65 mm/s, 250 fps, TIFF", CreepScene(grain_mm_s=6.0, celerity_mm_s=-65.0)),
    ("creep 5 mm/s, climb 45 mm/s, 500 fps, TIFF", CreepScene(fps=500.0, n_frames=800, grain_mm_s=5.0)),
    ("creep 5 mm/s, climb 45 mm/s, 250 fps, H.264", CreepScene(fmt="h264")),
    ("creep 4 mm/s, climb 65 mm/s, 500 fps, H.264", CreepScene(fps=500.0, n_frames=800, grain_mm_s=4.0,
                                                                celerity_mm_s=-65.0, fmt="h264")),
    ("oscillating 1 mm at 6 Hz, mean 5 mm/s, TIFF", CreepScene(oscillation_mm=1.0, celerity_mm_s=0.0)),
    ("oscillating 0.5 mm at 10 Hz, mean 3 mm/s, H.264", CreepScene(oscillation_mm=0.5, oscillation_hz=10.0,
                                                                   grain_mm_s=3.0, fmt="h264")),
)


def scene(name: str) -> CreepScene:
    """The case called ``name``."""
    return dict(CASES)[name]


def with_format(s: CreepScene, fmt: str) -> CreepScene:
    """``s`` written as ``fmt``."""
    return replace(s, fmt=fmt)
