"""Speed of `grainplug.simulation`: the compiled (numba) step against the NumPy reference.

    .venv/bin/python benchmarks/simulation.py [--engine numba|numpy] [--cells 2048] [--length-D 251]
        [--duration-tc 600] [--variant frozen-friction]

Runs one periodic simulation from the issue-18 target (2048 cells, a 251 D box, 600 t_c,
the frozen-friction variant, from 1e-9 noise) and prints the wall time of the time loop,
the number of steps, the time per step and per cell-step, and the end state. The compile
time of the numba kernel is excluded (it is cached on disk after the first run); run it
once before timing. Nothing here is a test: timings depend on the machine.
"""

from __future__ import annotations

import argparse
import json
import logging

import numpy as np

from grainplug.simulation import SimulationParams, simulate
from grainplug.simulation.waves import wave_state
from grainplug.stability import ModelParams

log = logging.getLogger("benchmarks.simulation")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--engine", default="numba", choices=["numba", "numpy"])
    ap.add_argument("--cells", type=int, default=2048)
    ap.add_argument("--length-D", type=float, default=251.0)
    ap.add_argument("--duration-tc", type=float, default=600.0)
    ap.add_argument("--variant", default="frozen-friction")
    a = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    # compile (or load the cached kernel) outside the timing
    simulate(ModelParams(variant=a.variant), SimulationParams(n_cells=32, length_D=10, duration_tc=0.1,
                                                              output_interval_tc=0.1, engine=a.engine))
    sim = SimulationParams(n_cells=a.cells, length_D=a.length_D, duration_tc=a.duration_tc, output_interval_tc=1.0,
                           engine=a.engine)
    res = simulate(ModelParams(variant=a.variant), sim, rng=np.random.default_rng(0))
    w = wave_state(res)
    out = {"engine": a.engine, "cells": a.cells, "length_D": a.length_D, "duration_tc": a.duration_tc,
           "wall_s": round(res.wall_s, 2), "steps": res.n_steps,
           "us_per_step": round(1e6 * res.wall_s / res.n_steps, 1),
           "ns_per_cell_step": round(1e9 * res.wall_s / res.n_steps / a.cells, 1),
           "n_waves": w.n_waves, "dense_length_D": round(w.dense_length_D, 2),
           "front_speed_v_c": round(w.front_speed, 3),
           "c_max_end": round(w.c_max, 4), "grain_drift": res.grain_drift, "air_drift": res.air_drift}
    log.info(json.dumps(out))


if __name__ == "__main__":
    main()
