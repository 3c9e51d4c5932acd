"""The compactness read from the light on renders with random parameters (held out from the type B term's choice).

Renders 8 movies with ``tests/compactness_render.py`` (optical depth, plug and bubble compactness, texture, grain
size, noise and bore drawn at random), analyses each with its empty and packed references, and prints each
error and whether the 95 % intervals hold the truth (docs/accuracy.md, "Compactness from the light").

    .venv/bin/python benchmarks/compactness_held_out.py [--seed 7] [--n 8]
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from compactness_render import Contents, movie

import grainplug as gp
from grainplug.calibration.background import grey_background

log = logging.getLogger("compactness_held_out")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--n", type=int, default=8)
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    rng = np.random.default_rng(args.seed)
    miss = 0
    for i in range(args.n):
        kw = dict(kappa_per_mm=float(rng.uniform(0.3, 2.0)), c_plug=float(rng.uniform(0.42, 0.6)),
                  c_bubble=float(rng.uniform(0.01, 0.15)), texture=float(rng.uniform(0.05, 0.35)),
                  grain_px=float(rng.choice([1.0, 2.0, 3.0])), noise=float(rng.uniform(1, 6)),
                  bore_px=float(rng.uniform(16, 32)))
        cfg = Contents(**kw)
        frames, empty, packed = movie(cfg, seed=100 + i)
        s = gp.analyze(frames, fps=250.0, mm_per_px=cfg.mm_per_px, background=grey_background([empty]),
                       packed=grey_background([packed])).summary["compactness"]
        holds = all(s[f"{p}_ci95"][0] <= t <= s[f"{p}_ci95"][1]
                    for p, t in (("plugs", cfg.c_plug), ("bubbles", cfg.c_bubble)))
        miss += not holds
        log.info("%s plugs %+.4f bubbles %+.4f interval %s", {k: round(v, 2) for k, v in kw.items()},
                 s["plugs"] - cfg.c_plug, s["bubbles"] - cfg.c_bubble, "holds" if holds else "MISSES")
    log.info("%d of %d intervals hold the truth", args.n - miss, args.n)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
