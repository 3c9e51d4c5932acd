"""Issue 37's closures in the open pipe at the paper's conditions: the table and figure of docs/model.md.

    .venv/bin/python benchmarks/closures_open_pipe.py [--out docs/figures] [--json runs.jsonl]

A 100 D pipe (300 mm, 400 cells) of 3 mm bore, 0.2 mm grains, atmospheric air, coulomb-janssen friction
(v_eps = 0.01 v_c), no (v/kappa) v_z term, Stokes + Carman-Kozeny drag, fed from the top at Table 1's rates
and started full of the fed state; 60 t_c (1.05 s) each, 1-21 s of computing each. Every run is measured as
a movie (:func:`grainplug.simulation.measure.measure`, its second half) and as fields; one JSON line per
run is logged (and written with --json); then a plug held at the bottom with rain landing on it, at 0.37-1.05 g/s.
Writes model_closures_open_pipe.png (about 4 minutes in all).
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from scipy.optimize import brentq

from grainplug.errors import ParameterError
from grainplug.simulation import SimulationParams, SimulationResult, simulate
from grainplug.simulation.equations import Closure
from grainplug.simulation.measure import measure
from grainplug.simulation.run import feed_velocity
from grainplug.stability import ModelParams
from grainplug.stability.params import P_ATM_PA

log = logging.getLogger("closures_open_pipe")

#: (feed c, rate g/s, c_min, pipe length D, cells, v_eps): the runs of docs/model.md's table
RUNS = [(0.58, r, 0.56, 100.0, 400, 0.01) for r in (0.37, 0.52, 0.67, 0.84, 1.05)] + [
    (0.5786, 0.5, 0.56, 100.0, 400, 0.01), (0.5846, 0.5, 0.56, 100.0, 400, 0.01),
    (0.5846, 1.05, 0.56, 100.0, 400, 0.01), (0.5515, 0.5, 0.50, 100.0, 400, 0.01),
    (0.5575, 0.5, 0.50, 100.0, 400, 0.01), (0.58, 1.05, 0.56, 333.0, 666, 0.01),
    # the regularisation and the grid
    (0.58, 0.5, 0.56, 100.0, 400, 0.005), (0.58, 0.5, 0.56, 100.0, 400, 0.02),
    (0.5846, 0.5, 0.56, 100.0, 400, 0.005), (0.5846, 0.5, 0.56, 100.0, 400, 0.02),
    (0.58, 0.5, 0.56, 100.0, 200, 0.01), (0.58, 0.5, 0.56, 100.0, 800, 0.01),
]


def model(c_min: float, v_eps: float, c0: float = 0.585) -> ModelParams:
    return ModelParams(grain_diameter_um=200, c0=c0, base_pressure_pa=P_ATM_PA, jamming=True, jamming_c_min=c_min,
                       friction_law="coulomb-janssen", friction_v_eps=v_eps, janssen_v2_term=False,
                       drag="stokes-carman")


def c_star(c_min: float) -> float:
    """The compactness at which the walls' largest friction equals the weight (stress ratio 1)."""
    return brentq(lambda c: model(c_min, 0.01, c).janssen_stress_ratio - 1.0, c_min + 1e-4, 0.639)


def run(feed_c: float, rate: float, c_min: float, length: float, cells: int,
        v_eps: float) -> tuple[dict[str, object], SimulationResult | None]:
    m = model(c_min, v_eps)
    sim = SimulationParams(boundary="open", length_D=length, n_cells=cells, duration_tc=60.0, output_interval_tc=0.25,
                           feed_c=feed_c, feed_rate_g_s=rate, noise=0.0)
    cl = Closure.from_params(m, balance=False)
    fv = feed_velocity(m, rate, feed_c)
    out: dict[str, object] = dict(feed_c=feed_c, rate_g_s=rate, c_min=c_min, length_D=length, cells=cells,
                                  v_eps=v_eps)
    t0 = time.perf_counter()
    try:
        res = simulate(m, sim, initial=cl.conserved(np.full(cells, feed_c), np.full(cells, fv),
                                                    np.full(cells, cl.P0)), max_seconds=120)
    except ParameterError as e:
        out.update(stopped=str(e))
        return out, None
    c = res.c[-1]
    out.update(wall_s=round(time.perf_counter() - t0, 1), steps=res.n_steps, c_range=[float(c.min()), float(c.max())],
               share_below_0_1=float(np.mean(c < 0.1)), v_range=[float(res.v[-1].min()), float(res.v[-1].max())],
               taken_in=float(res.grain_inflow[-1] / (feed_c * fv * sim.duration_tc)),
               budget_residual=res.grain_budget_residual, warnings=list(res.warnings))
    ms = measure(res).as_dict()
    out["movie"] = {k: ms[k] for k in ("regime", "celerity_m_s", "plug_length_mm", "bubble_length_mm", "n_tracks")}
    return out, res


def held_plug(rate: float, *, cells: int = 400) -> dict[str, object]:
    """A plug held by the walls at the bottom (the last 30 D at c = 0.60, above c*), rain fed at ``rate`` above
    it: the top of the plug climbs as the rain lands on it. Returns its movie measures, the climb of its top
    (fitted after 0.3 s) and the kinematic speed ``-q / (c_plug - c_rain)`` that mass conservation gives."""
    m = model(0.56, 0.01)
    length = 100.0
    sim = SimulationParams(boundary="open", length_D=length, n_cells=cells, duration_tc=60.0,
                           output_interval_tc=0.25, feed_c=0.58, feed_rate_g_s=rate, noise=0.0)
    cl = Closure.from_params(m, balance=False)
    z = (np.arange(cells) + 0.5) * sim.dx
    c = np.where(z > 70.0, 0.60, 0.02)
    res = simulate(m, sim, initial=cl.conserved(c, np.where(z > 70.0, 0.0, 2.0), np.full(cells, cl.P0)),
                   max_seconds=120)
    below = z > 5.0  # the fed cells at the inlet are dense too
    top = np.array([z[below][np.argmax(row[below] > 0.5)] for row in res.c])
    t_s = res.time * m.t_c_s
    sel = t_s > 0.3
    climb = float(np.polyfit(t_s[sel], top[sel] * m.D_m, 1)[0])
    i = int(np.searchsorted(z, top[-1]))
    c_rain = float(np.median(res.c[-1][(z > top[-1] - 10.0) & (z < top[-1] - 4.0)]))  # above the front's smear
    c_plug = float(np.median(res.c[-1][i + 4:]))
    q = rate * 1e-3 / (m.grain_density_kg_m3 * np.pi * m.D_m**2 / 4)
    ms = measure(res).as_dict()
    return dict(rate_g_s=rate, top_climb_m_s=climb, kinematic_m_s=-q / (c_plug - c_rain), c_rain=c_rain,
                c_plug=c_plug, movie={k: ms[k] for k in ("regime", "celerity_m_s", "frequency_hz", "n_tracks")})


def figure(rain: SimulationResult, jam: SimulationResult, cs: float, path: Path) -> None:
    p = rain.model
    fig, axs = plt.subplots(1, 3, figsize=(12, 4.2), gridspec_kw=dict(width_ratios=[1, 1, 0.8]))
    for ax, res, title in ((axs[0], rain, f"fed at c = {rain.params.feed_c:g} (below c* = {cs:.4f}): free rain"),
                           (axs[1], jam, f"fed at c = {jam.params.feed_c:g} (above c*): jammed, feed backs up")):
        im = ax.imshow(res.c.T, aspect="auto", origin="upper", cmap="gray_r", vmin=0, vmax=0.64,
                       extent=[0, res.time[-1] * p.t_c_s, res.params.length_D * p.diameter_mm, 0])
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("z from the inlet (mm)")
        axs[2].plot(res.c[-1], res.z * p.diameter_mm, label=title.split(":")[0])
    fig.colorbar(im, ax=axs[1], label="compactness c")
    axs[2].invert_yaxis()
    axs[2].set_xlabel(f"c at t = {rain.time[-1] * p.t_c_s:.2f} s")
    axs[2].axvline(0.1, ls=":", c="k")
    axs[2].legend(fontsize=7)
    axs[2].set_title("final profiles", fontsize=9)
    fig.suptitle("coulomb-janssen + stokes-carman, no (v/kappa) v_z term, atmospheric air, "
                 f"{rain.params.feed_rate_g_s:g} g/s, 3 mm bore, 0.2 mm grains, c_min {p.jamming_c_min:g}, "
                 f"v_eps {p.friction_v_eps:g} v_c", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("docs/figures"))
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    for c_min in (0.50, 0.55, 0.56):
        log.info("c* = %.4f for c_min = %g", c_star(c_min), c_min)
    lines = []
    for spec in RUNS:
        out, _ = run(*spec)
        log.info("%s", json.dumps(out))
        lines.append(json.dumps(out))
    for rate in (0.37, 0.5, 0.52, 0.67, 0.84, 1.05):
        out = held_plug(rate)
        log.info("%s", json.dumps(out))
        lines.append(json.dumps(out))
    if args.json is not None:
        args.json.write_text("\n".join(lines) + "\n")
    _, rain = run(0.58, 0.5, 0.56, 100.0, 400, 0.01)
    _, jam = run(0.5846, 0.5, 0.56, 100.0, 400, 0.01)
    if rain is not None and jam is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        figure(rain, jam, c_star(0.56), args.out / "model_closures_open_pipe.png")


if __name__ == "__main__":
    main()
