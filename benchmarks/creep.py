"""The grains' velocity inside the plugs on independent renders of creeping grains (docs/accuracy.md).

Renders every case of ``tests/creep_render.py`` (grains creeping at a known speed under a climbing plug
pattern, and oscillating plugs whose grains move with them; TIFF and H.264, camera shake 1.5 px) with
``--seeds`` seeds, analyses each with ``grainplug.analyze`` and prints a Markdown table: the truth, the
measure, its error against the target (10 % or 0.3 mm/s, whichever is larger), and whether its 95 %
interval holds the truth (the interval's coverage over all runs at the end).

    .venv/bin/python benchmarks/creep.py --out /work/scratch/creep [--seeds 3] [--cases REGEX]
"""

from __future__ import annotations

import argparse
import logging
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from creep_render import CASES, render_movie

import grainplug as gp

log = logging.getLogger("creep")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="folder for the rendered movies")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--cases", default="")
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print("| case | seed | truth mm/s | measured mm/s | 95 % interval mm/s | lag | error | target |")
    print("|---|---|---|---|---|---|---|---|")
    n = held = ok = 0
    for i, (name, scene) in enumerate(CASES):
        if not re.search(args.cases, name):
            continue
        for seed in range(args.seeds):
            path = out / f"case{i}_seed{seed}.{'tif' if scene.fmt == 'tif' else 'mp4'}"
            truth = render_movie(path, scene, seed=seed)
            s = gp.analyze(path, mm_per_px=scene.mm_per_px).summary
            v, ci = s["grain_velocity_in_plugs_m_s"], s["grain_velocity_in_plugs_ci95_m_s"]
            t_mm = truth.grain_velocity_m_s * 1e3
            n += 1
            if v is None:
                print(f"| {name} | {seed} | {t_mm:.2f} | (none) | | | | FAIL |", flush=True)
                continue
            err = v * 1e3 - t_mm
            good = abs(err) <= max(0.1 * abs(t_mm), 0.3)
            holds = ci is not None and ci[0] <= truth.grain_velocity_m_s <= ci[1]
            ok += good
            held += holds
            ci_s = "" if ci is None else f"{ci[0] * 1e3:.2f} – {ci[1] * 1e3:.2f}" + ("" if holds else " (misses)")
            lag = s["grain_velocity_in_plugs_lag_frames"]
            verdict = "ok" if good else "FAIL"
            print(f"| {name} | {seed} | {t_mm:.2f} | {v * 1e3:.2f} | {ci_s} | {lag} | {err:+.2f} mm/s | {verdict} |",
                  flush=True)
    print(f"\n{ok} of {n} within the target; {held} of {n} intervals hold the truth")
    return 0 if ok == n else 1


if __name__ == "__main__":
    raise SystemExit(main())
