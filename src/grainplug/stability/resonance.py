"""Acoustic resonance of the grain-air column (the paper's 4 Hz vs 7 Hz discussion).

Notes
-----
*Mixture sound speed (Wood's relation).* For a suspension of grains (volume
fraction ``c``, density ``rho_s``, sound speed ``a_s``) in air (``1 - c``,
``rho_a``, ``a_a``) at wavelengths much longer than the grains, the mixture
density and compressibility are volume averages:

.. math:: \\rho_m = c \\rho_s + (1 - c) \\rho_a, \\qquad
          \\frac{1}{\\rho_m a_m^2} = \\frac{c}{\\rho_s a_s^2} + \\frac{1 - c}{\\rho_a a_a^2}

(A. B. Wood, *A Textbook of Sound*, 1930, sec. 27; also Brennen, *Fundamentals
of Multiphase Flow*, 2005, eq. 9.7). The air's sound speed is
``a_a^2 = n P / rho_a`` with ``n = gamma`` (adiabatic) or ``n = 1``
(isothermal: heat exchange with fine grains is fast), and
``rho_a = P / (R_air T)``.

*Column modes.* A column of length ``L`` has the modes of a pipe
(Kinsler et al., *Fundamentals of Acoustics*, 4th ed., 2000, sec. 10.2):
half-wave ``f_n = n a_m / (2 L)`` with like ends (both open, or both closed) and
quarter-wave ``f_n = (2n - 1) a_m / (4 L)`` with one end open and one closed.

*Plug on an air spring.* A plug of length ``lambda`` and compactness ``c`` (mass
per unit area ``rho_s c lambda``) resting on a closed column of air of length
``L_air`` compressed at pressure ``P`` (stiffness per unit area
``n P / L_air``) oscillates at ``f = (1 / 2 pi) sqrt(n P / (rho_s c lambda L_air))``
(a mass-spring / Helmholtz-type estimate; Rayleigh, *The Theory of Sound*, vol.
2, sec. 303).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from ..errors import ParameterError

R_AIR_J_KG_K = 287.05


@dataclass(frozen=True)
class ResonanceInputs:
    """Inputs of the resonance estimates (SI units in the names)."""

    compactness: float = 0.55
    grain_density_kg_m3: float = 2500.0
    grain_sound_speed_m_s: float = 5000.0
    pressure_pa: float = 101_325.0
    temperature_k: float = 293.15
    gamma: float = 1.4
    isothermal: bool = False
    column_length_m: float = 1.0
    plug_length_m: float = 0.03
    air_column_m: float = 1.0
    n_modes: int = 3

    def __post_init__(self) -> None:
        if not 0 <= self.compactness < 1:
            raise ParameterError("compactness must be in [0, 1)")
        for name in ("grain_density_kg_m3", "grain_sound_speed_m_s", "pressure_pa", "temperature_k",
                     "column_length_m", "plug_length_m", "air_column_m"):
            if not getattr(self, name) > 0:
                raise ParameterError(f"{name} must be positive")
        if self.gamma < 1 or self.n_modes < 1:
            raise ParameterError("gamma must be >= 1 and n_modes >= 1")


def mixture_sound_speed(inp: ResonanceInputs) -> dict[str, float]:
    """Wood's mixture density and sound speed, and the air's own sound speed."""
    n = 1.0 if inp.isothermal else inp.gamma
    rho_a = inp.pressure_pa / (R_AIR_J_KG_K * inp.temperature_k)
    a_a = math.sqrt(n * inp.pressure_pa / rho_a)
    c = inp.compactness
    rho_m = c * inp.grain_density_kg_m3 + (1 - c) * rho_a
    compliance = c / (inp.grain_density_kg_m3 * inp.grain_sound_speed_m_s**2) + (1 - c) / (rho_a * a_a**2)
    a_m = math.sqrt(1.0 / (rho_m * compliance))
    return {"air_density_kg_m3": rho_a, "air_sound_speed_m_s": a_a,
            "mixture_density_kg_m3": rho_m, "mixture_sound_speed_m_s": a_m}


def resonance(inp: ResonanceInputs) -> dict[str, object]:
    """All three estimates, with the inputs."""
    mix = mixture_sound_speed(inp)
    a_m, L = mix["mixture_sound_speed_m_s"], inp.column_length_m
    n = 1.0 if inp.isothermal else inp.gamma
    half = [k * a_m / (2 * L) for k in range(1, inp.n_modes + 1)]
    quarter = [(2 * k - 1) * a_m / (4 * L) for k in range(1, inp.n_modes + 1)]
    m = inp.grain_density_kg_m3 * inp.compactness * inp.plug_length_m
    k_spring = n * inp.pressure_pa / inp.air_column_m
    # without grains (c = 0) the column's modes are the air's own, and there is no plug on the spring
    f_spring = math.sqrt(k_spring / m) / (2 * math.pi) if m > 0 else None
    return {
        "inputs": asdict(inp),
        "process": "isothermal" if inp.isothermal else "adiabatic",
        **mix,
        "half_wave_hz": half,
        "quarter_wave_hz": quarter,
        "plug_on_air_spring_hz": f_spring,
    }
