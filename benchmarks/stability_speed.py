"""Time the vectorised root computation: 10^5 wavenumbers, all three roots, tracked.

    .venv/bin/python benchmarks/stability_speed.py
"""

from __future__ import annotations

import time

import numpy as np

from grainplug.stability import ModelParams, roots


def main() -> None:
    k = np.linspace(1e-3, 3, 100_000)
    for variant in ("printed", "frozen-friction"):
        p = ModelParams(variant=variant)
        best = min(_time(p, k) for _ in range(5))
        print(f"{variant:16s} 100000 wavenumbers: {best * 1000:.0f} ms (best of 5)")


def _time(p: ModelParams, k: np.ndarray) -> float:
    t0 = time.perf_counter()
    roots(p, k)
    return time.perf_counter() - t0


if __name__ == "__main__":
    main()
