"""The paper's 1D grain-air model integrated in time (finite volumes).

See docs/model.md for the equations as integrated, the numerical method and its
validation against the linear analysis of :mod:`grainplug.stability`.

The modules, each importing only those before it: :mod:`.state` (the data:
:class:`SimulationParams`, :class:`SimulationResult`), :mod:`.equations` and
:mod:`.scheme` (with :mod:`._kernel`, its compiled step), the measures of the fields
(:mod:`.waves`, :mod:`.measure`, :mod:`.validation`), the time loop (:mod:`.run`,
:func:`simulate`), the study that runs and measures (:mod:`.study`,
:class:`SimulationStudy`); :mod:`.store` writes a run.
"""

from .equations import Closure
from .run import simulate
from .state import RANDOM_CLOSE_PACKING, SimulationParams, SimulationResult
from .study import SimulationStudy, run_study, simulate_and_measure
from .waves import segment_counts

__all__ = ["RANDOM_CLOSE_PACKING", "Closure", "SimulationParams", "SimulationResult", "SimulationStudy", "run_study",
           "segment_counts", "simulate", "simulate_and_measure"]
