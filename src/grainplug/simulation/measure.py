"""A simulation measured like a movie: its compactness diagram through the analysis's own stages.

Notes
-----
The compactness ``c(z, t)`` becomes the grey levels a back-lit camera would give,
``I = 200 - 250 c`` (grains dark; the mapping is fixed, not stretched to the run's
range), sampled at ``px_per_D`` positions per pipe diameter with the run's real
scale (``D`` in mm, ``t_c`` in s). :func:`grainplug.measures.diagram.measure_diagram`, the
stages :func:`grainplug.analyze` runs after reading a movie, then finds the plugs,
links them over time and measures celerity, regime, frequency, plug and bubble
lengths. Positions are from the top of the box, increasing with the flow; celerity
is positive downstream.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..diagram import Diagram
from ..measures.diagram import CONTRAST_ADVICE, DiagramMeasures, measure_diagram
from .state import SimulationResult

#: grey level of an empty bore and its fall per unit compactness
LIGHT, PER_C = 200.0, 250.0


def diagram_of(res: SimulationResult, *, px_per_D: int = 16, t_from_tc: float = 0.0) -> Diagram:
    """The run's compactness as a spatiotemporal diagram of grey levels, from ``t_from_tc`` on."""
    p = res.model
    sel = res.time >= t_from_tc - 1e-9
    c = res.c[sel]
    L = res.params.length_D
    n = int(round(L * px_per_D))
    zc = (np.arange(n) + 0.5) / px_per_D  # sample positions, units of D
    if res.params.boundary == "periodic":
        zz = np.concatenate([res.z[-1:] - L, res.z, res.z[:1] + L])
        c = np.concatenate([c[:, -1:], c, c[:, :1]], axis=1)
    else:
        zz = res.z
    prof = np.stack([np.interp(zc, zz, row) for row in c])
    values = np.clip(LIGHT - PER_C * prof, 1.0, LIGHT).astype(np.float32)
    mm_per_px = p.diameter_mm / px_per_D
    return Diagram(values, (res.time[sel] - res.time[sel][0]) * p.t_c_s, zc * p.diameter_mm, mm_per_px)


@dataclass(frozen=True)
class SimulationMeasures:
    """The measures of a run's diagram, in the units of a movie's analysis."""

    t_from_tc: float
    measures: DiagramMeasures

    @property
    def celerity_m_s(self) -> float | None:
        m = self.measures.motion
        return None if m is None else m.celerity_m_s

    @property
    def regime(self) -> str:
        m = self.measures.motion
        return "none" if m is None else m.regime

    @property
    def frequency_hz(self) -> float | None:
        m = self.measures.motion
        return None if m is None else m.oscillation_frequency_hz

    @property
    def plug_length_mm(self) -> float | None:
        g = self.measures.lengths
        return None if g is None else g.plug_length_mm

    @property
    def bubble_length_mm(self) -> float | None:
        g = self.measures.lengths
        return None if g is None else g.bubble_length_mm

    def as_dict(self) -> dict[str, object]:
        return {"from_t_tc": self.t_from_tc, "regime": self.regime, "celerity_m_s": self.celerity_m_s,
                "frequency_hz": self.frequency_hz, "plug_length_mm": self.plug_length_mm,
                "bubble_length_mm": self.bubble_length_mm, "n_tracks": len(self.measures.links),
                "statement": self.measures.statement}


def measure(res: SimulationResult, *, t_from_tc: float | None = None, px_per_D: int = 16) -> SimulationMeasures:
    """Analyse the run's diagram as a movie's (default: its second half, after the growth)."""
    t0 = 0.5 * float(res.time[-1]) if t_from_tc is None else t_from_tc
    d = diagram_of(res, px_per_D=px_per_D, t_from_tc=t0)
    fps = 1.0 / float(d.time_s[1] - d.time_s[0])
    found = measure_diagram(d, fps=fps, background_level=LIGHT)
    # a simulation has no lighting or file to improve: what its compactness does is the answer
    statement = found.statement.replace(CONTRAST_ADVICE, "the simulated compactness does not part into dense and "
                                        "dilute stretches clearly enough: that is the model's answer, not the "
                                        "camera's")
    return SimulationMeasures(t0, dataclasses.replace(found, statement=statement))
