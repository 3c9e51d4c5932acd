"""The paper's 1D grain-air model integrated in time (finite volumes).

See docs/model.md for the equations as integrated, the numerical method and its
validation against the linear analysis of :mod:`grainplug.stability`.

The modules, each importing only those before it: :mod:`.state` (the data:
:class:`SimulationParams`, :class:`SimulationResult`), :mod:`.equations` and
:mod:`.scheme` (with :mod:`._kernel`, its compiled step), the measures of the fields
(:mod:`.waves`, :mod:`.measure`, :mod:`.validation`), the time loop (:mod:`.run`,
:func:`simulate`), the study that runs and measures (:mod:`.study`,
:class:`SimulationStudy`); :mod:`.store` writes a run.

The names load on first use: ``grainplug.simulation.state`` (the parameters, which the command line takes its
defaults from) without the integrator and the linear analysis.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_names

_WHERE = {"Closure": "equations", "simulate": "run", "RANDOM_CLOSE_PACKING": "state", "SimulationParams": "state",
          "SimulationResult": "state", "SimulationStudy": "study", "run_study": "study",
          "simulate_and_measure": "study", "segment_counts": "waves"}

__all__ = [
    "RANDOM_CLOSE_PACKING",
    "Closure",
    "SimulationParams",
    "SimulationResult",
    "SimulationStudy",
    "run_study",
    "segment_counts",
    "simulate",
    "simulate_and_measure",
]


__getattr__, __dir__ = lazy_names(__name__, _WHERE, lambda: globals())


if TYPE_CHECKING:
    from .equations import Closure
    from .run import simulate
    from .state import RANDOM_CLOSE_PACKING, SimulationParams, SimulationResult
    from .study import SimulationStudy, run_study, simulate_and_measure
    from .waves import segment_counts
