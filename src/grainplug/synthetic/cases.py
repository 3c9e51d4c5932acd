"""A catalogue of hard synthetic cases, each with what a correct analysis must find.

Used by the test-suite and by ``benchmarks/accuracy.py``; every item the
``analyze`` issue lists is covered: both polarities, a 40% illumination
gradient, +-8% flicker, sensor noise sigma 15, dense falling grains, lossy
H.264, plugs entering and leaving, merging and splitting, oscillation and
stick-slip between 2 and 10 Hz, tilted, horizontal and upward tubes, 16-bit
grey, and movies with no plugs.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .render import SynthConfig

#: accuracy targets (relative errors, absolute Hz)
CELERITY_TOL_SCALE_GIVEN = 0.02
CELERITY_TOL_SCALE_FROM_TUBE = 0.04
LENGTH_TOL_SCALE_GIVEN = 0.03
LENGTH_TOL_SCALE_FROM_TUBE = 0.05
FREQUENCY_TOL_HZ = 0.2
MIN_PERIODS_FOR_FREQUENCY = 8


@dataclass(frozen=True)
class Case:
    """A named synthetic movie: its configuration and file format."""

    name: str
    config: dict = field(default_factory=dict)
    fmt: str = "tiff"
    slow: bool = False

    def synth_config(self, seed: int = 0) -> SynthConfig:
        return SynthConfig(seed=seed, **self.config)


CASES: tuple[Case, ...] = (
    Case("dark_plugs_climbing", {}),
    Case("bright_plugs_on_dark", {"polarity": "bright"}),
    Case("gradient_40pct", {"gradient": 0.4}),
    Case("flicker_8pct", {"flicker": 0.08}),
    Case("noise_sigma_15", {"noise_sigma": 15.0}),
    Case("dense_falling_grains", {"falling_grains_per_mm": 2.0}),
    Case("lossy_h264", {"noise_sigma": 6.0}, fmt="h264"),
    Case("downstream_fast", {"celerity_m_s": 0.09}),
    Case("merge_split", {"merge_split": True}),
    Case("oscillating_2hz", {"regime": "oscillating", "frequency_hz": 2.0, "amplitude_mm": 2.0,
                             "celerity_m_s": 0.02, "fps": 125.0, "n_frames": 520}, slow=True),
    Case("oscillating_7hz", {"regime": "oscillating", "frequency_hz": 7.0, "amplitude_mm": 1.0,
                             "celerity_m_s": 0.03, "n_frames": 300}),
    Case("oscillating_10hz", {"regime": "oscillating", "frequency_hz": 10.0, "amplitude_mm": 0.6,
                              "celerity_m_s": 0.05, "n_frames": 250}),
    Case("stick_slip_4hz", {"regime": "stick-slip", "frequency_hz": 4.0, "celerity_m_s": 0.025,
                            "n_frames": 520}, slow=True),
    Case("stick_slip_9hz", {"regime": "stick-slip", "frequency_hz": 9.0, "celerity_m_s": 0.04,
                            "stick_fraction": 0.4, "n_frames": 250}),
    Case("tilted_5deg", {"tilt_deg": 5.0, "tube_offset_px": -15}),
    Case("horizontal_tilted", {"flow_direction": "right", "tilt_deg": -4.0}),
    Case("upward_view", {"flow_direction": "up", "celerity_m_s": -0.04}),
    Case("grey_16bit", {"rgb": False, "bit_depth": 16}),
    Case("everything_at_once", {"polarity": "bright", "noise_sigma": 15.0, "flicker": 0.08,
                                "gradient": 0.4, "tilt_deg": 3.0, "falling_grains_per_mm": 1.0,
                                "merge_split": True}, fmt="h264", slow=True),
    Case("no_plugs_compact", {"regime": "none", "no_plug_fill": "compact", "celerity_m_s": 0.01}),
    Case("no_plugs_empty", {"regime": "none", "falling_grains_per_mm": 1.0}),
)


def case(name: str) -> Case:
    """The case called ``name``."""
    for c in CASES:
        if c.name == name:
            return c
    raise KeyError(name)
