"""Issue 37, fourth step: the three scratch trials of docs/model.md's subsection "Static wall friction above kinetic
(...), and two quick trials", reproduced. They are NOT in the library: each patches the NumPy engine's carried stress
or its sources in this process only, to see whether a closure is worth building.

    .venv/bin/python benchmarks/closures_trials.py TRIAL [--cells 200] [--param X]

TRIAL is one of
- ``mobilised``: Janssen's stress carried with ``mu_k / X`` (default X = 1.2): a sliding cell's kinetic friction
  is X times its weight plus the stress's push;
- ``unified``: one contact stress, the walls' hold on ``max(sigma, p_j(c))``;
- ``viscous``: a grain-phase viscosity ``(c nu v_z)_z``, ``nu = X d sqrt(g d) g0(c)``, ``g0 = 1 / (1 - (c /
  c_max)^(1/3))`` (kinetic-theory scaling, Lun & Savage's radial distribution), explicit and conservative, no
  viscous flux through the ends (default X = alpha = 1).

Each runs the held plug of ``closures_janssen_column.py`` (a 30 D plug at c = 0.60 at the outlet of a 100 D pipe,
rain at c = 0.58 and 0.5 g/s, 60 t_c) on the NumPy engine (about 45 s at 200 cells) and logs one JSON line.
"""

from __future__ import annotations

import argparse
import json
import logging
import math

import closures_janssen_column
import numpy as np
from closures_janssen_column import model, run

import grainplug.simulation.run as run_module
import grainplug.simulation.scheme as scheme
from grainplug.simulation.equations import Closure

log = logging.getLogger("closures_trials")


def patch(trial: str, x: float) -> None:
    """Patch the NumPy engine for ``trial`` (this process only)."""
    carried = scheme.column_stress
    m = model()
    cl = Closure.from_params(m, balance=False)
    if trial == "mobilised":
        def column_stress(c, w, wall, c_min, dx, periodic):  # type: ignore[no-untyped-def]
            push, cap = carried(c, w, wall / x, c_min, dx, periodic)
            return push, x * cap
        scheme.column_stress = column_stress
    elif trial == "unified":
        def column_stress(c, w, wall, c_min, dx, periodic):  # type: ignore[no-untyped-def]
            push, cap = carried(c, w, wall, c_min, dx, periodic)
            return push, np.maximum(cap, wall * cl.jamming_pressure(c))
        scheme.column_stress = column_stress
    elif trial == "viscous":
        nu0 = x * m.d_m * math.sqrt(m.g_m_s2 * m.d_m) / (m.D_m * m.v_c_m_s)  # units of D v_c
        sources = scheme.Integrator.sources

        def viscous_sources(self, U, dt):  # type: ignore[no-untyped-def]
            out = sources(self, U, dt)
            c, q = out[0], out[1]
            v = np.where(c > 1e-9, q / np.maximum(c, 1e-9), 0.0)
            cn = c * nu0 / (1.0 - (np.minimum(c, 0.999 * cl.jam_c_max) / cl.jam_c_max) ** (1 / 3))
            f = np.r_[0.0, 0.5 * (cn[1:] + cn[:-1]) * np.diff(v) / self.dx, 0.0]
            out[1] = q + dt * np.diff(f) / self.dx
            return out
        scheme.Integrator.sources = viscous_sources
    simulate = run_module.simulate
    closures_janssen_column.simulate = lambda mm, p, **kw: simulate(mm, p.replace(engine="numpy"), **kw)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("trial", choices=["mobilised", "unified", "viscous"])
    ap.add_argument("--cells", type=int, default=200)
    ap.add_argument("--param", type=float, default=None, help="X (mobilised: 1.2; viscous: alpha = 1)")
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    x = args.param if args.param is not None else {"mobilised": 1.2, "viscous": 1.0}.get(args.trial, 1.0)
    patch(args.trial, x)
    out, _ = run("held", cells=args.cells)
    out.update(trial=args.trial, param=x)
    log.info(json.dumps({k: v for k, v in out.items() if k not in ("c_range_end", "v_range_end")}))


if __name__ == "__main__":
    main()
