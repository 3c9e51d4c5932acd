"""Plug-train kinematics for synthetic movies: where every plug is at every time."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

REGIMES = ("propagative", "oscillating", "stick-slip", "none")


def displacement_mm(t_s: np.ndarray | float, *, regime: str, celerity_m_s: float,
                    frequency_hz: float, amplitude_mm: float, stick_fraction: float,
                    phase_rad: float = 0.0) -> np.ndarray:
    """Common displacement of the plug train along the flow, in mm.

    Parameters
    ----------
    t_s : array_like
        Times in seconds.
    regime : {"propagative", "oscillating", "stick-slip", "none"}
        ``propagative``: ``X = c t``. ``oscillating``: ``X = c t + A [sin(2 pi f t + phi) - sin(phi)]``.
        ``stick-slip``: the train stands still for ``stick_fraction`` of each period
        ``1/f`` and then slips by ``c/f`` with a smooth (half-cosine) velocity.
    celerity_m_s : float
        Mean (drift) celerity, positive downstream.

    Notes
    -----
    In every regime ``X(0) = 0`` and the time-averaged velocity is exactly
    ``celerity_m_s``.
    """
    t = np.asarray(t_s, dtype=float)
    c = celerity_m_s * 1000.0  # mm/s
    if regime in ("propagative", "none"):
        return c * t
    if regime == "oscillating":
        return c * t + amplitude_mm * (np.sin(2 * np.pi * frequency_hz * t + phase_rad) - np.sin(phase_rad))
    if regime == "stick-slip":
        period = 1.0 / frequency_hz
        step = c * period
        tau = t / period + phase_rad / (2 * np.pi)
        n = np.floor(tau)
        frac = tau - n
        x = np.clip((frac - stick_fraction) / (1.0 - stick_fraction), 0.0, 1.0)
        ramp = 0.5 * (1 - np.cos(np.pi * x))
        # subtract the value at t=0 so that X(0) = 0
        tau0 = phase_rad / (2 * np.pi)
        n0 = np.floor(tau0)
        x0 = np.clip((tau0 - n0 - stick_fraction) / (1.0 - stick_fraction), 0.0, 1.0)
        return step * (n + ramp) - step * (n0 + 0.5 * (1 - np.cos(np.pi * x0)))
    raise ValueError(f"unknown regime {regime!r}; choose one of {REGIMES}")


@dataclass(frozen=True)
class PlugTrain:
    """Plugs of a synthetic movie in material coordinates (position at t = 0).

    Attributes
    ----------
    top0_mm, bottom0_mm : ndarray
        Upper and lower edge of each plug at ``t = 0`` along the flow (mm from the
        top of the field of view; the train extends beyond the view).
    merge_amplitude_mm : ndarray
        Extra upstream excursion of each plug towards the one above it (0 for most
        plugs); when larger than the bubble between them the two plugs merge, then split.
    merge_phase_rad : ndarray
        Phase of that excursion.
    """

    top0_mm: np.ndarray
    bottom0_mm: np.ndarray
    merge_amplitude_mm: np.ndarray
    merge_phase_rad: np.ndarray

    @property
    def length_mm(self) -> np.ndarray:
        return self.bottom0_mm - self.top0_mm

    def __len__(self) -> int:
        return len(self.top0_mm)


def build_train(rng: np.random.Generator, *, span_mm: tuple[float, float], plug_length_mm: float,
                plug_length_sd_mm: float, bubble_length_mm: float, bubble_length_sd_mm: float,
                merge_split: bool) -> PlugTrain:
    """Draw a train of plugs and bubbles covering ``span_mm`` (material coordinates)."""
    lo, hi = span_mm
    tops, bots = [], []
    pos = lo - rng.uniform(0, plug_length_mm + bubble_length_mm)
    min_len = max(0.25 * plug_length_mm, 1.0)
    while pos < hi:
        length = max(rng.normal(plug_length_mm, plug_length_sd_mm), min_len)
        gap = max(rng.normal(bubble_length_mm, bubble_length_sd_mm), 0.3 * bubble_length_mm)
        tops.append(pos)
        bots.append(pos + length)
        pos += length + gap
    top = np.asarray(tops)
    bot = np.asarray(bots)
    amp = np.zeros(len(top))
    phase = rng.uniform(0, 2 * np.pi, len(top))
    if merge_split and len(top) > 1:
        gaps = top[1:] - bot[:-1]
        idx = np.arange(1, len(top), 3)  # every third plug joins the one above it for a while
        amp[idx] = gaps[idx - 1] + 0.8
    return PlugTrain(top, bot, amp, phase)
