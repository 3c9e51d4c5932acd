"""Issue 37, fourth step: static wall friction above kinetic (``ModelParams.mu_static_over_kinetic``) on Janssen's
stress carried down each dense stretch, in the open pipe at the paper's conditions. The table and the figure of
docs/model.md's subsection.

    .venv/bin/python benchmarks/closures_static_friction.py [--out docs/figures] [--json runs.jsonl]

The set-ups of ``closures_janssen_column.py`` (100 D pipe, 3 mm bore, 0.2 mm grains, atmospheric air, exact
coulomb-janssen friction on the carried stress, fed at c = 0.58 and 0.5 g/s for 60 t_c): a 30 D plug at c = 0.60
held at the outlet, and the pipe full of a dense feed, at static over kinetic friction r = 1 (today's law), 1.5, 2
and 3; the grid (200, 400, 800 cells) at r = 2; the sealed inlet at r = 2. Each run reports when the dense stretch
(c > c_min) is gone, the speed of its bottom, the share of its cell-states found exactly at rest (``v = 0``: where
static friction can act), the grain budget and the movie measures. About 2 minutes; writes
model_static_friction.png.
"""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from closures_janssen_column import run, sealed

from grainplug.simulation import SimulationResult

log = logging.getLogger("closures_static_friction")

STICKS = (1.0, 1.5, 2.0, 3.0)


def at_rest_share(res: SimulationResult) -> float:
    """The share of the dense cells' saved states (c > c_min, below the inlet's first 5 D) exactly at rest."""
    m = res.model
    dense = (res.c > m.jamming_c_min) & (res.z > 5.0)[None, :]
    return float(np.mean(res.v[dense] == 0.0)) if dense.any() else float("nan")


def stretch_edges(res: SimulationResult) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Time (s) and the top and bottom (mm) of the dense stretch (c > c_min) below the inlet's first 5 D."""
    m = res.model
    keep = res.z > 5.0
    z = res.z[keep] * m.D_m * 1e3
    dense = res.c[:, keep] > m.jamming_c_min
    top = np.array([z[np.flatnonzero(r)[0]] if r.any() else np.nan for r in dense])
    bottom = np.array([z[np.flatnonzero(r)[-1]] if r.any() else np.nan for r in dense])
    return res.time * m.t_c_s, top, bottom


def figure(runs: dict[float, SimulationResult], path: Path) -> None:
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
    for r, res in runs.items():
        t, top, bottom = stretch_edges(res)
        (line,) = a.plot(t, bottom, label=f"r = {r:g}: bottom")
        a.plot(t, top, ls="--", color=line.get_color())
        m = res.model
        rest = [float(np.mean(res.v[j][res.c[j] > m.jamming_c_min] == 0.0)) if (res.c[j] > m.jamming_c_min).any()
                else np.nan for j in range(len(res.time))]
        b.plot(t, rest, color=line.get_color(), label=f"r = {r:g}")
    a.set(xlabel="time (s)", ylabel="depth in the pipe (mm)", xlim=(0, 0.4),
          title="(a) the held plug (c > c_min): bottom (solid), top (dashed)")
    a.invert_yaxis()
    a.legend(fontsize=8)
    b.set(xlabel="time (s)", ylabel="share of its cells exactly at rest", xlim=(0, 0.4), ylim=(-0.02, 1.02),
          title="(b) where static friction can act")
    b.legend(fontsize=8)
    fig.suptitle("static friction r times the kinetic one, carried Janssen stress, 400 cells (100 D): the four r "
                 "coincide", fontsize=10)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("docs/figures"))
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    rows: list[dict[str, object]] = []
    held: dict[float, SimulationResult] = {}

    def keep(out: dict[str, object], res: SimulationResult, stick: float) -> None:
        out["stick"] = stick
        out["at_rest_share"] = at_rest_share(res)
        log.info(json.dumps(out))
        rows.append(out)

    for stick in STICKS:
        for start in ("held", "dense"):
            out, res = run(start, cells=400, stick=stick)
            keep(out, res, stick)
            if start == "held":
                held[stick] = res
    for cells in (200, 800):
        out, res = run("held", cells=cells, stick=2.0)
        keep(out, res, 2.0)
    for stick in (1.0, 2.0):
        out, res = sealed(100.0, 400, 60.0, stick=stick)
        keep(out, res, stick)
    if args.json:
        args.json.write_text("".join(json.dumps(r) + "\n" for r in rows))
    args.out.mkdir(parents=True, exist_ok=True)
    figure(held, args.out / "model_static_friction.png")


if __name__ == "__main__":
    main()
