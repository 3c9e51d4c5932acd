"""The sweep of calibration images through distorting lenses (tests/test_calibration_lens.py, docs/calibration.md)."""

from __future__ import annotations

import numpy as np

#: the lens's distortion at the frame's corners (optics' sign: negative is barrel)
DISTORTIONS = (-0.05, -0.035, -0.025, -0.015, 0.0, 0.015, 0.025, 0.035, 0.05)


def sweep_cases() -> list[tuple[str, dict]]:
    """Name and :func:`calibration_lens.render` keywords of each image of the sweep (deterministic)."""
    rng = np.random.default_rng(2026)
    cases = []
    patterns = ("checkerboard", "dots", "graph", "ruler")
    k = 0
    for distortion in DISTORTIONS:
        for pattern in patterns:
            mm_per_px = float(rng.choice([0.1, 0.15, 0.185, 0.22, 0.3]))
            shape = (480, 640)
            field_mm = (shape[0] * mm_per_px, shape[1] * mm_per_px)
            kw: dict = {"pattern": pattern, "mm_per_px": mm_per_px, "shape": shape, "distortion": distortion,
                        "roll_deg": float(rng.uniform(-8, 8)), "tilt_deg": float(rng.uniform(0, 4)),
                        "tilt_axis_deg": float(rng.uniform(0, 180)), "distance_mm": 200.0,
                        "centre_offset_px": (float(rng.uniform(-15, 15)), float(rng.uniform(-15, 15))),
                        "blur_px": float(rng.uniform(0.5, 1.3)), "noise": float(rng.uniform(0.005, 0.025))}
            if pattern in ("checkerboard", "dots"):
                pitch = 5.0 if mm_per_px >= 0.15 else 3.0
                kw.update(pitch_mm=pitch, n=(int(field_mm[1] * 0.95 / pitch) // 2 * 2,
                                             int(field_mm[0] * 0.95 / pitch) // 2 * 2 + 1))
            elif pattern == "graph":
                kw.update(pitch_mm=1.0, n=(int(field_mm[1] * 1.2), int(field_mm[0] * 1.2)),
                          thin_contrast=(0.05, 0.1, 0.2, 0.45)[k // 4 % 4])
            else:
                kw.update(pitch_mm=1.0, n=(int(field_mm[1] * 1.2), 12), roll_deg=float(rng.uniform(-4, 4)))
            name = f"{k:02d} {pattern} {100 * distortion:+.1f}% {mm_per_px} mm/px"
            cases.append((name, kw))
            k += 1
    return cases
