"""Movies of plug flow in a glass tube with the nuisances of a real lab (issue "Right on a real lab's footage", item 7).

Independent of grainplug's own generator (``grainplug.synthetic``): it imports nothing from
grainplug. The tube's optics come from ``tube_optics.py`` (rays traced through the glass with
Fresnel reflections: the radiance across the tube with the bore full of air and of grains);
everything else is drawn here, in the **scene's** coordinates (mm along the tube from the top of
the undisturbed view, mm across from the axis), and every pixel is the exact average of the scene
over its square, so sub-pixel motion of the camera is real sub-pixel motion:

* along the tube, the plug occupancy of a pixel is the covered share of its extent (a cumulative
  length function of the plug intervals, exact); across, the radiance profiles are box-filtered
  over one pixel and interpolated at the pixel's centre;
* clamps, labels and the labels' printed marks are rectangles in the scene, their coverage of a
  pixel the product of the exact overlaps along and across.

The physics and geometry assumed, in the order they are applied to each frame:

1. **Kinematics.** A train of plugs (lengths ``plug_mm`` ± 6 %, bubbles ``bubble_mm`` ± 10 %,
   Gaussian) moves rigidly by ``X(t)`` (mm, positive downstream = down the image):
   propagative ``X = c t``; oscillating ``X = c t + A sin(2 pi f t)``; stick-slip: still for
   ``stick_fraction`` of each period, then one smooth (half-cosine) jump of ``c / f``; static
   ``X = 0``. Sparse grains fall through the bubbles at ``grain_speed_m_s`` (dark specks in back
   light, bright in front light), hidden inside plugs.
2. **Labels** (translucent, wrapped round the tube over its outer width): the light through them
   is multiplied by ``transmission``, the paper adds its own diffuse light (faint in back light,
   bright in front light), and printed marks (random bars) absorb ``ink`` of what remains.
3. **Clamps** (opaque, dark): replace the scene by ``level`` over the tube's outer width plus
   ``overhang_mm`` on each side.
4. **Passing shadows**: the scene (background, tube, clamps) is multiplied by
   ``1 - depth * g`` where ``g`` is a Gaussian band (or a tanh edge) moving along the tube at
   ``speed_mm_s``, switched on and off smoothly (50 ms) between ``t_on_s`` and ``t_off_s``.
5. **Lamp ripple**: the whole frame times ``(1 + depth sin(2 pi f_mains t + phase)) (1 + drift
   (t / T - 1/2))``, sampled at the frame times (a short exposure: a 100 Hz ripple at 250 fps is
   aliased, as a camera sees it).
6. **Camera shake**: the scene moves in the image by ``(dy, dx)`` px (along, across): a
   sinusoid of ``amplitude_px`` at ``frequency_hz`` (along and across in quadrature) plus a slow
   random wander (low-passed random walk, peak ``wander_px``).
7. **Camera**: Gaussian optical blur ``blur_px``, shot and read noise (``noise`` of the range,
   grey), 8 bits; lossless TIFF or H.264 (libx264, ``crf``).

The truth comes from the kinematics, never from the images: the celerity ``c`` (the train's mean
velocity), the mean length of the plugs seen whole in at least one frame (within the undisturbed
view; clamps and labels do not change what the plugs are), the mean length of the bubbles seen
whole likewise, the oscillation's frequency and amplitude (half the peak-to-peak of ``X - c t``),
and the regime (stick-slip counts as ``oscillating``, as grainplug names it).

Not modelled: perspective, a tilted or horizontal tube, the grains' texture inside plugs, plug
shapes (flat interfaces), motion blur during the exposure, rolling shutter, stray reflections of
the clamps, colour, and a camera that rotates rather than translates.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy import ndimage
from tube_optics import Lighting, profiles

#: file name suffix of each format
SUFFIX = {"tif": ".tif", "h264": ".mp4"}


@dataclass(frozen=True)
class Motion:
    """How the plug train moves.

    Attributes
    ----------
    regime : {"propagative", "oscillating", "stick-slip", "static"}
        Kind of motion (see the module's docstring).
    celerity_m_s : float
        Mean velocity of the train, m/s, positive downstream (climbing plugs: negative).
    frequency_hz : float
        Oscillation (or stick-slip) frequency.
    amplitude_mm : float
        Sinusoid amplitude (oscillating).
    stick_fraction : float
        Share of each period the train stands still (stick-slip).
    """

    regime: str = "propagative"
    celerity_m_s: float = -0.05
    frequency_hz: float = 0.0
    amplitude_mm: float = 0.0
    stick_fraction: float = 0.6

    def displacement_mm(self, t_s: np.ndarray) -> np.ndarray:
        """The train's displacement ``X(t)`` in mm (positive downstream), ``X(0) = 0``."""
        t = np.asarray(t_s, dtype=float)
        c = self.celerity_m_s * 1000.0
        if self.regime == "static":
            return np.zeros_like(t)
        if self.regime == "propagative":
            return c * t
        if self.regime == "oscillating":
            return c * t + self.amplitude_mm * np.sin(2 * math.pi * self.frequency_hz * t)
        if self.regime == "stick-slip":
            cycles = t * self.frequency_hz
            whole = np.floor(cycles)
            phase = cycles - whole
            slip = np.clip((phase - self.stick_fraction) / (1.0 - self.stick_fraction), 0.0, 1.0)
            return c / self.frequency_hz * (whole + 0.5 * (1.0 - np.cos(math.pi * slip)))
        raise ValueError(f"unknown regime {self.regime!r}")


@dataclass(frozen=True)
class Shake:
    """Camera shake: the whole image translated by a sinusoid plus a slow wander (pixels).

    Attributes
    ----------
    amplitude_px : float
        Amplitude of the sinusoid along the tube; across it is ``across_ratio`` times this.
    frequency_hz : float
        Frequency of the sinusoid.
    wander_px : float
        Peak of the slow random wander (both directions), over the record.
    across_ratio : float
        Across-the-tube amplitude over the along-the-tube one.
    """

    amplitude_px: float = 1.0
    frequency_hz: float = 30.0
    wander_px: float = 0.0
    across_ratio: float = 0.7


@dataclass(frozen=True)
class Ripple:
    """Lamp ripple at the mains' double frequency, and a slow drift of the light level.

    Attributes
    ----------
    depth : float
        Relative amplitude of the ripple (0.2 = +-20 %).
    mains_hz : float
        Ripple frequency: 100 Hz (50 Hz mains) or 120 Hz (60 Hz mains).
    drift : float
        Relative change of the level over the record (linear).
    phase : float
        Phase of the ripple at the first frame, rad.
    """

    depth: float = 0.2
    mains_hz: float = 100.0
    drift: float = 0.0
    phase: float = 0.4


@dataclass(frozen=True)
class Shadow:
    """A soft shadow moving along the tube.

    Attributes
    ----------
    depth : float
        Darkening at the shadow's core (0.5 = half the light).
    width_mm : float
        Standard deviation of the band (``kind="band"``) or the tanh edge's half-width.
    speed_mm_s : float
        Speed along the tube, mm/s (positive down the image).
    start_mm : float
        Centre (or edge) position at ``t = 0``, mm from the top of the view.
    t_on_s, t_off_s : float
        When the shadow is there (faded in and out over 50 ms).
    kind : {"band", "edge"}
        A dark band, or a dark half-space below a moving edge (a gradient).
    """

    depth: float = 0.4
    width_mm: float = 6.0
    speed_mm_s: float = 40.0
    start_mm: float = 10.0
    t_on_s: float = 0.0
    t_off_s: float = 1e9
    kind: str = "band"


@dataclass(frozen=True)
class Clamp:
    """An opaque clamp over the tube.

    Attributes
    ----------
    center_mm, length_mm : float
        Where it is along the tube (mm from the top of the view) and its length.
    overhang_mm : float
        How far beyond the tube's outer wall it reaches on each side.
    level : float
        Its radiance, as a share of the back-light's.
    """

    center_mm: float
    length_mm: float = 8.0
    overhang_mm: float = 1.5
    level: float = 0.03


@dataclass(frozen=True)
class Label:
    """A translucent printed label wrapped round the tube.

    Attributes
    ----------
    center_mm, length_mm : float
        Where it is along the tube and its length.
    transmission : float
        Share of the light through the tube that crosses the paper.
    ink : float
        Share of the remaining light the printed marks absorb.
    n_marks : int
        Number of printed marks (bars of random size and position).
    seed : int
        Seed of the marks' layout (the label is the same in every frame).
    """

    center_mm: float
    length_mm: float = 12.0
    transmission: float = 0.55
    ink: float = 0.6
    n_marks: int = 8
    seed: int = 7


@dataclass(frozen=True)
class Ruler:
    """A printed ruler standing beside the tube (in front of the lamp): dark ticks every ``pitch_mm``.

    Attributes
    ----------
    from_axis_mm : float
        Where its ticks start, across, from the tube's axis (on the right of the image).
    tick_mm : float
        The ticks' length across (every fifth twice as long).
    pitch_mm, line_mm : float
        Their spacing along the tube and their thickness.
    level : float
        The ticks' radiance, as a share of the back-light's.
    """

    from_axis_mm: float = 5.0
    tick_mm: float = 1.0
    pitch_mm: float = 1.0
    line_mm: float = 0.2
    level: float = 0.1


@dataclass(frozen=True)
class Scene:
    """Everything one movie holds: the tube, the flow, the nuisances, the camera.

    Attributes
    ----------
    lighting : str
        ``"back"`` (diffuse lamp behind the tube, 25 deg half-size) or ``"front"``.
    mm_per_px, height_px, width_px : float, int, int
        Scale, and the frame (rows along the tube, columns across it).
    inner_diameter_mm, outer_diameter_mm : float
        The tube (borosilicate, n = 1.47).
    n_frames, fps : int, float
        The record.
    plug_mm, bubble_mm : float
        Mean plug and bubble lengths of the train.
    plugs : bool
        False: the train's plugs are not drawn (an empty tube, for the renderer's own checks).
    motion : Motion
        The train's kinematics.
    grains_per_mm, grain_speed_m_s : float
        Falling grains in the bubbles (per mm of tube), and their speed (downstream).
    shake, ripple : Shake or None, Ripple or None
        Camera shake and lamp ripple.
    shadows, clamps, labels : tuple
        Passing shadows, clamps and labels.
    blur_px, noise : float
        Optical blur (Gaussian sigma) and grey noise (read noise, share of the range).
    shot : float
        Shot noise: its variance is ``shot`` times the pixel's value (in counts).
    fmt : {"tif", "h264"}
        Lossless TIFF stack or H.264 MP4.
    crf : int
        H.264 quality (higher: more loss).
    level : float
        The back-light's (or front-lit plug's) share of the sensor's range (0.6: a +40 % ripple just
        stays below saturation).
    """

    lighting: str = "back"
    mm_per_px: float = 0.15
    height_px: int = 600
    width_px: int = 100
    inner_diameter_mm: float = 3.0
    outer_diameter_mm: float = 5.5
    n_frames: int = 250
    fps: float = 250.0
    plug_mm: float = 14.0
    bubble_mm: float = 10.0
    plugs: bool = True
    motion: Motion = field(default_factory=Motion)
    grains_per_mm: float = 0.4
    grain_speed_m_s: float = 0.35
    shake: Shake | None = None
    ripple: Ripple | None = None
    shadows: tuple[Shadow, ...] = ()
    clamps: tuple[Clamp, ...] = ()
    labels: tuple[Label, ...] = ()
    rulers: tuple[Ruler, ...] = ()
    blur_px: float = 0.8
    noise: float = 0.01
    shot: float = 0.02
    fmt: str = "tif"
    crf: int = 28
    level: float = 0.6


@dataclass(frozen=True)
class Truth:
    """What a rendered movie holds, from the renderer's own kinematics.

    Attributes
    ----------
    celerity_m_s : float
        Mean velocity of the plug train (positive downstream).
    plug_length_mm, bubble_length_mm : float
        Mean length of the plugs (bubbles) seen whole in at least one frame.
    n_plugs_whole, n_bubbles_whole : int
        How many.
    frequency_hz, amplitude_mm : float or None
        Oscillation frequency, and half the peak-to-peak of ``X - c t`` (None unless oscillating).
    regime : str
        ``propagative``, ``oscillating`` (stick-slip included) or ``static``.
    mm_per_px, fps, n_frames : float, float, int
        The record.
    bore_px : float
        The bore's diameter in pixels.
    shake_px : ndarray
        ``(n_frames, 2)``: the image's displacement (along, across) in each frame, px.
    light : ndarray
        ``(n_frames,)``: the lamp's relative level in each frame (ripple and drift).
    displacement_mm : ndarray
        ``(n_frames,)``: the train's displacement ``X`` in each frame.
    """

    celerity_m_s: float
    plug_length_mm: float
    bubble_length_mm: float
    n_plugs_whole: int
    n_bubbles_whole: int
    frequency_hz: float | None
    amplitude_mm: float | None
    regime: str
    mm_per_px: float
    fps: float
    n_frames: int
    bore_px: float
    shake_px: np.ndarray
    light: np.ndarray
    displacement_mm: np.ndarray


def shake_px(shake: Shake | None, t_s: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The image's displacement ``(n, 2)`` (along, across) in px at times ``t_s`` (evenly spaced)."""
    t = np.asarray(t_s, dtype=float)
    out = np.zeros((len(t), 2))
    if shake is None:
        return out
    w = 2 * math.pi * shake.frequency_hz * t
    out[:, 0] = shake.amplitude_px * np.sin(w + 0.3)
    out[:, 1] = shake.across_ratio * shake.amplitude_px * np.cos(w + 0.3)
    if shake.wander_px > 0 and len(t) > 2:
        fps = 1.0 / float(t[1] - t[0])
        walk = np.cumsum(rng.standard_normal((len(t), 2)), axis=0)
        walk = ndimage.gaussian_filter1d(walk, sigma=0.1 * fps, axis=0, mode="nearest")  # slower than ~2 Hz
        walk -= walk.mean(axis=0)
        walk *= shake.wander_px / max(float(np.abs(walk).max()), 1e-12)
        out += walk
    return out


def light_level(ripple: Ripple | None, t_s: np.ndarray, duration_s: float) -> np.ndarray:
    """The lamp's relative level at times ``t_s`` (1 without ripple)."""
    t = np.asarray(t_s, dtype=float)
    if ripple is None:
        return np.ones_like(t)
    wave = 1.0 + ripple.depth * np.sin(2 * math.pi * ripple.mains_hz * t + ripple.phase)
    return wave * (1.0 + ripple.drift * (t / duration_s - 0.5))


def _overlap(lo: np.ndarray, hi: np.ndarray, a: float, b: float) -> np.ndarray:
    """Share of each interval ``[lo, hi]`` covered by ``[a, b]``."""
    return np.clip(np.minimum(hi, b) - np.maximum(lo, a), 0.0, None) / (hi - lo)


def _shadow_factor(shadows: tuple[Shadow, ...], s_mm: np.ndarray, t: float) -> np.ndarray:
    """Multiplicative darkening of the scene at positions ``s_mm`` along the tube, time ``t``."""
    f = np.ones_like(s_mm)
    for sh in shadows:
        fade_in = 1.0 if sh.t_on_s <= 0 else (t - sh.t_on_s) / 0.05
        env = float(np.clip(min(fade_in, (sh.t_off_s - t) / 0.05), 0.0, 1.0))
        if env <= 0:
            continue
        u = (s_mm - sh.start_mm - sh.speed_mm_s * t) / sh.width_mm
        g = np.exp(-0.5 * u * u) if sh.kind == "band" else 0.5 * (1.0 + np.tanh(u))
        f = f * (1.0 - sh.depth * env * g)
    return f


def _train(scene: Scene, x_mm: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Plug tops and lengths at ``t = 0`` covering the view at every displacement in ``x_mm``."""
    view = scene.height_px * scene.mm_per_px
    period = scene.plug_mm + scene.bubble_mm
    lo = -float(x_mm.max()) - 3 * period
    hi = view - float(x_mm.min()) + 3 * period
    tops, lengths = [], []
    s = lo + rng.uniform(0.0, period)
    while s < hi:
        ln = scene.plug_mm * (1 + 0.06 * rng.standard_normal())
        tops.append(s)
        lengths.append(ln)
        s += ln + scene.bubble_mm * (1 + 0.1 * rng.standard_normal())
    return np.array(tops), np.array(lengths)


def _truth(scene: Scene, tops: np.ndarray, lengths: np.ndarray, x_mm: np.ndarray, shake: np.ndarray,
           light: np.ndarray) -> Truth:
    view = scene.height_px * scene.mm_per_px
    bottoms = tops + lengths
    plugs, bubbles = set(), set()
    for x in x_mm:
        whole = (tops + x >= 0) & (bottoms + x <= view)
        plugs.update(np.flatnonzero(whole).tolist())
        gap = (bottoms[:-1] + x >= 0) & (tops[1:] + x <= view)
        bubbles.update(np.flatnonzero(gap).tolist())
    m = scene.motion
    osc = m.regime in ("oscillating", "stick-slip")
    amp = None
    if osc:
        t = np.linspace(0.0, 1.0 / m.frequency_hz, 2001)
        rest = m.displacement_mm(t) - m.celerity_m_s * 1000.0 * t
        amp = float(np.ptp(rest) / 2)
    gaps = tops[1:] - bottoms[:-1]
    return Truth(
        celerity_m_s=0.0 if m.regime == "static" else m.celerity_m_s,
        plug_length_mm=float(np.mean(lengths[sorted(plugs)])) if plugs else float("nan"),
        bubble_length_mm=float(np.mean(gaps[sorted(bubbles)])) if bubbles else float("nan"),
        n_plugs_whole=len(plugs), n_bubbles_whole=len(bubbles),
        frequency_hz=m.frequency_hz if osc else None, amplitude_mm=amp,
        regime="oscillating" if osc else m.regime,
        mm_per_px=scene.mm_per_px, fps=scene.fps, n_frames=scene.n_frames,
        bore_px=scene.inner_diameter_mm / scene.mm_per_px, shake_px=shake, light=light, displacement_mm=x_mm)


def render_frames(scene: Scene, rng: np.random.Generator) -> tuple[np.ndarray, Truth]:
    """Render the movie in memory: ``(n_frames, height, width)`` uint8, and its truth.

    Parameters
    ----------
    scene : Scene
        What to draw.
    rng : numpy.random.Generator
        Draws the plug train, the falling grains, the wander and the noise.

    Returns
    -------
    frames : ndarray
    truth : Truth
    """
    h, w, px = scene.height_px, scene.width_px, scene.mm_per_px
    t_all = np.arange(scene.n_frames) / scene.fps
    duration = scene.n_frames / scene.fps
    x_all = scene.motion.displacement_mm(t_all)
    tops, lengths = _train(scene, x_all, rng)
    if not scene.plugs:
        lengths = np.zeros_like(lengths)
    cum = np.concatenate([[0.0], np.cumsum(lengths)])
    shake = shake_px(scene.shake, t_all, rng)
    light = light_level(scene.ripple, t_all, duration)
    truth = _truth(scene, tops, lengths, x_all, shake, light)

    prof = profiles(inner_diameter_mm=scene.inner_diameter_mm, outer_diameter_mm=scene.outer_diameter_mm,
                    lighting=Lighting(scene.lighting, 25.0))
    step = float(prof.x_mm[1] - prof.x_mm[0])
    box = max(1, int(round(px / step)))
    kern = np.ones(box) / box
    xs = np.concatenate([-prof.x_mm[::-1], prof.x_mm])
    air = np.convolve(np.concatenate([prof.air[::-1], prof.air]), kern, mode="same")
    plug = np.convolve(np.concatenate([prof.plug[::-1], prof.plug]), kern, mode="same")
    x_edge = float(xs[-1]) - px  # beyond this the box-filtered profile is the background's
    outer_r = scene.outer_diameter_mm / 2
    inner_r = scene.inner_diameter_mm / 2
    paper = 0.08 if scene.lighting == "back" else 0.45  # a label's own diffuse light

    # falling grains: positions at t = 0 over a span the fastest of them sweeps, wrapped
    span = h * px + scene.grain_speed_m_s * 1000 * duration + 20.0
    n_grains = int(round(scene.grains_per_mm * span))
    g_s0 = rng.uniform(-span + h * px, h * px, n_grains)
    g_x = rng.uniform(-0.8 * inner_r, 0.8 * inner_r, n_grains)

    label_marks = []
    for lab in scene.labels:
        lr = np.random.default_rng(lab.seed)
        marks = []
        for _ in range(lab.n_marks):
            ln, wd = lr.uniform(0.4, 1.5), lr.uniform(0.3, 0.7) * 2 * outer_r
            s0 = lr.uniform(lab.center_mm - lab.length_mm / 2, lab.center_mm + lab.length_mm / 2 - ln)
            x0 = lr.uniform(-outer_r, outer_r - wd)
            marks.append((s0, s0 + ln, x0, x0 + wd))
        label_marks.append(marks)

    top = 255
    scale = scene.level * top / max(float(prof.air.max()), float(prof.plug.max()))
    rows = np.arange(h, dtype=float)
    cols = np.arange(w, dtype=float)
    frames = np.empty((scene.n_frames, h, w), np.uint8)
    for k, t in enumerate(t_all):
        dy, dx = shake[k]
        # scene coordinates of each pixel's extent (the image moved by +dy, +dx)
        s_lo, s_hi = (rows - dy) * px, (rows + 1 - dy) * px
        x_lo, x_hi = (cols - dx - w / 2) * px, (cols + 1 - dx - w / 2) * px
        x_c = 0.5 * (x_lo + x_hi)
        # the plug occupancy of each row: exact covered share, from the cumulative plug length
        a_lo, a_hi = s_lo - x_all[k], s_hi - x_all[k]

        def covered(s: np.ndarray) -> np.ndarray:
            i = np.clip(np.searchsorted(tops, s, side="right") - 1, 0, None)
            return cum[i] + np.clip(s - tops[i], 0.0, lengths[i])

        occ = (covered(a_hi) - covered(a_lo)) / (a_hi - a_lo)
        far = np.abs(x_c) >= x_edge
        air_c = np.where(far, prof.air[-1], np.interp(x_c, xs, air))
        plug_c = np.where(far, prof.plug[-1], np.interp(x_c, xs, plug))
        img = air_c[None, :] + occ[:, None] * (plug_c - air_c)[None, :]
        # falling grains, in the bubbles only
        if n_grains:
            gs = (g_s0 + scene.grain_speed_m_s * 1000 * t) % span - span + h * px
            rel = gs - x_all[k]
            i = np.clip(np.searchsorted(tops, rel, side="right") - 1, 0, None)
            free = rel >= tops[i] + lengths[i]
            r = gs[free] / px - 0.5 + dy
            c = g_x[free] / px + w / 2 - 0.5 + dx
            ok = (r >= 0) & (r < h - 1) & (c >= 0) & (c < w - 1)
            r, c = r[ok], c[ok]
            r0, c0 = np.floor(r).astype(int), np.floor(c).astype(int)
            fr, fc = r - r0, c - c0
            specks = np.zeros((h, w))
            for ddr, ddc, wt in ((0, 0, (1 - fr) * (1 - fc)), (1, 0, fr * (1 - fc)), (0, 1, (1 - fr) * fc),
                                 (1, 1, fr * fc)):
                np.add.at(specks, (r0 + ddr, c0 + ddc), wt)
            specks = np.clip(specks, 0.0, 1.0)
            img = img * (1 - 0.6 * specks) if scene.lighting == "back" else img + 0.4 * specks
        for lab, marks in zip(scene.labels, label_marks, strict=True):
            cov = _overlap(s_lo, s_hi, lab.center_mm - lab.length_mm / 2, lab.center_mm + lab.length_mm / 2)[:, None] \
                * _overlap(x_lo, x_hi, -outer_r, outer_r)[None, :]
            ink = np.zeros((h, w))
            for m0, m1, q0, q1 in marks:
                ink += _overlap(s_lo, s_hi, m0, m1)[:, None] * _overlap(x_lo, x_hi, q0, q1)[None, :]
            through = (lab.transmission * img + paper) * (1 - lab.ink * np.clip(ink, 0.0, 1.0))
            img = img * (1 - cov) + cov * through
        for cl in scene.clamps:
            half = outer_r + cl.overhang_mm
            cov = _overlap(s_lo, s_hi, cl.center_mm - cl.length_mm / 2, cl.center_mm + cl.length_mm / 2)[:, None] \
                * _overlap(x_lo, x_hi, -half, half)[None, :]
            img = img * (1 - cov) + cov * cl.level
        for ru in scene.rulers:
            ink = np.zeros((h, w))
            for j in range(int(np.floor(s_lo.min() / ru.pitch_mm)) - 1, int(np.ceil(s_hi.max() / ru.pitch_mm)) + 2):
                long = ru.tick_mm * (2.0 if j % 5 == 0 else 1.0)
                ink += _overlap(s_lo, s_hi, j * ru.pitch_mm, j * ru.pitch_mm + ru.line_mm)[:, None] \
                    * _overlap(x_lo, x_hi, ru.from_axis_mm, ru.from_axis_mm + long)[None, :]
            ink = np.clip(ink, 0.0, 1.0)
            img = img * (1 - ink) + ink * ru.level
        if scene.shadows:
            img = img * _shadow_factor(scene.shadows, 0.5 * (s_lo + s_hi), float(t))[:, None]
        img = img * light[k]
        if scene.blur_px > 0:
            img = ndimage.gaussian_filter(img, scene.blur_px, mode="nearest")
        img = img * scale
        img = img + rng.standard_normal(img.shape) * np.sqrt((scene.noise * top) ** 2 + scene.shot * np.maximum(img, 0))
        frames[k] = np.clip(np.round(img), 0, top).astype(np.uint8)
    return frames, truth


def write_movie(path: str | Path, frames: np.ndarray, *, fps: float, fmt: str = "tif", crf: int = 28) -> None:
    """Write ``frames`` (uint8, ``T x H x W``) as a TIFF stack or an H.264 MP4 (libx264, yuv420p, ``crf``)."""
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


def render_movie(path: str | Path, scene: Scene, rng: np.random.Generator) -> Truth:
    """Render ``scene`` and write it to ``path`` (its format is ``scene.fmt``); return the truth."""
    frames, truth = render_frames(scene, rng)
    write_movie(path, frames, fps=scene.fps, fmt=scene.fmt, crf=scene.crf)
    return truth


@dataclass(frozen=True)
class Case:
    """One case of the bench: a scene, how the scale is given, and its seed.

    Attributes
    ----------
    name : str
        Short, unique, readable.
    scene : Scene
    scale : {"given", "tube"}
        ``mm_per_px=`` given to the analysis, or only ``tube_diameter_mm`` (the scale from the tube).
    seed : int
    """

    name: str
    scene: Scene
    scale: str = "given"
    seed: int = 1

    def analysis_kwargs(self) -> dict[str, float]:
        """The keywords ``grainplug.analyze`` is given for this case."""
        kw: dict[str, float] = {"fps": self.scene.fps, "tube_diameter_mm": self.scene.inner_diameter_mm}
        if self.scale == "given":
            kw["mm_per_px"] = self.scene.mm_per_px
        return kw

    def movie_name(self) -> str:
        """A file name for the case's movie (the scale does not change the movie)."""
        stem = re.sub(r"[^a-z0-9]+", "_", self.name.lower()).strip("_")
        return f"{stem}{SUFFIX[self.scene.fmt]}"


# ---- the targets ----

#: celerity and plug-length tolerances, by how the scale is known
CELERITY_TOL = {"given": 0.03, "tube": 0.06}
LENGTH_TOL = {"given": 0.05, "tube": 0.08}
FREQUENCY_TOL_HZ = 0.3
#: the celerity's 95 % interval may miss the truth by this share of it and still count as holding it
CI_GRACE = 0.005


def truth_record(truth: Truth) -> dict[str, object]:
    """The truth's scalars as a plain dict (JSON-ready)."""
    keys = ("celerity_m_s", "plug_length_mm", "bubble_length_mm", "n_plugs_whole", "n_bubbles_whole",
            "frequency_hz", "amplitude_mm", "regime", "mm_per_px", "fps", "n_frames", "bore_px")
    return {k: getattr(truth, k) for k in keys}


def judge(case: Case, truth: dict[str, object], summary: dict[str, object]) -> dict[str, object]:
    """Errors of one analysis against the truth, and the targets it misses.

    Parameters
    ----------
    case : Case
    truth : dict
        :func:`truth_record` of the case's truth.
    summary : dict
        The analysis's ``summary``.

    Returns
    -------
    dict
        ``celerity_err``, ``plug_err``, ``bubble_err`` (relative, or None), ``f_err_hz``, ``ci_holds``
        (None for a static train), ``fails`` (names of the targets missed: regime, celerity, plug, f,
        CI) and ``ok``. A static train has no celerity target; the bubble length has no target.
    """
    def rel(m: object, t: object) -> float | None:
        return None if m is None or t is None or not t else float(m) / float(t) - 1.0

    moving = truth["regime"] != "static"
    ec = rel(summary.get("celerity_m_s"), truth["celerity_m_s"]) if moving else None
    el = rel(summary.get("plug_length_mm"), truth["plug_length_mm"])
    eb = rel(summary.get("bubble_length_mm"), truth["bubble_length_mm"])
    ft, fm = truth["frequency_hz"], summary.get("oscillation_frequency_hz")
    df = None if ft is None or fm is None else float(fm) - float(ft)
    ci = summary.get("celerity_ci95_m_s")
    ci_holds = None
    if moving:
        c = float(truth["celerity_m_s"])
        ci_holds = bool(ci) and None not in ci and max(min(ci) - c, c - max(ci), 0.0) <= CI_GRACE * abs(c)
    fails = []
    if summary.get("regime") != truth["regime"]:
        fails.append("regime")
    if moving and (ec is None or abs(ec) > CELERITY_TOL[case.scale]):
        fails.append("celerity")
    if el is None or abs(el) > LENGTH_TOL[case.scale]:
        fails.append("plug")
    if ft is not None and (df is None or abs(df) > FREQUENCY_TOL_HZ):
        fails.append("f")
    if moving and not ci_holds:
        fails.append("CI")
    return {"celerity_err": ec, "plug_err": el, "bubble_err": eb, "f_err_hz": df, "ci_holds": ci_holds,
            "fails": fails, "ok": not fails}


# ---- the bench ---------------------------------------------------------------------------------------------

#: the paper's plugs climb: celerities of the bench
_C = (-0.02, -0.05, -0.1)
#: a clamp and a label used across cases (mm from the top of a 90 mm view)
CLAMP = Clamp(center_mm=30.0, length_mm=8.0)
LABEL = Label(center_mm=62.0, length_mm=12.0)
OSC = Motion("oscillating", celerity_m_s=-0.01, frequency_hz=5.0, amplitude_mm=2.0)
STICK = Motion("stick-slip", celerity_m_s=-0.03, frequency_hz=4.0, stick_fraction=0.6)
_N_OSC = 300  # frames at 250 fps: 1.2 s, six periods of 5 Hz, 4.8 of 4 Hz


def _combined(**kw: object) -> Scene:
    base = Scene(shake=Shake(1.0, 30.0, wander_px=2.0), ripple=Ripple(0.2, 100.0, drift=0.1),
                 clamps=(CLAMP,), labels=(LABEL,), shadows=(Shadow(0.4, 6.0, 40.0, start_mm=5.0, t_on_s=0.1,
                                                                   t_off_s=0.9),))
    return replace(base, **kw)


def _cases() -> list[Case]:
    m = {c: Motion("propagative", c) for c in _C}
    out = [
        # references: no nuisance
        Case("clean c=-0.02", Scene(motion=m[-0.02])),
        Case("clean c=-0.05", Scene(motion=m[-0.05])),
        Case("clean c=-0.1", Scene(motion=m[-0.1])),
        Case("clean c=-0.05, front light", Scene(lighting="front", motion=m[-0.05])),
        Case("clean c=-0.05, scale from tube", Scene(motion=m[-0.05]), "tube"),
        Case("clean oscillating 5 Hz 2 mm", Scene(motion=OSC, n_frames=_N_OSC)),
        Case("clean static", Scene(motion=Motion("static"))),
        # camera shake
        Case("shake 0.5 px 10 Hz", Scene(shake=Shake(0.5, 10.0))),
        Case("shake 1.5 px 35 Hz", Scene(shake=Shake(1.5, 35.0))),
        Case("shake 2 px 5 Hz + wander 3 px", Scene(shake=Shake(2.0, 5.0, wander_px=3.0))),
        Case("shake 1 px 20 Hz + wander 3 px, c=-0.02", Scene(motion=m[-0.02], shake=Shake(1.0, 20.0, 3.0))),
        Case("shake 1.5 px 35 Hz, scale from tube", Scene(shake=Shake(1.5, 35.0)), "tube"),
        Case("shake 1.5 px 35 Hz, static plugs", Scene(motion=Motion("static"), shake=Shake(1.5, 35.0))),
        Case("shake 1 px 8 Hz, static plugs", Scene(motion=Motion("static"), shake=Shake(1.0, 8.0, 2.0))),
        Case("shake 1.5 px 35 Hz, oscillating 5 Hz", Scene(motion=OSC, n_frames=_N_OSC, shake=Shake(1.5, 35.0))),
        # lamp ripple
        Case("ripple 5 % 100 Hz", Scene(ripple=Ripple(0.05, 100.0))),
        Case("ripple 20 % 100 Hz + drift 10 %", Scene(ripple=Ripple(0.2, 100.0, drift=0.1))),
        Case("ripple 40 % 100 Hz", Scene(ripple=Ripple(0.4, 100.0))),
        Case("ripple 30 % 120 Hz, front light", Scene(lighting="front", ripple=Ripple(0.3, 120.0))),
        Case("ripple 40 % 120 Hz, scale from tube", Scene(ripple=Ripple(0.4, 120.0)), "tube"),
        # passing shadows
        Case("shadow band 30 % at 10 mm/s", Scene(shadows=(Shadow(0.3, 8.0, 10.0, start_mm=40.0),))),
        Case("shadow band 60 % at 60 mm/s", Scene(shadows=(Shadow(0.6, 6.0, 60.0, start_mm=5.0, t_on_s=0.1,
                                                                  t_off_s=0.9),))),
        Case("shadow edge 50 % at 100 mm/s", Scene(shadows=(Shadow(0.5, 4.0, 100.0, start_mm=-10.0,
                                                                   kind="edge"),))),
        Case("shadow band 50 % at 5 mm/s, c=-0.1", Scene(motion=m[-0.1], shadows=(Shadow(0.5, 5.0, 5.0,
                                                                                         start_mm=45.0),))),
        Case("shadow band 40 % at 40 mm/s, front light", Scene(lighting="front", shadows=(
            Shadow(0.4, 6.0, 40.0, start_mm=5.0, t_on_s=0.1, t_off_s=0.9),))),
        Case("shadow band 60 % at 60 mm/s, front light", Scene(lighting="front", shadows=(
            Shadow(0.6, 6.0, 60.0, start_mm=5.0, t_on_s=0.1, t_off_s=0.9),))),
        # clamps and labels
        Case("clamp 3 mm", Scene(clamps=(Clamp(30.0, 3.0),))),
        Case("clamp 8 mm", Scene(clamps=(CLAMP,))),
        Case("clamp 15 mm, c=-0.1", Scene(motion=m[-0.1], clamps=(Clamp(45.0, 15.0),))),
        Case("clamp 8 mm, scale from tube", Scene(clamps=(CLAMP,)), "tube"),
        Case("two clamps 6 mm, front light", Scene(lighting="front", clamps=(Clamp(20.0, 6.0), Clamp(70.0, 6.0)))),
        Case("label 12 mm, 55 % through", Scene(labels=(LABEL,))),
        Case("label 20 mm, 30 % through", Scene(labels=(Label(45.0, 20.0, transmission=0.3),))),
        Case("label 12 mm, front light", Scene(lighting="front", labels=(LABEL,))),
        # light, noise, codec
        Case("noise 4 %", Scene(noise=0.04)),
        Case("H.264 crf 23", Scene(fmt="h264", crf=23)),
        Case("H.264 crf 35", Scene(fmt="h264", crf=35)),
        Case("H.264 crf 30, front light", Scene(lighting="front", fmt="h264", crf=30)),
        # oscillating and stick-slip trains
        Case("oscillating 3 Hz 3 mm", Scene(motion=Motion("oscillating", -0.005, 3.0, 3.0), n_frames=_N_OSC)),
        Case("oscillating 5 Hz 1 mm, ripple 20 %", Scene(motion=replace(OSC, amplitude_mm=1.0), n_frames=_N_OSC,
                                                         ripple=Ripple(0.2, 100.0))),
        Case("stick-slip 4 Hz", Scene(motion=STICK, n_frames=_N_OSC)),
        Case("stick-slip 4 Hz, shake 1 px 30 Hz", Scene(motion=STICK, n_frames=_N_OSC, shake=Shake(1.0, 30.0, 2.0))),
        # everything at once: shake + ripple + clamp + label + shadow
        Case("combined c=-0.05", _combined()),
        Case("combined c=-0.05, scale from tube", _combined(), "tube"),
        Case("combined c=-0.02", _combined(motion=m[-0.02])),
        Case("combined c=-0.1", _combined(motion=m[-0.1])),
        Case("combined c=-0.05, H.264 crf 28", _combined(fmt="h264")),
        Case("combined c=-0.05, H.264 crf 28, scale from tube", _combined(fmt="h264"), "tube"),
        Case("combined c=-0.05, front light", _combined(lighting="front")),
        Case("combined c=-0.05, front light, H.264, scale from tube", _combined(lighting="front", fmt="h264"), "tube"),
        Case("combined oscillating 5 Hz", _combined(motion=OSC, n_frames=_N_OSC)),
        Case("combined stick-slip 4 Hz, H.264", _combined(motion=STICK, n_frames=_N_OSC, fmt="h264")),
    ]
    return out


#: every case of the bench, by name
CASES: dict[str, Case] = {c.name: c for c in _cases()}
