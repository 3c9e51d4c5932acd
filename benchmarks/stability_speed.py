"""Time the root computation and the analysis of many wavenumbers, and the memory they hold.

- ``roots``: 10^5 wavenumbers, all three roots, tracked (the result is whole: 48 B each);
- ``analyze_stability``: 10^6 wavenumbers solved in chunks; and the peak of the memory
  allocated for 2 and 4 x 10^5 (tracemalloc: numpy's arrays included, the interpreter's and
  the libraries' own memory not), which stays the same whatever the count beyond 10^5.

    .venv/bin/python benchmarks/stability_speed.py [--n-k 1000000]
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

import numpy as np

from grainplug.stability import ModelParams, analyze_stability, roots

#: wavenumber counts whose allocations are traced: the memory must not grow from one to the other
TRACED = (200_000, 400_000)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-k", type=float, default=1e6, help="wavenumbers of the analysis timed")
    n_k = int(parser.parse_args().n_k)
    k = np.linspace(1e-3, 3, 100_000)
    for variant in ("printed", "frozen-friction"):
        p = ModelParams(variant=variant)
        best = min(_time(p, k) for _ in range(5))
        print(f"{variant:16s} roots, 100000 wavenumbers: {best * 1000:.0f} ms (best of 5)")
    for variant in ("printed", "frozen-friction"):
        p = ModelParams(variant=variant)
        t0 = time.perf_counter()
        res = analyze_stability(p, n_k=n_k)
        elapsed = time.perf_counter() - t0
        peaks = []
        for n in TRACED:  # tracemalloc slows numpy's allocations: traced apart, at counts beyond max_points
            tracemalloc.start()
            analyze_stability(p, n_k=n)
            peaks.append(tracemalloc.get_traced_memory()[1] / 1e6)
            tracemalloc.stop()
        print(f"{variant:16s} analyze_stability, {n_k} wavenumbers: {elapsed:.2f} s "
              f"({elapsed / n_k * 1e6:.2f} µs each), {len(res.k)} kept; peak allocated {peaks[0]:.1f} MB at "
              f"{TRACED[0]}, {peaks[1]:.1f} MB at {TRACED[1]} wavenumbers")


def _time(p: ModelParams, k: np.ndarray) -> float:
    t0 = time.perf_counter()
    roots(p, k)
    return time.perf_counter() - t0


if __name__ == "__main__":
    main()
