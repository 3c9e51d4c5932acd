"""Physical inputs of the one-dimensional model and the scales derived from them."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

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


#: wall-friction laws ``F(c, v)`` in the momentum equation (dimensionless, per unit volume)
FRICTION_LAWS = {
    "v2": "as printed: F = 2 b mu_s v^2 (the paper's sigma_zr = rho_s mu_s v^2 / 2; no sign for upward flow)",
    "v|v|": "F = 2 b mu_s v |v|: the printed law with the sign of the velocity (same as v2 for a downward base "
            "flow in the linear analysis; differs for climbing grains)",
    "coulomb-frozen": "Coulomb friction held at its base value F0 = 2 b mu_s v0^2: it does not respond to "
                      "perturbations (the frozen-friction variant)",
    "coulomb-weight": "Coulomb friction following the local weight: F = F0 c / c0 (a Janssen normal stress "
                      "proportional to the grains' weight), F0 = 2 b mu_s v0^2",
    "coulomb-janssen": "rate-independent Coulomb wall friction on Janssen's wall stress: F = 4 mu_s kappa "
                       "sigma_c(c) sgn(v), set-valued (a jammed column held at rest) or regularised as "
                       "tanh(v / v_eps); sigma_c is the contact stress (the jamming pressure, zero below its "
                       "c_min, random loose packing): needs jamming=True (issue 37)",
}
#: air-grain drag laws (the permeability of Darcy's law for the air's flow through the grains)
DRAG_LAWS = {
    "carman-kozeny": "as in the paper: Carman-Kozeny, beta = 180 mu c^2 / (d^2 (1 - c)); vanishes as c -> 0",
    "stokes-carman": "Stokes' single-grain drag added: beta = 18 mu c (1 + 9 c) / (d^2 (1 - c)), which is "
                     "Stokes' 18 mu c / d^2 for dilute grains and within 10 % of Carman-Kozeny in a plug (issue 37)",
}
#: where the coulomb-janssen friction's normal stress comes from
WALL_STRESSES = {
    "local": "the contact stress of each cell is its own jamming pressure sigma_c(c) (zero below c_min): a uniform "
             "plug is held uniformly, its bottom edge included",
    "janssen-column": "Janssen's stress carried down each dense stretch (c > c_min): zero at the stretch's top, "
                      "d sigma / dz = c cos(theta) - 4 mu_s kappa sigma below it (the walls fully mobilised), and zero "
                      "again at its free bottom; its gradient carries the weight down to the walls, so a cell inside "
                      "a stretch is held exactly at Coulomb's limit, while the weight the walls could not hold pushes "
                      "on the lowest grains, which are released (issue 37)",
}
#: base velocities: the printed v* = 1, or the one at which friction carries the weight
BASE_VELOCITIES = ("printed", "balanced")
#: atmospheric pressure, Pa
P_ATM_PA = 101_325.0


#: the largest input a model parameter takes (every one is a size or a material constant)
MAX_INPUT = 1e12


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
        One of :data:`VARIANTS`; ``"frozen-friction"`` is ``friction_law="coulomb-frozen"``.
    friction_law : str, optional
        One of :data:`FRICTION_LAWS` (default: ``"v2"`` as printed, or the variant's).
    base_pressure_pa : float, optional
        Absolute air pressure of the base state, Pa. Default (None): as printed,
        ``P* = 1``, i.e. ``P_c = rho_s g D`` (74 Pa with the paper's inputs);
        :data:`P_ATM_PA` for the atmosphere. The compressibility term ``gamma P / (1 - c)``
        and the diffusivity ``B`` (proportional to ``P``) are both taken at this pressure.
    base_velocity : str
        ``"printed"`` (``v* = 1``) or ``"balanced"``: ``v0*`` such that the wall friction
        carries the weight, ``F(c0, v0) = c0 cos(theta)`` (velocity-dependent laws only).
    jamming : bool
        Add a jamming (frictional contact) pressure ``p_j(c)`` to the grains' momentum
        equation, which diverges at ``jamming_c_max`` and so caps the compactness below
        random close packing (not in the paper). The form of Johnson & Jackson (1987):
        ``p_j = Fr (c - c_min)^2 / (c_max - c)^5`` for ``c > c_min``, else 0.
    jamming_fr_pa, jamming_c_min, jamming_c_max : float
        Its constants: ``Fr`` in Pa (0.05 Pa, Johnson & Jackson's glass beads), the
        compactness where contacts start to last (0.50) and random close packing (0.64).
        With ``friction_law="coulomb-janssen"`` the jamming pressure is the contact (Janssen) stress
        ``sigma_c`` and ``c_min`` is random loose packing (set it to 0.55-0.58).
    janssen_v2_term : bool
        Keep the paper's Janssen term ``(v / kappa) v_z`` in the grains' momentum (default, as printed).
        ``False`` drops it (issue 37's closure, where the Janssen effect is the wall friction on the contact
        stress instead).
    friction_v_eps : float, optional
        Regularisation velocity of the ``coulomb-janssen`` friction, units of ``v_c``:
        ``F = 4 mu_s kappa sigma_c tanh(v / v_eps)``. None (default): exact, set-valued Coulomb friction.
    drag : str
        One of :data:`DRAG_LAWS` (``"carman-kozeny"`` as in the paper).
    wall_stress : str
        One of :data:`WALL_STRESSES`: the normal stress of the ``coulomb-janssen`` friction, each cell's own
        (``"local"``, the default) or carried down each dense stretch (``"janssen-column"``, with the exact
        Coulomb law only: a regularised law cannot hold a cell exactly at its limit).
    mu_static_over_kinetic : float
        Static over kinetic wall friction, ``>= 1``, for the exact (set-valued) Coulomb laws only (issue 37's
        stick-slip trial). ``mu_s`` is then the kinetic coefficient: a sliding cell feels the friction ``F``, a
        cell at rest stays at rest while the force on it is below ``mu_static_over_kinetic * F``. The carried
        Janssen stress is built with the kinetic coefficient. 1 (default): one coefficient, as before.

    Notes
    -----
    The base state ``c = c0, v* = v0, P* = P0*`` is uniform; the linear analysis drops
    the O(1) residual ``-c0 cos(theta) + F(c0, v0)`` of the momentum equation (as the
    paper does) and reports it (:attr:`base_state_residual`). Linearised, the friction
    enters through ``F_c = dF/dc`` and ``F_v = dF/dv`` at the base state.
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
    friction_law: str | None = None
    base_pressure_pa: float | None = None
    base_velocity: str = "printed"
    jamming: bool = False
    jamming_fr_pa: float = 0.05
    jamming_c_min: float = 0.50
    jamming_c_max: float = 0.64
    janssen_v2_term: bool = True
    friction_v_eps: float | None = None
    drag: str = "carman-kozeny"
    wall_stress: str = "local"
    mu_static_over_kinetic: float = 1.0

    def __post_init__(self) -> None:
        from ..params import as_number

        for f in fields(self):  # numbers in another dress (numpy, Decimal) as floats; a string refused
            if "float" in str(f.type) and getattr(self, f.name) is not None:
                value = as_number(getattr(self, f.name))
                if isinstance(value, bool) or not isinstance(value, (int, float)):
                    raise ParameterError(f"must be a number, got {value!r} (a {type(value).__name__})",
                                         param=f.name)
                object.__setattr__(self, f.name, float(value))
        checks = [
            (self.diameter_mm > 0, "diameter must be positive"),
            (self.grain_diameter_um > 0, "grain diameter must be positive"),
            (self.grain_diameter_um * 1e-3 < self.diameter_mm,
             f"the grains (d = {self.grain_diameter_um:g} um) must be smaller than the pipe (D = "
             f"{self.diameter_mm:g} mm)"),
            (self.grain_density_kg_m3 > 0, "grain density must be positive"),
            (self.air_viscosity_pa_s > 0, "air viscosity must be positive"),
            (self.gamma >= 1, "gamma must be >= 1"),
            (self.g_m_s2 > 0, "g must be positive"),
            (0 < self.c0 < 1, "c0 (compactness) must be between 0 and 1"),
            (self.kappa > 0, "kappa must be positive"),
            (self.mu_s >= 0, "mu_s must be non-negative"),
            (abs(self.theta_deg) < 90, "theta must be strictly between -90 and 90 degrees (90: a horizontal pipe, "
                                       "where gravity does not drive the grains along it)"),
            (self.b > 0, "b must be positive"),
            (self.B1_star_override is None or self.B1_star_override >= 0, "B1* must be non-negative"),
            (self.variant in VARIANTS, f"variant must be one of {', '.join(VARIANTS)}"),
            (self.friction_law is None or self.friction_law in FRICTION_LAWS,
             f"friction law must be one of {', '.join(FRICTION_LAWS)}"),
            (self.variant != "frozen-friction" or self.friction_law in (None, "coulomb-frozen"),
             "the frozen-friction variant is the coulomb-frozen friction law: give one or the other"),
            (self.base_pressure_pa is None or (math.isfinite(self.base_pressure_pa) and 0 < self.base_pressure_pa
                                               <= 1e8), "the base pressure must be between 0 and 1e8 Pa"),
            (self.base_velocity in BASE_VELOCITIES, f"base velocity must be one of {', '.join(BASE_VELOCITIES)}"),
            (math.isfinite(self.jamming_fr_pa) and self.jamming_fr_pa >= 0, "the jamming constant Fr must be >= 0 Pa"),
            (0 <= self.jamming_c_min < self.jamming_c_max < 1, "need 0 <= jamming c_min < c_max < 1"),
            (not self.jamming or self.c0 < self.jamming_c_max,
             "c0 must be below the jamming compactness c_max (random close packing)"),
            (self.drag in DRAG_LAWS, f"drag must be one of {', '.join(DRAG_LAWS)}"),
            (self.wall_stress in WALL_STRESSES,
             f"wall stress must be one of {', '.join(WALL_STRESSES)}"),
            (self.wall_stress == "local" or self.law == "coulomb-janssen",
             "the janssen-column wall stress is the coulomb-janssen friction's: give friction_law="
             "\"coulomb-janssen\""),
            (self.wall_stress == "local" or self.friction_v_eps is None,
             "the janssen-column stress holds a stretch's cells exactly at Coulomb's limit, which only the exact "
             "law can hold: leave friction_v_eps= unset"),
            (self.friction_v_eps is None or (math.isfinite(self.friction_v_eps) and self.friction_v_eps > 0),
             "the friction's regularisation velocity v_eps must be positive (None: exact Coulomb friction)"),
            (math.isfinite(self.mu_static_over_kinetic) and self.mu_static_over_kinetic >= 1.0,
             "static friction must be at least the kinetic one: mu_static_over_kinetic >= 1"),
            (self.mu_static_over_kinetic == 1.0 or (self.law.startswith("coulomb") and self.friction_v_eps is None),
             "mu_static_over_kinetic needs the exact (set-valued) Coulomb friction: a coulomb-* law without "
             "friction_v_eps"),
            (self.friction_v_eps is None or self.law == "coulomb-janssen",
             "friction_v_eps regularises the coulomb-janssen friction law only"),
            (self.law != "coulomb-janssen" or self.jamming,
             "the coulomb-janssen friction acts on the contact stress: it needs jamming=True"),
            (self.base_velocity != "balanced" or not self.law.startswith("coulomb")
             or (self.law == "coulomb-janssen" and self.friction_v_eps is not None
                 and self.janssen_stress_ratio > 1.0) or self.wall_stress == "janssen-column",
             "with Coulomb friction the velocity does not set the friction: no velocity balances the weight "
             "(use the v2 or v|v| law, or the printed base velocity; coulomb-janssen balances with a v_eps and a "
             "contact stress at c0 whose friction exceeds the weight)"),
        ]
        for ok, msg in checks:
            if not ok:
                raise ParameterError(msg)
        self._check_scales()

    def _check_scales(self) -> None:
        """Refuse inputs whose scales (B1*, the pressure and time scales) overflow or are not finite: a pipe
        of 1e308 mm is a typing slip, and the model's numbers would be infinite or an OverflowError."""
        for name in ("diameter_mm", "grain_diameter_um", "grain_density_kg_m3", "air_viscosity_pa_s", "g_m_s2",
                     "kappa", "b", "mu_s", "gamma"):
            value = getattr(self, name)
            if not math.isfinite(value) or abs(value) > MAX_INPUT:
                raise ParameterError(f"must be a finite number below {MAX_INPUT:g}, got {value:g}", param=name)
        for scale in ("L_c_m", "t_c_s", "v_c_m_s", "P_c_pa", "B1_star"):
            try:
                value = float(getattr(self, scale))
            except (OverflowError, ZeroDivisionError, ValueError):
                value = math.inf
            if not math.isfinite(value):
                raise ParameterError(f"these inputs make the model's scale {scale} {value:g}: give the pipe "
                                     "(diameter_mm=) and grains (grain_diameter_um=, grain_density_kg_m3=) sizes "
                                     "of a laboratory")

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

    # -- the set-up -----------------------------------------------------------------
    @property
    def law(self) -> str:
        """The friction law in use (:data:`FRICTION_LAWS`)."""
        if self.friction_law is not None:
            return self.friction_law
        return "coulomb-frozen" if self.variant == "frozen-friction" else "v2"

    @property
    def is_printed(self) -> bool:
        """Whether the set-up is the paper's as printed (friction law, base pressure and velocity)."""
        return (self.law == "v2" and self.base_pressure_pa is None and self.base_velocity == "printed"
                and not self.jamming and self.janssen_v2_term and self.drag == "carman-kozeny"
                and self.wall_stress == "local" and self.mu_static_over_kinetic == 1.0)

    @property
    def P0_star(self) -> float:
        """Base pressure in units of ``P_c`` (1 as printed)."""
        return 1.0 if self.base_pressure_pa is None else self.base_pressure_pa / self.P_c_pa

    @property
    def base_pressure_abs_pa(self) -> float:
        """The base state's absolute air pressure, Pa."""
        return self.P_c_pa * self.P0_star

    @property
    def v0_star(self) -> float:
        """Base velocity in units of ``v_c`` (1 as printed; balanced: ``sqrt(c0 cos(theta) / (2 b mu_s))``)."""
        if self.base_velocity == "printed" or self.wall_stress == "janssen-column":  # any velocity balances
            return 1.0
        if self.law == "coulomb-janssen":  # 4 mu kappa sigma_c(c0) tanh(v0 / v_eps) = c0 cos(theta)
            return float(self.friction_v_eps or 0.0) * math.atanh(1.0 / self.janssen_stress_ratio)
        if self.mu_s == 0:
            raise ParameterError("without friction (mu_s = 0) no velocity balances the weight")
        return math.sqrt(self.c0 * math.cos(math.radians(self.theta_deg)) / (2.0 * self.b * self.mu_s))

    @property
    def contact_stress(self) -> float:
        """The contact stress ``sigma_c(c0) = p_j(c0) / P_c`` (0 without jamming or below ``c_min``)."""
        if not self.jamming or self.c0 <= self.jamming_c_min:
            return 0.0
        x, y = self.c0 - self.jamming_c_min, self.jamming_c_max - self.c0
        return self.jamming_fr_pa * x * x / y**5 / self.P_c_pa if y > 0 else math.inf

    @property
    def janssen_stress_ratio(self) -> float:
        """The largest wall friction of the base state over the grains' weight, ``4 mu_s kappa sigma_c(c0) /
        (c0 cos theta)``: above 1 the walls can hold the column at rest."""
        return 4.0 * self.mu_s * self.kappa * self.contact_stress / (self.c0 * math.cos(math.radians(self.theta_deg)))

    def _janssen_tanh(self) -> tuple[float, float]:
        """``tanh(v0 / v_eps)`` and its derivative in ``v0`` (1 and 0 for the exact law with v0 > 0)."""
        v0 = self.v0_star
        if self.friction_v_eps is None:
            return math.copysign(1.0, v0) if v0 != 0 else 0.0, 0.0
        t = math.tanh(v0 / self.friction_v_eps)
        return t, (1.0 - t * t) / self.friction_v_eps

    @property
    def base_friction(self) -> float:
        """``F0 = F(c0, v0)``: the wall friction of the base state (a uniform dense column carrying Janssen's
        stress: its saturated value, the weight)."""
        if self.wall_stress == "janssen-column":
            return self.c0 * math.cos(math.radians(self.theta_deg))
        if self.law == "coulomb-janssen":
            return 4.0 * self.mu_s * self.kappa * self.contact_stress * self._janssen_tanh()[0]
        v0 = self.v0_star
        return 2.0 * self.b * self.mu_s * v0 * abs(v0)

    @property
    def friction(self) -> float:
        """``F_v = dF/dv`` at the base state: the coefficient of ``v~`` in the perturbed momentum equation."""
        if self.wall_stress == "janssen-column":
            return 0.0
        if self.law == "coulomb-janssen":
            return 4.0 * self.mu_s * self.kappa * self.contact_stress * self._janssen_tanh()[1]
        return 0.0 if self.law.startswith("coulomb") else 4.0 * self.b * self.mu_s * abs(self.v0_star)

    @property
    def friction_c(self) -> float:
        """``F_c = dF/dc`` at the base state: the coefficient of ``c~`` from the friction.

        With the ``janssen-column`` stress, a sliding uniform column's perturbation ``c~ e^{ikz}`` carries the
        stress ``sigma~ = c~ cos(theta) / (4 mu_s kappa + i k)``, and the weight, the stress's gradient and the
        wall friction on it cancel mode by mode: ``c~ cos(theta) - i k sigma~ - 4 mu_s kappa sigma~ = 0``, i.e.
        ``F_c = cos(theta)`` for the stress gradient and friction together."""
        if self.wall_stress == "janssen-column":
            return math.cos(math.radians(self.theta_deg))
        if self.law == "coulomb-janssen":
            return 4.0 * self.mu_s * self.kappa * self.jamming_slope * self._janssen_tanh()[0]
        return self.base_friction / self.c0 if self.law == "coulomb-weight" else 0.0

    @property
    def drag_factor(self) -> float:
        """The permeability at ``c0`` relative to Carman-Kozeny's: ``10 c0 / (1 + 9 c0)`` with Stokes' drag
        added (:data:`DRAG_LAWS`), else 1."""
        return 10.0 * self.c0 / (1.0 + 9.0 * self.c0) if self.drag == "stokes-carman" else 1.0

    @property
    def jamming_slope(self) -> float:
        """``d p_j* / dc`` at ``c0`` (``p_j* = p_j / P_c``): the jamming pressure's coefficient of
        ``i k c~`` in the perturbed momentum equation; 0 without jamming or below ``c_min``."""
        if not self.jamming or self.c0 <= self.jamming_c_min:
            return 0.0
        x, y = self.c0 - self.jamming_c_min, self.jamming_c_max - self.c0
        return self.jamming_fr_pa * (2 * x / y**5 + 5 * x**2 / y**6) / self.P_c_pa

    @property
    def B_star(self) -> float:
        """Dimensionless diffusivity of the air pressure at the base pressure, ``B1* P0*``."""
        return self.B1_star * self.P0_star * self.drag_factor

    @property
    def base_state_residual(self) -> float:
        """Steady uniform momentum balance at the base state, ``-c0 cos(theta) + F(c0, v0)``.

        Zero if the base state were a solution of the momentum equation; the paper's
        set-up gives ``-c0 cos(theta) + 2 b mu_s`` = +0.70: friction exceeds gravity.
        """
        return -self.c0 * math.cos(math.radians(self.theta_deg)) + self.base_friction

    def caveats(self) -> list[str]:
        """What the reader of a result for this set-up must know, one sentence each."""
        out = []
        if abs(self.base_state_residual) > 1e-9:
            out.append(f"the base state is not steady: friction minus weight is {self.base_state_residual:+.3f} "
                       "(in units of rho_s g); the linear analysis drops this imbalance, as the paper does")
        if self.base_pressure_pa is None:
            out.append(f"P* = 1 means an absolute air pressure of {self.P_c_pa:.0f} Pa, 1/{P_ATM_PA / self.P_c_pa:.0f} "
                       "of the atmosphere (as printed; base_pressure_pa=101325 for the real one)")
        if self.law == "coulomb-frozen":
            out.append("frozen friction is a change of wall-friction law (a Coulomb stress held at its base value, "
                       "not the paper's closure rho_s mu_s v^2 / 2, which it contradicts); its long-wave "
                       "instability needs the printed 74 Pa base pressure")
        if self.law == "coulomb-weight":
            out.append("Coulomb friction following the local weight is not the paper's closure")
        if self.jamming:
            out.append(f"the jamming pressure (Johnson & Jackson's form, Fr = {self.jamming_fr_pa:g} Pa, c_max = "
                       f"{self.jamming_c_max:g}) is not in the paper; its slope at c0, "
                       f"{self.jamming_slope:.3g} P_c, depends steeply on c_max")
        ratio = self.diameter_mm * 1e3 / self.grain_diameter_um
        if ratio < 6:
            out.append(f"D/d = {ratio:.3g}, below the paper's 6 to 30: the model treats the grains as a continuum "
                       "with Darcy's permeability, which needs many grains across the pipe")
        if self.c0 > 0.64:
            out.append(f"c0 = {self.c0:g} is above random close packing (0.64): spheres cannot pack that tight")
        if self.law == "coulomb-janssen":
            out.append("Coulomb wall friction on the contact stress (Janssen) is not the paper's closure (issue 37)")
        if self.wall_stress == "janssen-column":
            out.append("Janssen's stress carried down each dense stretch and zero at its free bottom (issue 37): a "
                       "uniform column in a periodic box slides at any velocity (its weight, stress gradient and "
                       "wall friction cancel), the linear analysis is of that neutral state")
        if not self.janssen_v2_term:
            out.append("the paper's Janssen term (v / kappa) v_z is dropped (issue 37's closure)")
        if self.drag != "carman-kozeny":
            out.append("Stokes' single-grain drag is added to Carman-Kozeny's (not the paper's closure)")
        if self.law == "v|v|":
            out.append("v|v| differs from the printed v^2 only for climbing grains; for this downward base flow "
                       "their linear analyses are the same")
        return out

    def as_dict(self) -> dict[str, object]:
        d = asdict(self)
        d.update(B1_star=self.B1_star, B1_star_computed=self.B1_star_computed, P_c_pa=self.P_c_pa,
                 t_c_s=self.t_c_s, v_c_m_s=self.v_c_m_s, L_c_m=self.L_c_m,
                 base_state_residual=self.base_state_residual, friction_law_used=self.law,
                 base_pressure_abs_pa=self.base_pressure_abs_pa, P0_star=self.P0_star, v0_star=self.v0_star,
                 v0_m_s=self.v0_star * self.v_c_m_s, B_star=self.B_star, printed_setup=self.is_printed,
                 jamming_slope=self.jamming_slope)
        if self.law == "coulomb-janssen":
            d.update(contact_stress=self.contact_stress, janssen_stress_ratio=self.janssen_stress_ratio)
        return d
