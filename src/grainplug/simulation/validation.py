"""Compare a simulation's linear phase with the linear stability analysis.

Notes
-----
In a periodic box of length ``L`` the perturbation ``(c - c0, v - v0, P - P0)`` is
expanded in Fourier modes ``k_n = 2 pi n / L``. For each ``k_n`` the three-component
amplitude is projected on the eigenvector of the chosen root of the stability matrix
(:func:`grainplug.stability.system_matrices`), using the left eigenvectors, so the
other two roots do not leak in. While the perturbation is small, that projection
evolves as ``exp(-i omega t)``: the slope of ``log|a|`` is the growth rate
``omega_i`` and the slope of the unwrapped phase is ``-omega_r``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..stability.model import system_matrices
from .state import SimulationResult


@dataclass(frozen=True)
class ModeFit:
    """One Fourier mode of a simulation against the linear theory (units of ``t_c``, ``v_c``)."""

    k: float
    growth_sim: float
    growth_linear: float
    omega_r_sim: float
    omega_r_linear: float

    @property
    def growth_rel_error(self) -> float:
        return (self.growth_sim - self.growth_linear) / abs(self.growth_linear)

    @property
    def frequency_rel_error(self) -> float:
        """Error of ``omega_r`` relative to ``|omega|``."""
        return (self.omega_r_sim - self.omega_r_linear) / abs(complex(self.omega_r_linear, self.growth_linear))

    @property
    def phase_speed_sim(self) -> float:
        return self.omega_r_sim / self.k

    @property
    def phase_speed_linear(self) -> float:
        return self.omega_r_linear / self.k


def fit_modes(res: SimulationResult, modes: list[int] | np.ndarray, *, t_from: float = 0.0,
              t_to: float | None = None) -> list[ModeFit]:
    """Fit growth rate and frequency of the most unstable root for Fourier modes ``n`` (``k = 2 pi n / L``)."""
    if res.params.boundary != "periodic":
        raise ValueError("the modal fit needs a periodic box")
    L = res.params.length_D
    sel = (res.time >= t_from) & (res.time <= (res.time[-1] if t_to is None else t_to))
    base = np.array([res.model.c0, res.model.v0_star, res.model.P0_star])[None, :, None]
    fields = np.stack([res.c, res.v, res.P], axis=1)[sel] - base  # (t, 3, z)
    spec = np.fft.fft(fields, axis=2)
    t = res.time[sel]
    ns = np.asarray(modes, dtype=int)
    ks = 2 * np.pi * ns / L
    A, E = system_matrices(res.model, ks)
    out = []
    for j, (n, k) in enumerate(zip(ns, ks, strict=True)):
        lam, V = np.linalg.eig(A[j] / np.diag(E)[:, None])
        omega = -1j * lam
        i = int(np.argmax(omega.imag))
        a = spec[:, :, n] @ np.linalg.inv(V)[i]
        growth = np.polyfit(t, np.log(np.abs(a)), 1)[0]
        omega_r = -np.polyfit(t, np.unwrap(np.angle(a)), 1)[0]
        out.append(ModeFit(float(k), float(growth), float(omega[i].imag), float(omega_r), float(omega[i].real)))
    return out
