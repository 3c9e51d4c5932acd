"""The paper's one-dimensional model and its linear stability analysis.

See docs/stability.md for the equations, what the printed model gives with the
paper's parameters, and the ``frozen-friction`` variant.
"""

from .analysis import Mode, StabilityResult, analyze_stability, max_growth, sweep
from .model import dispersion_coefficients, normal_mode_matrix, roots, system_matrices
from .params import BASE_VELOCITIES, FRICTION_LAWS, P_ATM_PA, VARIANTS, ModelParams

__all__ = ["BASE_VELOCITIES", "FRICTION_LAWS", "P_ATM_PA", "VARIANTS", "Mode", "ModelParams", "StabilityResult",
           "analyze_stability", "dispersion_coefficients", "max_growth", "normal_mode_matrix", "roots", "sweep",
           "system_matrices"]
