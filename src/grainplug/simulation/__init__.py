"""The paper's 1D grain-air model integrated in time (finite volumes).

See docs/model.md for the equations as integrated, the numerical method and its
validation against the linear analysis of :mod:`grainplug.stability`.
"""

from .equations import Closure
from .run import (
    RANDOM_CLOSE_PACKING,
    SimulationParams,
    SimulationResult,
    segment_counts,
    simulate,
    simulate_and_measure,
)

__all__ = ["RANDOM_CLOSE_PACKING", "Closure", "SimulationParams", "SimulationResult", "segment_counts", "simulate",
           "simulate_and_measure"]
