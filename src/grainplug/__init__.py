"""grainplug: density waves (granular plugs) in grain flows through narrow pipes.

>>> import grainplug as gp
>>> res = gp.analyze(gp.datasets.sample_movie())
>>> res.summary["regime"]
'propagative'

The public API, imported on first use so that ``import grainplug`` stays fast:

- :func:`analyze` (a path, an open :class:`Movie` or frames in memory) returning an
  :class:`AnalysisResult`, tuned by :class:`AnalysisParams`; :func:`load_result`
  reads a saved one back;
- :func:`open_movie` for every supported format, :class:`Movie` and :class:`MovieInfo`;
- :func:`synthesize` and :class:`SynthConfig`: synthetic movies with known truth;
- :func:`analyze_stability`, :func:`sweep`, :class:`ModelParams`: the paper's linear
  stability analysis (:mod:`grainplug.stability`);
- :func:`simulate` and :class:`SimulationParams`: the model's equations integrated in time
  (:mod:`grainplug.simulation`, docs/model.md);
- :func:`calibrate_image` / :func:`calibrate_file` (a checkerboard, dot grid, graph paper or
  ruler) giving a :class:`Calibration`, :func:`save_calibration` / :func:`load_calibration`; pass
  it as ``analyze(..., calibration=cal)``; :func:`read_background` (a light calibration, the
  tube with nothing moving in it) giving a :class:`Background` for ``analyze(..., background=bg)``;
- :class:`FigureOptions` (and :data:`PUBLICATION`, PNG, SVG and PDF) for
  ``result.save(dir, figure_options=...)``;
- :class:`Corrections`, :func:`apply_corrections`, :func:`remeasure`: a reviewer's edits of the
  detected tracks (exclude, merge, split, time window, spans without plugs), measures recomputed;
- :func:`run_campaign`: many movies from a manifest, optionally on Dask;
- :func:`compare`: an analysis and a simulation in the same figures and units (:class:`Comparison`);
- :mod:`datasets`: the sample movie and the paper's tables.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from ._version import __version__

#: public name -> module that defines it
_EXPORTS = {
    "analyze": "grainplug.pipeline",
    "AnalysisParams": "grainplug.params",
    "FLOW_DIRECTIONS": "grainplug.params",
    "AnalysisResult": "grainplug.result",
    "load_result": "grainplug.result",
    "open_movie": "grainplug.readers",
    "Movie": "grainplug.readers",
    "MovieInfo": "grainplug.readers",
    "synthesize": "grainplug.synthetic",
    "SynthConfig": "grainplug.synthetic",
    "analyze_stability": "grainplug.stability",
    "sweep": "grainplug.stability",
    "ModelParams": "grainplug.stability",
    "simulate": "grainplug.simulation",
    "Corrections": "grainplug.corrections",
    "apply_corrections": "grainplug.corrections",
    "remeasure": "grainplug.workflows",
    "compare": "grainplug.comparison",
    "Comparison": "grainplug.comparison",
    "FigureOptions": "grainplug.plotting.options",
    "PUBLICATION": "grainplug.plotting.options",
    "SimulationParams": "grainplug.simulation",
    "run_campaign": "grainplug.campaigns.batch",
    "calibrate_image": "grainplug.calibration.pattern",
    "Calibration": "grainplug.calibration.pattern",
    "calibrate_file": "grainplug.calibration_files",
    "load_calibration": "grainplug.calibration_files",
    "save_calibration": "grainplug.calibration_files",
    "read_background": "grainplug.calibration_files",
    "Background": "grainplug.calibration.background",
    "GrainplugError": "grainplug.errors",
    "MovieError": "grainplug.errors",
    "ParameterError": "grainplug.errors",
}
_SUBMODULES = ("datasets", "stability", "simulation", "synthetic", "readers", "plotting", "calibration",
               "campaigns", "errors", "pipeline", "result", "outputs", "corrections", "reports", "measures")

__all__ = [
    "FLOW_DIRECTIONS", "PUBLICATION", "AnalysisParams", "AnalysisResult", "Background", "Calibration",
    "Comparison", "Corrections", "FigureOptions", "GrainplugError", "ModelParams", "Movie", "MovieError", "MovieInfo",
    "ParameterError", "SimulationParams", "SynthConfig", "__version__", "analyze", "analyze_stability",
    "apply_corrections", "calibrate_file", "calibrate_image", "compare", "datasets", "load_calibration", "load_result",
    "open_movie", "plotting", "read_background", "readers", "remeasure", "run_campaign", "save_calibration",
    "simulate", "simulation", "stability", "sweep", "synthesize", "synthetic"
]


def __getattr__(name: str) -> object:
    if name in _EXPORTS:
        value = getattr(importlib.import_module(_EXPORTS[name]), name)
    elif name in _SUBMODULES:
        value = importlib.import_module(f"grainplug.{name}")
    else:
        raise AttributeError(f"module 'grainplug' has no attribute {name!r}")
    globals()[name] = value  # found directly from now on
    return value


def __dir__() -> list[str]:
    """The public names and subpackages (not this module's own imports)."""
    return sorted(set(__all__) | set(_SUBMODULES))


if TYPE_CHECKING:  # for type checkers and IDEs: the names as if imported eagerly
    from . import datasets, plotting, readers, stability, synthetic
    from .calibration.background import Background
    from .calibration.pattern import Calibration, calibrate_image
    from .calibration_files import calibrate_file, load_calibration, read_background, save_calibration
    from .campaigns.batch import run_campaign
    from .errors import GrainplugError, MovieError, ParameterError
    from .params import FLOW_DIRECTIONS, AnalysisParams
    from .pipeline import analyze
    from .readers import Movie, MovieInfo, open_movie
    from .result import AnalysisResult, load_result
    from .stability import ModelParams, analyze_stability, sweep
    from .synthetic import SynthConfig, synthesize
