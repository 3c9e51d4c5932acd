"""The paper's one-dimensional model and its linear stability analysis.

See docs/stability.md for the equations, what the printed model gives with the
paper's parameters, and the ``frozen-friction`` variant.

The names load on first use (``grainplug.stability.params``, the model's parameters, without
numpy and scipy: the command line takes its defaults from there).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_names

_WHERE = {
    "Mode": "analysis", "StabilityResult": "analysis", "analyze_stability": "analysis", "max_growth": "analysis",
    "sweep": "analysis",
    "dispersion_coefficients": "model", "normal_mode_matrix": "model", "roots": "model", "system_matrices": "model",
    "BASE_VELOCITIES": "params", "FRICTION_LAWS": "params", "P_ATM_PA": "params", "VARIANTS": "params",
    "ModelParams": "params",
}

__all__ = [
    "BASE_VELOCITIES",
    "FRICTION_LAWS",
    "P_ATM_PA",
    "VARIANTS",
    "Mode",
    "ModelParams",
    "StabilityResult",
    "analyze_stability",
    "dispersion_coefficients",
    "max_growth",
    "normal_mode_matrix",
    "roots",
    "sweep",
    "system_matrices",
]


__getattr__, __dir__ = lazy_names(__name__, _WHERE, lambda: globals())


if TYPE_CHECKING:
    from .analysis import Mode, StabilityResult, analyze_stability, max_growth, sweep
    from .model import dispersion_coefficients, normal_mode_matrix, roots, system_matrices
    from .params import BASE_VELOCITIES, FRICTION_LAWS, P_ATM_PA, VARIANTS, ModelParams
