"""Physical inputs of the one-dimensional model and the scales derived from them."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from ..errors import ParameterError

#: model variants: the printed equations, and the one assumption that reproduces the claim
VARIANTS = {
    "printed": (
        "the equations exactly as printed (linearised wall friction 4 b mu_s v~ included)"
    ),
    "frozen-friction": (
        "wall friction set by the base state only: its perturbation 4 b mu_s v~ is dropped "
        "(friction does not respond to velocity perturbations, as a Coulomb force held at the "
        "base-state value would not); reproduces the paper's long-wave instability"
    ),
}


@dataclass(frozen=True)
class ModelParams:
    """Inputs of the model of Alvarez & Franklin (2017), in SI-friendly units.

    Attributes
    ----------
    diameter_mm : float
        Pipe inner diameter ``D``.
    grain_diameter_um : float
        Median grain diameter ``d``.
    grain_density_kg_m3 : float
        Density of the grains' material ``rho_s``.
    air_viscosity_pa_s : float
        Dynamic viscosity of air ``mu_a``.
    gamma : float
        Ratio of specific heats of air.
    g_m_s2 : float
        Gravity.
    c0 : float
        Base-state compactness.
    kappa : float
        Janssen redirection coefficient (``sigma_zr = mu_s kappa sigma_zz``).
    mu_s : float
        Friction coefficient (``tan 32 deg`` in the paper).
    theta_deg : float
        Inclination of the pipe from the vertical.
    b : float
        Capillary factor on the wall friction (``b >= 1``; 1 in the paper).
    B1_star_override : float, optional
        Use this ``B1*`` instead of computing it from the inputs.
    variant : str
        One of :data:`VARIANTS`.
    """

    diameter_mm: float = 3.0
    grain_diameter_um: float = 225.0
    grain_density_kg_m3: float = 2500.0
    air_viscosity_pa_s: float = 1.8e-5
    gamma: float = 1.4
    g_m_s2: float = 9.81
    c0: float = 0.55
    kappa: float = 0.5
    mu_s: float = math.tan(math.radians(32.0))
    theta_deg: float = 0.0
    b: float = 1.0
    B1_star_override: float | None = None
    variant: str = "printed"

    def __post_init__(self) -> None:
        checks = [
            (self.diameter_mm > 0, "diameter must be positive"),
            (self.grain_diameter_um > 0, "grain diameter must be positive"),
            (self.grain_density_kg_m3 > 0, "grain density must be positive"),
            (self.air_viscosity_pa_s > 0, "air viscosity must be positive"),
            (self.gamma >= 1, "gamma must be >= 1"),
            (self.g_m_s2 > 0, "g must be positive"),
            (0 < self.c0 < 1, "c0 (compactness) must be between 0 and 1"),
            (self.kappa > 0, "kappa must be positive"),
            (self.mu_s >= 0, "mu_s must be non-negative"),
            (abs(self.theta_deg) < 90, "theta must be within +-90 degrees"),
            (self.b > 0, "b must be positive"),
            (self.B1_star_override is None or self.B1_star_override >= 0, "B1* must be non-negative"),
            (self.variant in VARIANTS, f"variant must be one of {', '.join(VARIANTS)}"),
        ]
        for ok, msg in checks:
            if not ok:
                raise ParameterError(msg)

    # -- scales ----------------------------------------------------------------
    @property
    def D_m(self) -> float:
        return self.diameter_mm * 1e-3

    @property
    def d_m(self) -> float:
        return self.grain_diameter_um * 1e-6

    @property
    def L_c_m(self) -> float:
        """Length scale ``L_c = D``."""
        return self.D_m

    @property
    def t_c_s(self) -> float:
        """Time scale ``t_c = sqrt(D / g)``."""
        return math.sqrt(self.D_m / self.g_m_s2)

    @property
    def v_c_m_s(self) -> float:
        """Velocity scale ``v_c = sqrt(g D)``."""
        return math.sqrt(self.g_m_s2 * self.D_m)

    @property
    def P_c_pa(self) -> float:
        """Pressure scale ``P_c = rho_s g D``."""
        return self.grain_density_kg_m3 * self.g_m_s2 * self.D_m

    @property
    def B1_star_computed(self) -> float:
        """``B1* = B(P = P_c, c = c0) g^-1/2 D^-3/2`` with the Carman-Kozeny ``B``.

        ``B = gamma P (1 - c)^2 d^2 / (180 mu_a c^2)``, so
        ``B1* = gamma rho_s g^1/2 d^2 (1 - c0)^2 / (180 mu_a c0^2 D^1/2)``.
        """
        B = (self.gamma * self.P_c_pa * (1 - self.c0) ** 2 * self.d_m**2
             / (self.air_viscosity_pa_s * 180.0 * self.c0**2))
        return B / (math.sqrt(self.g_m_s2) * self.D_m**1.5)

    @property
    def B1_star(self) -> float:
        """The ``B1*`` in use (override, or computed)."""
        return self.B1_star_override if self.B1_star_override is not None else self.B1_star_computed

    @property
    def friction(self) -> float:
        """Coefficient of ``v~`` from the wall friction in the perturbed momentum equation."""
        return 0.0 if self.variant == "frozen-friction" else 4.0 * self.b * self.mu_s

    @property
    def base_state_residual(self) -> float:
        """Steady uniform momentum balance at the base state, ``-c0 cos(theta) + 2 b mu_s``.

        Zero if the base state (v* = 1, c = c0) were a solution of the momentum
        equation; the paper's values give 0.70, i.e. friction exceeds gravity.
        """
        return -self.c0 * math.cos(math.radians(self.theta_deg)) + 2.0 * self.b * self.mu_s

    def as_dict(self) -> dict[str, object]:
        d = asdict(self)
        d.update(B1_star=self.B1_star, B1_star_computed=self.B1_star_computed, P_c_pa=self.P_c_pa,
                 t_c_s=self.t_c_s, v_c_m_s=self.v_c_m_s, L_c_m=self.L_c_m,
                 base_state_residual=self.base_state_residual)
        return d
