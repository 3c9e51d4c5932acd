"""Issue 37, third step: Janssen's stress carried down each dense stretch (``wall_stress="janssen-column"``) in the
open pipe at the paper's conditions. The numbers and the figure of docs/model.md's subsection.

    .venv/bin/python benchmarks/closures_janssen_column.py [--out docs/figures] [--json runs.jsonl]

A 100 D pipe (300 mm) of 3 mm bore, 0.2 mm grains, atmospheric air, exact coulomb-janssen friction on the carried
stress, no (v/kappa) v_z term, Stokes + Carman-Kozeny drag, fed from the top at Table 1's rates (c = 0.58, rain)
for 60 t_c (1.05 s). Three starts: a plug of 30 D held at the outlet (as for the local stress, where it stays and
climbs); the pipe full of a dense feed (c = 0.5846); the pipe full of the fed rain. Each run is measured as a movie
(:func:`grainplug.simulation.measure.measure`, second half) and as fields: the dense stretch's (c > c_min) top and
bottom over time, the time it takes to leave, the speed of its bottom, the grain budget. The grid (200, 400, 800
cells) and the stretch threshold c_min (0.55, 0.56, 0.57) are varied. Then a dense feed into a pipe whose air
enters the top only through a hopper's grains (``inlet_seal_D``): its suction, its column's lower front and how
fast it climbs, at two grids, two seals, two rates and in a 1 m pipe over 21 s, where a lone thin plug climbs
through the rain once the column is gone. About 3 minutes; writes model_janssen_column.png.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from grainplug.simulation import SimulationParams, SimulationResult, simulate
from grainplug.simulation.equations import Closure
from grainplug.simulation.measure import measure
from grainplug.simulation.run import feed_velocity
from grainplug.stability import ModelParams
from grainplug.stability.params import P_ATM_PA

log = logging.getLogger("closures_janssen_column")

LENGTH_D, PLUG_D, DURATION_TC = 100.0, 30.0, 60.0


def model(*, c_min: float = 0.56, column: bool = True, stick: float = 1.0) -> ModelParams:
    kw = (dict(wall_stress="janssen-column", mu_static_over_kinetic=stick) if column
          else dict(friction_v_eps=0.01))
    return ModelParams(grain_diameter_um=200, c0=0.585, base_pressure_pa=P_ATM_PA, jamming=True, jamming_c_min=c_min,
                       friction_law="coulomb-janssen", janssen_v2_term=False, drag="stokes-carman", **kw)


def run(start: str, *, rate: float = 0.5, cells: int = 400, c_min: float = 0.56, c_plug: float = 0.60,
        column: bool = True, stick: float = 1.0) -> tuple[dict[str, object], SimulationResult]:
    """One run; ``start`` is "held" (a plug of c_plug at the outlet, rain above), "dense" or "rain"; ``stick`` is
    the static over kinetic friction (closures_static_friction.py)."""
    m = model(c_min=c_min, column=column, stick=stick)
    feed_c = 0.5846 if start == "dense" else 0.58
    sim = SimulationParams(boundary="open", length_D=LENGTH_D, n_cells=cells, duration_tc=DURATION_TC,
                           output_interval_tc=0.25, feed_c=feed_c, feed_rate_g_s=rate, noise=0.0)
    cl = Closure.from_params(m, balance=False)
    z = (np.arange(cells) + 0.5) * sim.dx
    if start == "held":
        plug = z > LENGTH_D - PLUG_D
        U0 = cl.conserved(np.where(plug, c_plug, 0.02), np.where(plug, 0.0, 2.0), np.full(cells, cl.P0))
    else:
        fv = feed_velocity(m, rate, feed_c)
        U0 = cl.conserved(np.full(cells, feed_c), np.full(cells, fv), np.full(cells, cl.P0))
    t0 = time.perf_counter()
    res = simulate(m, sim, initial=U0, max_seconds=300)
    out: dict[str, object] = dict(start=start, wall_stress=m.wall_stress, rate_g_s=rate, cells=cells, c_min=c_min,
                                  c_plug=c_plug if start == "held" else None, wall_s=round(time.perf_counter() - t0, 1),
                                  steps=res.n_steps, budget_residual=res.grain_budget_residual)
    dense = res.c[:, z > 5.0] > c_min  # below the fed cells at the inlet
    zz = z[z > 5.0]
    alive = dense.any(axis=1)
    out["dense_stretch_gone_s"] = (None if alive[-1] else float(res.time[np.argmin(alive)] * m.t_c_s))
    bottoms = np.array([zz[np.flatnonzero(row)[-1]] if row.any() else math.nan for row in dense])
    tops = np.array([zz[np.flatnonzero(row)[0]] if row.any() else math.nan for row in dense])
    early = alive & (res.time * m.t_c_s < 0.1)  # the first 0.1 s, while the plug is still whole
    if early.sum() >= 3:
        out["bottom_speed_m_s"] = float(np.polyfit(res.time[early] * m.t_c_s, bottoms[early] * m.D_m, 1)[0])
        out["top_speed_m_s"] = float(np.polyfit(res.time[early] * m.t_c_s, tops[early] * m.D_m, 1)[0])
    c = res.c[-1]
    out.update(c_range_end=[float(c.min()), float(c.max())], share_below_0_1_end=float(np.mean(c < 0.1)),
               v_range_end=[float(res.v[-1].min()), float(res.v[-1].max())])
    ms = measure(res).as_dict()
    out["movie"] = {k: ms[k] for k in ("regime", "celerity_m_s", "plug_length_mm", "bubble_length_mm", "n_tracks")}
    return out, res


def sealed(length_D: float, cells: int, duration_tc: float, *, seal_D: float = 30.0,
           rate: float = 0.5, stick: float = 1.0) -> tuple[dict[str, object], SimulationResult]:
    """A dense feed (c = 0.5846) into a pipe whose air enters the top only through ``seal_D`` of the fed grains (a
    hopper): the suction, the dense column's lower front (c > 0.3) and its climb (fitted over the run's second
    half), and the movie measures."""
    m = model(stick=stick)
    fc = 0.5846
    sim = SimulationParams(boundary="open", length_D=length_D, n_cells=cells, duration_tc=duration_tc,
                           output_interval_tc=0.25, feed_c=fc, feed_rate_g_s=rate, noise=0.0, inlet_seal_D=seal_D)
    cl = Closure.from_params(m, balance=False)
    fv = feed_velocity(m, rate, fc)
    t0 = time.perf_counter()
    res = simulate(m, sim, initial=cl.conserved(np.full(cells, fc), np.full(cells, fv), np.full(cells, cl.P0)),
                   max_seconds=300)
    z = res.z
    front = np.array([z[np.flatnonzero(r > 0.3)[-1]] if (r > 0.3).any() else math.nan for r in res.c])
    fit_to = min(float(res.time[-1]), 240.0)  # the column's phase (a 1 m pipe's column is gone by ~430 t_c)
    late = (res.time > fit_to / 2) & (res.time <= fit_to) & (front < length_D - 2.0)
    climb = float(np.polyfit(res.time[late] * m.t_c_s, front[late] * m.D_m, 1)[0]) if late.sum() >= 3 else None
    j = int(np.argmin(np.abs(res.time - fit_to)))
    above = z < front[j] - 2.0
    c, v = res.c[j], res.v[j]
    ms = measure(res).as_dict()
    out = dict(start="dense, sealed inlet", seal_D=seal_D, length_D=length_D, cells=cells, rate_g_s=rate,
               wall_s=round(time.perf_counter() - t0, 1), budget_residual=res.grain_budget_residual,
               at_tc=float(res.time[j]), suction_pa=float((res.P[j].min() - cl.P0) * m.P_c_pa), front_D=float(front[j]),
               front_climb_m_s=climb,
               column_c=[float(c[above].min()), float(c[above].max())], column_v_m_s=[float(v[above].min() * m.v_c_m_s),
                                                                          float(v[above].max() * m.v_c_m_s)],
               below_c=[float(c[~above].min()), float(c[~above].max())], share_below_0_1=float(np.mean(c < 0.1)),
               share_dense=float(np.mean(c > m.jamming_c_min)),
               movie={k: ms[k] for k in ("regime", "celerity_m_s", "plug_length_mm", "bubble_length_mm", "n_tracks")})
    if res.time[-1] > 2 * fit_to:
        out["after_the_column"] = lone_plug(res, t_from_s=9.5)
    return out, res


def lone_plug(res: SimulationResult, *, t_from_s: float) -> dict[str, object]:
    """The thin plug that climbs through the rain once the sucked column is gone: the medians over the saved
    states after ``t_from_s`` of its length (c > 0.3, and c > 0.1), its peak compactness, the rain's below it,
    and its centre's speed while it climbs (below the inlet's first 8 D)."""
    m = res.model
    z = res.z
    t_s = res.time * m.t_c_s
    rows = []
    for j in np.flatnonzero(t_s >= t_from_s):
        r = np.where(z < 8.0, 0.0, res.c[j])
        idx = np.flatnonzero(r > 0.3)
        if not idx.size or idx[-1] - idx[0] + 1 > 0.2 * len(z):  # none, or joined to the fed column
            continue
        rain = res.c[j][z > z[idx[-1]] + 3.0]
        rows.append((t_s[j], z[idx].mean(), (idx[-1] - idx[0] + 1) * res.params.dx, r.max(),
                     float(np.sum(r > 0.1)) * res.params.dx, float(np.median(rain)) if rain.size else math.nan))
    a = np.array(rows)
    speed = np.gradient(a[:, 1] * m.D_m, a[:, 0])
    up = speed < -0.01
    return dict(seen_share=len(a) / max(int(np.sum(t_s >= t_from_s)), 1),
                length_mm_c_above_0_3=float(np.median(a[:, 2]) * m.diameter_mm),
                length_mm_c_above_0_1=float(np.median(a[:, 4]) * m.diameter_mm), peak_c=float(np.median(a[:, 3])),
                rain_c=float(np.nanmedian(a[:, 5])), climbing_share=float(np.mean(up)),
                climb_m_s=float(np.median(speed[up])) if up.any() else None)


def unheld_share(length_D: float, wall: float) -> float:
    """The share of a uniform stretch's weight its walls cannot hold with Janssen's stress zero at its top and
    fully mobilised below: ``lambda (1 - exp(-L / lambda)) / L``, ``lambda = D / (4 mu_s kappa)``."""
    lam = 1.0 / wall
    return lam * (1.0 - math.exp(-length_D / lam)) / length_D


def figure(column: SimulationResult, local: SimulationResult, seal: SimulationResult, path: Path) -> None:
    p = column.model
    fig, axs = plt.subplots(1, 4, figsize=(15.5, 4.3), gridspec_kw=dict(width_ratios=[1, 1, 0.75, 1.2]))
    for ax, res, title in ((axs[0], local, "(a) local stress (v_eps 0.01):\nthe plug at the outlet is held, climbs"),
                           (axs[1], column, "(b) janssen-column: the same plug\nslides out, released from its bottom"),
                           (axs[3], seal, "(d) janssen-column, dense feed (c = 0.5846), 1 m pipe, air in through\n"
                                          "30 D of grains (hopper): a column held by suction, then a lone plug")):
        im = ax.imshow(res.c.T, aspect="auto", origin="upper", cmap="gray_r", vmin=0, vmax=0.64,
                       extent=[0, res.time[-1] * p.t_c_s, res.params.length_D * p.diameter_mm, 0])
        ax.set_title(title, fontsize=8)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("z from the inlet (mm)")
    fig.colorbar(im, ax=axs[3], label="compactness c")
    z = column.z * p.diameter_mm
    for t_s, ls in ((0.0, "-"), (0.035, "--"), (0.07, "-."), (0.105, ":")):
        j = int(np.argmin(np.abs(column.time * p.t_c_s - t_s)))
        axs[2].plot(column.c[j], z, ls=ls, label=f"t = {column.time[j] * p.t_c_s:.3f} s")
    axs[2].axvline(p.jamming_c_min, c="k", lw=0.6)
    axs[2].set_ylim(z[-1], 150)
    axs[2].set_xlabel("c in (b); line: c_min")
    axs[2].legend(fontsize=7)
    axs[2].set_title("(c) profiles of (b): the plug\ndilates and is released", fontsize=8)
    fig.suptitle("(a-c) 30 D plug at the outlet of a 100 D pipe, rain fed at 0.5 g/s (c = 0.58); all: 3 mm bore, "
                 "0.2 mm grains, atmospheric air, stokes-carman drag, c_min 0.56", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("docs/figures"))
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    wall = 4.0 * model().mu_s * model().kappa
    log.info("share of a 30 D stretch's weight its walls cannot hold: %.4f (lambda = %.3f D)",
             unheld_share(PLUG_D, wall), 1 / wall)
    lines = []
    specs = ([dict(start="held", cells=n) for n in (200, 400, 800)]
             + [dict(start="held", c_min=cm) for cm in (0.55, 0.57)]
             + [dict(start="held", c_plug=0.57), dict(start="dense")]
             + [dict(start="rain", rate=r) for r in (0.37, 1.05)])
    kept = None
    for spec in specs:
        out, res = run(**spec)
        if spec == dict(start="held", cells=400):
            kept = res
        log.info("%s", json.dumps(out))
        lines.append(json.dumps(out))
    out, local = run("held", column=False)
    log.info("%s", json.dumps(out))
    lines.append(json.dumps(out))
    for spec in (dict(length_D=100.0, cells=400, duration_tc=60.0), dict(length_D=100.0, cells=800, duration_tc=60.0),
                 dict(length_D=100.0, cells=400, duration_tc=60.0, seal_D=100.0),
                 dict(length_D=100.0, cells=400, duration_tc=60.0, rate=1.05),
                 dict(length_D=333.0, cells=666, duration_tc=1200.0)):
        out, seal = sealed(**spec)
        log.info("%s", json.dumps(out))
        lines.append(json.dumps(out))
    if args.json is not None:
        args.json.write_text("\n".join(lines) + "\n")
    args.out.mkdir(parents=True, exist_ok=True)
    figure(kept, local, seal, args.out / "model_janssen_column.png")


if __name__ == "__main__":
    main()
