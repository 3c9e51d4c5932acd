"""The nonlinear 1D grain-air model in conservative form: variables, fluxes, wave speeds.

Notes
-----
Dimensionless as in the paper (length ``D``, time ``t_c = sqrt(D/g)``, velocity
``v_c = sqrt(g D)``, pressure ``P_c = rho_s g D``; stars dropped). The conserved
variables per unit pipe volume are

- the compactness ``c`` (grain volume fraction);
- the grain momentum ``q = c v``;
- the air mass ``m = r (1 - c)``, with ``r = rho_a / rho_a0`` the air density in units of
  its value at the base pressure ``P0``; the air is isentropic, ``P = P0 r^gamma``.

They obey

.. math::

    c_t + (c v)_z &= 0 \\\\
    q_t + \\left(q v + \\frac{v^2}{2\\kappa} + P + p_j(c)\\right)_z &= c\\cos\\theta + S - F(c, v) \\\\
    m_t + \\left(m v - r K(c) P_z\\right)_z &= 0

The first two are the paper's eqs. (1) and (3) with the Janssen term written as the
flux it is (``(v/kappa) v_z = (v^2 / 2 kappa)_z``), plus the optional jamming
pressure ``p_j`` (Johnson & Jackson 1987). The third replaces the printed,
non-conservative pressure equation (eq. 6) by the air's mass balance with Darcy's law
and the Carman-Kozeny permeability ``K(c) ∝ (1 - c)^3 / c^2`` that eq. (7) assumes:
linearised about a uniform state it is eq. (6) exactly (``tests/test_simulation.py``
checks the linearisation against the stability matrix), but it conserves the air, which
the printed equation does not through a compaction front. ``K`` is scaled so that
``gamma P0 K(c0) / (1 - c0) = B1* P0``, the paper's diffusivity.

``S`` is a constant force per unit volume that makes the uniform base state steady in
a periodic box, ``S = F(c0, v0) - c0 cos(theta)``: the linear analysis drops this
residual of the momentum balance, and adding it back as a uniform force (a mean
pressure gradient) leaves the linearised equations unchanged. With a base velocity
that balances the weight, ``S = 0``.

The hyperbolic part has the characteristic speeds ``v`` and ``v + s``, where
``s^2 - s v / (kappa c) - (gamma P / (c (1 - c)) + p_j'(c)) = 0``.

References
----------
C. A. Alvarez, E. M. Franklin, Physica A 465 (2017) 725-741, eqs. (1)-(7).
P. C. Johnson, R. Jackson, J. Fluid Mech. 176 (1987) 67-93 (frictional pressure).
Y. Bertho, F. Giorgiutti-Dauphiné, J.-P. Hulin, Phys. Fluids 15 (2003) 3358 (air).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from ..stability.params import ModelParams

#: below this compactness the grain velocity is not defined: cells are treated as empty
C_FLOOR = 1e-6


@dataclass(frozen=True)
class Closure:
    """The constants of the nonlinear equations for one set-up (dimensionless).

    Built from :class:`~grainplug.stability.ModelParams` by :meth:`from_params`.
    """

    c0: float
    v0: float
    P0: float
    gamma: float
    kappa: float
    cos_theta: float
    law: str
    F0: float
    alpha: float
    K0: float
    balance_force: float
    jamming: bool
    jam_fr: float
    jam_c_min: float
    jam_c_max: float
    #: 1 with the paper's Janssen term ``(v^2 / 2 kappa)_z``, 0 without it
    jterm: float = 1.0
    #: ``4 mu_s kappa``: the coulomb-janssen friction is ``wall * sigma_c(c)``
    wall: float = 0.0
    #: its regularisation velocity (0: exact, set-valued)
    v_eps: float = 0.0
    #: Stokes' drag added to Carman-Kozeny's (``DRAG_LAWS``)
    stokes: bool = False
    #: the coulomb-janssen friction on Janssen's stress carried down each dense stretch (``WALL_STRESSES``)
    column: bool = False
    #: static over kinetic friction of the exact Coulomb laws (1: one coefficient)
    stick: float = 1.0

    @classmethod
    def from_params(cls, p: ModelParams, *, balance: bool = True) -> Closure:
        """The closure of ``p``; ``balance`` adds the force that makes the base state steady."""
        if p.mu_s == 0 and p.law.startswith("coulomb"):
            raise ParameterError("Coulomb friction needs mu_s > 0")
        c0, P0 = p.c0, p.P0_star
        cos_theta = math.cos(math.radians(p.theta_deg))
        # gamma P0 K(c0) / (1 - c0) = B1* P0  ->  K(c0) = B1* (1 - c0) / gamma
        K0 = p.B1_star * (1 - c0) / p.gamma
        if p.law == "coulomb-janssen" and p.mu_s * p.kappa == 0:
            raise ParameterError("Coulomb friction on the contact stress needs mu_s > 0")
        return cls(c0=c0, v0=p.v0_star, P0=P0, gamma=p.gamma, kappa=p.kappa, cos_theta=cos_theta, law=p.law,
                   F0=p.base_friction, alpha=2.0 * p.b * p.mu_s, K0=K0,
                   balance_force=p.base_state_residual if balance else 0.0, jamming=p.jamming,
                   jam_fr=p.jamming_fr_pa / p.P_c_pa, jam_c_min=p.jamming_c_min, jam_c_max=p.jamming_c_max,
                   jterm=1.0 if p.janssen_v2_term else 0.0, wall=4.0 * p.mu_s * p.kappa,
                   v_eps=p.friction_v_eps or 0.0, stokes=p.drag == "stokes-carman",
                   column=p.wall_stress == "janssen-column", stick=p.mu_static_over_kinetic)

    # -- closures -------------------------------------------------------------------
    def permeability(self, c: np.ndarray) -> np.ndarray:
        """``K(c) = K(c0) [(1 - c)^3 / c^2] / [(1 - c0)^3 / c0^2]`` (Carman-Kozeny)."""
        c = np.maximum(c, C_FLOOR)
        K = self.K0 * ((1 - c) ** 3 / c**2) * (self.c0**2 / (1 - self.c0) ** 3)
        return K * (10 * c / (1 + 9 * c)) if self.stokes else K

    def jamming_pressure(self, c: np.ndarray) -> np.ndarray:
        """``p_j = Fr (c - c_min)^2 / (c_max - c)^5`` above ``c_min`` (0 without jamming)."""
        if not self.jamming:
            return np.zeros_like(c)
        x = np.maximum(c - self.jam_c_min, 0.0)
        y = np.maximum(self.jam_c_max - c, 1e-4)
        return self.jam_fr * x**2 / y**5

    def jamming_slope(self, c: np.ndarray) -> np.ndarray:
        """``dp_j / dc``."""
        if not self.jamming:
            return np.zeros_like(c)
        x = np.maximum(c - self.jam_c_min, 0.0)
        y = np.maximum(self.jam_c_max - c, 1e-4)
        return self.jam_fr * (2 * x / y**5 + 5 * x**2 / y**6)

    # -- variables ---------------------------------------------------------------
    def pressure(self, r: np.ndarray) -> np.ndarray:
        """Isentropic air: ``P = P0 r^gamma``."""
        return self.P0 * np.power(np.maximum(r, 0.0), self.gamma)

    def air_density(self, P: np.ndarray) -> np.ndarray:
        """``r = (P / P0)^(1/gamma)``."""
        return np.power(np.maximum(P, 0.0) / self.P0, 1.0 / self.gamma)

    def primitive(self, U: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(c, v, P)`` from the conserved ``U = (c, q, m)`` (shape ``(3, n)``)."""
        c, q, m = U
        cs = np.maximum(c, C_FLOOR)
        v = np.where(c > C_FLOOR, q / cs, 0.0)
        return c, v, self.pressure(m / (1 - c))

    def conserved(self, c: np.ndarray, v: np.ndarray, P: np.ndarray) -> np.ndarray:
        """``U = (c, c v, r (1 - c))``."""
        return np.stack([c, c * v, self.air_density(P) * (1 - c)])

    def flux(self, c: np.ndarray, v: np.ndarray, P: np.ndarray, r: np.ndarray | None = None) -> np.ndarray:
        """The hyperbolic flux ``(c v, c v^2 + v^2 / 2 kappa + P + p_j, m v)``, ``m = r (1 - c)``; ``r`` defaults
        to the air density of ``P``."""
        m = (self.air_density(P) if r is None else r) * (1 - c)
        return np.stack([c * v, c * v * v + self.jterm * (v * v / (2 * self.kappa)) + P + self.jamming_pressure(c),
                         m * v])

    def speeds(self, c: np.ndarray, v: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Smallest and largest characteristic speeds ``(v + s-, v + s+)``."""
        cs = np.maximum(c, C_FLOOR)
        b = self.jterm * (v / (self.kappa * cs))
        a = self.gamma * P / (cs * (1 - c)) + self.jamming_slope(c)
        root = np.sqrt(b * b + 4 * a)
        return v + 0.5 * (b - root), v + 0.5 * (b + root)
