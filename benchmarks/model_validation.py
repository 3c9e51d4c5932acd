"""Figures and numbers of docs/model.md: the simulation against the linear theory, its
convergence, and what the nonlinear states say about the paper's claim.

    .venv/bin/python benchmarks/model_validation.py [--out docs/figures]

Writes model_growth_rates.png, model_convergence.png, model_nonlinear.png and
model_box_scaling.png, and logs the numbers quoted in docs/model.md (about 2 minutes
on one core). The test suite checks the same properties with tolerances
(tests/test_simulation.py); this script only draws them.
"""

from __future__ import annotations

import argparse
import logging
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from grainplug.plotting.simulation import plot_simulation
from grainplug.simulation import SimulationParams, simulate
from grainplug.simulation.equations import Closure
from grainplug.simulation.validation import fit_modes
from grainplug.simulation.waves import wave_state
from grainplug.stability import ModelParams, roots

log = logging.getLogger("benchmarks.model_validation")
SETUPS = {"frozen friction": {"variant": "frozen-friction"},
          "frozen friction + jamming": {"variant": "frozen-friction", "jamming": True}}


def growth_rates(out: Path) -> None:
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 4.2), constrained_layout=True)
    kk = np.linspace(0.02, 0.6, 300)
    for (label, kw), col, n_cells in zip(SETUPS.items(), ("#d55e00", "#cc79a7"), (512, 1024), strict=True):
        p = ModelParams(**kw)
        w = roots(p, kk)
        i = np.argmax(w.imag, axis=1)
        top = w[np.arange(len(kk)), i]
        ax.plot(kk, top.imag, color=col, label=f"{label}: linear theory")
        bx.plot(kk, top.real / kk * p.v_c_m_s, color=col)
        res = simulate(p, SimulationParams(length_D=2 * np.pi / 0.05, n_cells=n_cells, duration_tc=40.0,
                                           output_interval_tc=0.25, noise=1e-7), rng=np.random.default_rng(1))
        fits = fit_modes(res, range(1, 11), t_from=40.0 / 3)
        ks = [f.k for f in fits]
        ax.plot(ks, [f.growth_sim for f in fits], "o", mfc="none", color=col,
                label=f"{label}: simulation, {n_cells} cells")
        bx.plot(ks, [f.phase_speed_sim * p.v_c_m_s for f in fits], "o", mfc="none", color=col)
        worst_g = max(abs(f.growth_rel_error) for f in fits)
        worst_w = max(abs(f.frequency_rel_error) for f in fits)
        log.info("%s, %d cells: worst growth-rate error %.2f %%, worst frequency error %.3f %% (k* = 0.05..0.5)",
                 label, n_cells, 100 * worst_g, 100 * worst_w)
    ax.axhline(0, color="0.6", lw=0.7)
    ax.set_xlabel("k* = kD")
    ax.set_ylabel("growth rate ω_i t_c")
    ax.legend(fontsize=7)
    ax.set_title("(a) growth rate", loc="left", fontsize=10)
    bx.set_xlabel("k* = kD")
    bx.set_ylabel("phase speed (m s⁻¹)")
    bx.set_title("(b) phase speed of the growing wave", loc="left", fontsize=10)
    fig.savefig(out / "model_growth_rates.png", dpi=110)
    plt.close(fig)


def _smooth(n: int) -> np.ndarray:
    p = ModelParams()
    cl = Closure.from_params(p)
    L, h = 50.0, 50.0 / n
    z = (np.arange(n) + 0.5) * h
    c = cl.c0 + 0.01 * np.sin(2 * np.pi * z / L) * math.sin(math.pi * h / L) / (math.pi * h / L)
    U0 = cl.conserved(c, np.full(n, cl.v0), np.full(n, cl.P0))
    return simulate(p, SimulationParams(length_D=L, n_cells=n, duration_tc=8.0, output_interval_tc=8.0, noise=0.0,
                                        cfl=0.3), initial=U0).c[-1]


def convergence(out: Path) -> None:
    ref = _smooth(4096)
    ns = np.array([32, 64, 128, 256, 512])
    errs = np.array([np.mean(np.abs(_smooth(n) - ref.reshape(n, -1).mean(axis=1))) for n in ns])
    orders = np.log2(errs[:-1] / errs[1:])
    log.info("L1 errors %s, observed orders %s", np.array2string(errs, precision=3),
             np.array2string(orders, precision=2))
    fig, ax = plt.subplots(figsize=(5, 4), constrained_layout=True)
    ax.loglog(ns, errs, "o-", color="k", label="L1 error of c at t = 8 t_c")
    ax.loglog(ns, errs[0] * (ns / ns[0]) ** -2.0, "--", color="0.5", label="second order")
    ax.set_xticks(ns, [str(n) for n in ns])  # the cell counts themselves (log ticks overlapped)
    ax.minorticks_off()
    ax.set_xlabel("cells over 50 D")
    ax.set_ylabel("error against 4096 cells")
    ax.legend(fontsize=8)
    fig.savefig(out / "model_convergence.png", dpi=110)
    plt.close(fig)


def nonlinear(out: Path) -> None:
    res = simulate(ModelParams(variant="frozen-friction"),
                   SimulationParams(length_D=251.0, n_cells=512, duration_tc=400.0, output_interval_tc=0.5),
                   rng=np.random.default_rng(0))
    fig = plot_simulation(res)
    fig.savefig(out / "model_nonlinear.png", dpi=110)
    plt.close(fig)
    w = wave_state(res)
    log.info("frozen friction, 251 D box: %s; drift grain %.1e air %.1e", w, res.grain_drift, res.air_drift)


def box_scaling(out: Path) -> None:
    boxes = np.array([63.0, 125.0, 251.0, 503.0])
    fig, ax = plt.subplots(figsize=(5.5, 4), constrained_layout=True)
    for (label, kw), col in zip(SETUPS.items(), ("#d55e00", "#cc79a7"), strict=True):
        dense, front = [], []
        for L in boxes:
            res = simulate(ModelParams(**kw), SimulationParams(length_D=L, n_cells=int(2 * L), duration_tc=600.0,
                                                               output_interval_tc=0.5, noise=1e-6),
                           rng=np.random.default_rng(0))
            w = wave_state(res)
            dense.append(w.dense_length_D)
            front.append(w.front_speed * res.model.v_c_m_s)
            log.info("%s, box %g D: %d waves, dense segment %.1f D, front %+.3f m/s, c %.3f..%.3f%s", label, L,
                     w.n_waves, w.dense_length_D, w.front_speed * res.model.v_c_m_s, w.c_min, w.c_max,
                     " (still coarsening)" if any("coarsening" in x for x in res.warnings) else "")
        ax.plot(boxes, dense, "o-", color=col, label=label)
    ax.plot(boxes, boxes / 3, ":", color="0.5", label="a third of the box")
    ax.axhline(10, color="k", lw=2, label="measured plugs (10 D)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("periodic box (D)")
    ax.set_ylabel("dense segment at the end (D)")
    ax.legend(fontsize=7)
    fig.savefig(out / "model_box_scaling.png", dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("docs/figures"))
    a = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    a.out.mkdir(parents=True, exist_ok=True)
    growth_rates(a.out)
    convergence(a.out)
    nonlinear(a.out)
    box_scaling(a.out)


if __name__ == "__main__":
    main()
