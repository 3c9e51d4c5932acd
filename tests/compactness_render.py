"""An independent renderer of back-lit tube contents with a known compactness, for the compactness tests.

It shares no code with :mod:`grainplug.synthetic` or ``tests/lab_nuisances.py``. A vertical glass tube of
bore ``bore_px`` is seen in back light; at each pixel across the bore the light crosses a chord of the
bore, ``bore_mm * sqrt(1 - (2 x / bore)^2)`` long, and is attenuated by ``exp(-kappa * c * chord)``
(Beer–Lambert), ``c`` the contents' compactness at that height and time. The grains' texture is a
random relative variation of ``c`` from pixel to pixel (grains of about ``grain_px``), and the camera adds
noise and rounds to 8 bits. The walls are dark lines, the background a smooth lamp.

Plugs (compactness ``c_plug``) and bubbles (``c_bubble``: grains falling through air) alternate along
the tube and climb at ``speed_px_per_frame``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np


@dataclass(frozen=True)
class Contents:
    """What is in the tube and how it is filmed."""

    height_px: int = 480
    width_px: int = 96
    bore_px: float = 24.0
    mm_per_px: float = 0.125
    kappa_per_mm: float = 0.9  # attenuation at compactness 1 per mm of chord
    c_plug: float = 0.55
    c_bubble: float = 0.04
    plug_px: int = 80
    bubble_px: int = 60
    speed_px_per_frame: float = -1.5
    texture: float = 0.15  # relative variation of c from grain to grain
    grain_px: float = 2.0
    noise: float = 2.0  # camera noise, grey levels
    lamp: float = 220.0
    n_frames: int = 120


def _texture(rng: np.random.Generator, shape: tuple[int, int], grain_px: float) -> np.ndarray:
    """Unit-mean random field with a correlation length of about ``grain_px`` (block noise, smoothed)."""
    k = max(1, int(round(grain_px)))
    coarse = rng.normal(0.0, 1.0, (shape[0] // k + 2, shape[1] // k + 2))
    field = np.kron(coarse, np.ones((k, k)))[: shape[0], : shape[1]]
    return field / max(float(field.std()), 1e-9)


def frame(cfg: Contents, c_rows: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One grey uint8 frame with compactness ``c_rows`` (one value per image row) in the bore."""
    h, w = cfg.height_px, cfg.width_px
    x = np.arange(w) + 0.5 - w / 2.0
    r = cfg.bore_px / 2.0
    inside = np.abs(x) < r
    chord_mm = np.where(inside, 2.0 * r * np.sqrt(np.clip(1.0 - (x / r) ** 2, 0.0, 1.0)), 0.0) * cfg.mm_per_px
    c = c_rows[:, None] * (1.0 + cfg.texture * _texture(rng, (h, w), cfg.grain_px))
    light = cfg.lamp * (1.0 - 0.15 * ((np.arange(h)[:, None] / h) - 0.5) ** 2) * np.ones((1, w))
    light = light * np.exp(-cfg.kappa_per_mm * np.clip(c, 0.0, None) * chord_mm[None, :])
    wall = (np.abs(x) >= r) & (np.abs(x) < r + 3)
    light[:, wall] *= 0.35
    light = light + rng.normal(0.0, cfg.noise, light.shape)
    return np.clip(np.rint(light), 0, 255).astype(np.uint8)


def truth_rows(cfg: Contents, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The compactness of every row at frame ``k``, and which rows are plug."""
    period = cfg.plug_px + cfg.bubble_px
    phase = (np.arange(cfg.height_px) - cfg.speed_px_per_frame * k) % period
    plug = phase < cfg.plug_px
    return np.where(plug, cfg.c_plug, cfg.c_bubble), plug


def movie(cfg: Contents, seed: int = 0, *, empty_lamp: float | None = None,
          packed_lamp: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The movie (n_frames, h, w) uint8, the empty tube and the tube packed at 0.60 (each a mean of 8 frames),
    the references under a lamp of another level if given."""
    rng = np.random.default_rng(seed)
    frames = np.stack([frame(cfg, truth_rows(cfg, k)[0], rng) for k in range(cfg.n_frames)])
    e_cfg = cfg if empty_lamp is None else replace(cfg, lamp=empty_lamp)
    p_cfg = cfg if packed_lamp is None else replace(cfg, lamp=packed_lamp)
    empty = np.mean([frame(e_cfg, np.zeros(cfg.height_px), rng) for _ in range(8)], axis=0)
    packed = np.mean([frame(p_cfg, np.full(cfg.height_px, 0.60), rng) for _ in range(8)], axis=0)
    return frames, empty.astype(np.float32), packed.astype(np.float32)


def core_profile(images: np.ndarray, cfg: Contents, core: float = 0.7) -> np.ndarray:
    """The mean level over the middle ``core`` of the bore, row by row (the band a diagram averages)."""
    w = cfg.width_px
    x = np.arange(w) + 0.5 - w / 2.0
    cols = np.abs(x) <= core * cfg.bore_px / 2.0
    return np.asarray(images, np.float64)[..., cols].mean(axis=-1)
