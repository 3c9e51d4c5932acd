"""Which single assumption makes the paper's 1D model unstable? (docs/stability.md)

    .venv/bin/python scripts/stability_assumptions.py

Changes one assumption of the printed linear model at a time and prints the most
unstable k* and the unstable band. The base-state and pressure variants need a
linearisation about other base values (v0, P0), so the matrix is built here
directly: rows are grain mass, grain momentum and air pressure, as in
grainplug.stability.model but with base velocity v0 and base pressure P0.
"""

from __future__ import annotations

import math

import numpy as np

from grainplug.stability import ModelParams

P = ModelParams()
K = np.linspace(1e-3, 3, 6000)


def growth(k: np.ndarray, *, B1: float = P.B1_star, c0: float = P.c0, kappa: float = P.kappa,
           friction: float = 4 * P.mu_s, theta: float = 0.0, v0: float = 1.0, P0: float = 1.0) -> np.ndarray:
    """Largest growth rate at each k for the linearisation about (c0, v0, P0)."""
    n = len(k)
    A = np.zeros((n, 3, 3), complex)
    ik = 1j * k
    A[:, 0, 0] = ik * v0
    A[:, 0, 1] = ik * c0
    A[:, 1, 0] = -math.cos(theta)
    A[:, 1, 1] = ik * c0 * v0 + ik * v0 / kappa + friction
    A[:, 1, 2] = ik
    A[:, 2, 1] = P.gamma * P0 / (1 - c0) * ik
    A[:, 2, 2] = ik * v0 + B1 * k**2
    lam = np.linalg.eigvals(A / np.array([1.0, c0, 1.0])[None, :, None])
    return (-1j * lam).imag.max(axis=1)


def report(name: str, **kw: float) -> None:
    g = growth(K, **kw)
    j = int(np.argmax(g))
    band = K[g > 0]
    if band.size:
        print(f"{name:46s} most unstable k* = {K[j]:.3f} (growth {g[j]:+.4f}), unstable k* in "
              f"[{band.min():.3f}, {band.max():.3f}]")
    else:
        print(f"{name:46s} stable (max growth {g.max():+.2e})")


def main() -> None:
    mu, c0 = P.mu_s, P.c0
    report("printed")
    report("frozen friction (perturbation of 4 mu_s v dropped)", friction=0.0)
    report("friction from a balanced base state", friction=2 * c0)
    report("balanced base velocity v0", v0=math.sqrt(c0 / (2 * mu)), friction=4 * mu * math.sqrt(c0 / (2 * mu)))
    report("friction linearised as 2 mu_s", friction=2 * mu)
    report("no Janssen term (kappa -> inf)", kappa=1e12)
    report("B1* x 10", B1=10 * P.B1_star)
    report("B1* / 10", B1=P.B1_star / 10)
    report("gravity reversed", theta=math.pi)
    pa = 101325.0 / P.P_c_pa
    report("absolute (atmospheric) base pressure", P0=pa, B1=P.B1_star * pa)


if __name__ == "__main__":
    main()
