"""Model against experiment: what each set-up of the 1D model predicts, next to what was measured.

Notes
-----
For each set-up in :data:`SETUPS` (the paper as printed and the variants of
docs/stability.md) the panel gives

- linear theory (:func:`grainplug.stability.analyze_stability`): the most unstable
  wavelength ``lambda/D``, the cut-off wavelength and the phase speed of the growing
  wave, in m/s, positive downstream;
- nonlinear (:func:`grainplug.simulation.simulate`), for the set-ups with a finite band
  of unstable wavelengths shorter than the pipe: periodic boxes of two lengths run
  from small noise until the waves have formed, and what they end as: the number of
  waves, the dense-segment length, the front speed, and what the movie analysis sees
  in the compactness diagram. Two boxes tell a length the flow selects (the same in
  both) from one the box sets (growing with it).

It is compared with the measured celerity (range over the runs), plug length and,
where bubbles were measured, wavelength (plug + bubble). :func:`verdict` writes the
sentences from the numbers; nothing in them is fixed text about agreement.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..stability import P_ATM_PA, ModelParams, analyze_stability

#: (label, ModelParams fields): the set-ups compared
SETUPS: tuple[tuple[str, dict[str, object]], ...] = (
    ("as printed", {}),
    ("frozen friction", {"variant": "frozen-friction"}),
    ("frozen friction, atmospheric air", {"variant": "frozen-friction", "base_pressure_pa": P_ATM_PA}),
    ("frozen friction + jamming pressure", {"variant": "frozen-friction", "jamming": True}),
    ("Coulomb friction following the weight", {"friction_law": "coulomb-weight"}),
)
#: periodic boxes of the nonlinear runs, in D
BOXES_D = (125.0, 251.0)
#: cells per D of the nonlinear runs, their length in t_c and initial noise
CELLS_PER_D, DURATION_TC, NOISE = 2.04, 400.0, 1e-6
#: the pipe of the experiment, mm
PIPE_LENGTH_MM = 1000.0


@dataclass(frozen=True)
class Nonlinear:
    """The end state of one periodic run (lengths in D, speeds in m/s)."""

    box_D: float
    n_waves: int
    dense_length_D: float
    front_speed_m_s: float
    c_min: float
    c_max: float
    seen_as_movie: str
    #: the movie measures of the run's compactness diagram (:func:`grainplug.simulation.measure.measure`): None
    #: (and regime "none") when the analysis finds no plugs
    regime: str = "none"
    celerity_m_s: float | None = None
    plug_length_mm: float | None = None
    bubble_length_mm: float | None = None

    def as_dict(self) -> dict[str, object]:
        return dict(self.__dict__)


@dataclass(frozen=True)
class Prediction:
    """What one set-up predicts."""

    label: str
    params: ModelParams
    lambda_D: float | None
    cutoff_lambda_D: list[float]
    phase_speed_m_s: float | None
    growth_per_s: float | None
    nonlinear: list[Nonlinear] = field(default_factory=list)
    note: str = ""

    def as_dict(self) -> dict[str, object]:
        return {"label": self.label, "setup": {k: v for k, v in self.params.as_dict().items()
                                               if k in ("variant", "friction_law_used", "base_pressure_abs_pa",
                                                        "jamming", "v0_star")},
                "most_unstable_lambda_D": self.lambda_D, "cutoff_lambda_D": self.cutoff_lambda_D,
                "phase_speed_m_s": self.phase_speed_m_s, "growth_per_s": self.growth_per_s,
                "nonlinear": [n.as_dict() for n in self.nonlinear], "note": self.note}


@dataclass(frozen=True)
class Measured:
    """What the experiment measured (m/s, mm)."""

    source: str
    n_runs: int
    celerity_min_m_s: float
    celerity_max_m_s: float
    plug_length_mm: float
    wavelength_mm: float | None

    def as_dict(self) -> dict[str, object]:
        return dict(self.__dict__)


def measured_from(celerity_m_s: np.ndarray, plug_length_mm: np.ndarray, bubble_length_mm: np.ndarray | None,
                  *, source: str) -> Measured:
    """The measured ranges and means, ignoring missing values."""
    cel = np.asarray(celerity_m_s, float)
    cel = cel[np.isfinite(cel)]
    plug = np.asarray(plug_length_mm, float)
    plug = plug[np.isfinite(plug)]
    wl = None
    if bubble_length_mm is not None:
        b = np.asarray(bubble_length_mm, float)
        both = np.isfinite(b) & np.isfinite(np.asarray(plug_length_mm, float))
        if both.any():
            wl = float(np.mean(np.asarray(plug_length_mm, float)[both] + b[both]))
    return Measured(source, int(len(cel)), float(cel.min()) if len(cel) else math.nan,
                    float(cel.max()) if len(cel) else math.nan, float(plug.mean()) if len(plug) else math.nan, wl)


def _nonlinear(p: ModelParams, box_D: float) -> Nonlinear:
    from ..simulation import SimulationParams, simulate
    from ..simulation.measure import measure
    from ..simulation.waves import wave_state

    n = int(round(box_D * CELLS_PER_D / 2)) * 2
    res = simulate(p, SimulationParams(length_D=box_D, n_cells=n, duration_tc=DURATION_TC, output_interval_tc=0.5,
                                       noise=NOISE), rng=np.random.default_rng(0))
    w = wave_state(res)
    seen = measure(res)
    movie = (f"{seen.regime}, celerity {seen.celerity_m_s:+.3f} m/s" if seen.celerity_m_s is not None
             else "no plugs (a single phase)")
    def number(x: float | None) -> float | None:
        return None if x is None or not math.isfinite(x) else float(x)

    return Nonlinear(box_D, w.n_waves, w.dense_length_D, w.front_speed * p.v_c_m_s, w.c_min, w.c_max, movie,
                     regime=seen.regime, celerity_m_s=number(seen.celerity_m_s),
                     plug_length_mm=number(seen.plug_length_mm), bubble_length_mm=number(seen.bubble_length_mm))


def predict(*, diameter_mm: float = 3.0, simulate: bool = True) -> list[Prediction]:
    """Linear (and, with ``simulate``, nonlinear) predictions of every set-up in :data:`SETUPS`."""
    out = []
    for label, kw in SETUPS:
        p = ModelParams(diameter_mm=diameter_mm, **kw)
        lin = analyze_stability(p, k_min=1e-3, k_max=3.0, n_k=1500)
        m = lin.most_unstable
        cut = [float(x) for x in lin.cutoff_wavelength_over_diameter]
        lam = None if m is None else m.wavelength_over_diameter
        note, nonlinear = "", []
        pipe_D = PIPE_LENGTH_MM / diameter_mm
        speed = None if m is None else m.phase_speed * p.v_c_m_s
        if m is None:
            note = "stable: no wavelength grows"
        elif not cut or max(cut) <= 2 * np.pi / 3.0 * 1.001 or m.at_range_edge == "k_max":
            note = ("no short-wave cut-off: growth increases to the shortest waves, so there is no most unstable "
                    "wavelength and a simulation would pick the grid scale")
            lam, speed = None, None
        elif min(cut) > pipe_D:
            note = (f"the unstable waves (longer than {min(cut):.0f} D) do not fit in the {PIPE_LENGTH_MM:.0f} mm "
                    f"pipe ({pipe_D:.0f} D)")
            lam = None
        elif simulate:
            nonlinear = [_nonlinear(p, box) for box in BOXES_D]
        out.append(Prediction(label, p, lam, cut, speed, None if m is None else m.growth_rate / p.t_c_s, nonlinear,
                              note))
    return out


def verdict(measured: Measured, preds: list[Prediction], *, diameter_mm: float = 3.0) -> list[str]:
    """One sentence on the celerity, one on the lengths, from the numbers."""
    out = []
    growing = [q for q in preds if q.phase_speed_m_s is not None and q.lambda_D is not None]
    lo, hi = measured.celerity_min_m_s, measured.celerity_max_m_s
    if growing and math.isfinite(lo):
        speeds = [q.phase_speed_m_s for q in growing] + [n.front_speed_m_s for q in growing for n in q.nonlinear]
        same_sign = [s for s in speeds if (s < 0) == (0.5 * (lo + hi) < 0)]
        direction = "climb" if hi < 0 else ("move down" if lo > 0 else "move both ways")
        if not same_sign:
            out.append(f"Celerity: the measured plugs {direction} ({lo:+.3f} to {hi:+.3f} m/s); every growing "
                       f"wave of the model travels the other way ({min(speeds):+.2f} to {max(speeds):+.2f} m/s): "
                       "the model does not predict the observed waves' direction.")
        else:
            out.append(f"Celerity: the measured plugs {direction} ({lo:+.3f} to {hi:+.3f} m/s); the model's waves "
                       f"travel at {min(speeds):+.2f} to {max(speeds):+.2f} m/s.")
    elif math.isfinite(lo):
        out.append(f"Celerity: measured {lo:+.3f} to {hi:+.3f} m/s; no set-up has a growing wave to compare.")
    plug_D = measured.plug_length_mm / diameter_mm
    wl = ("" if measured.wavelength_mm is None
          else f", wavelength (plug + bubble) {measured.wavelength_mm / diameter_mm:.1f} D")
    lin = [(q.label, q.lambda_D) for q in growing if q.lambda_D is not None]
    text = f"Lengths: measured plugs are {plug_D:.1f} D long{wl}"
    if lin:
        text += "; linear theory's most unstable wavelength is " + ", ".join(f"{v:.0f} D ({k})" for k, v in lin)
    out.append(text + ".")
    for q in (q for q in growing if len(q.nonlinear) == 2):
        a, b = q.nonlinear
        ratio = b.dense_length_D / a.dense_length_D if a.dense_length_D > 0 else math.nan
        if not a.n_waves:
            continue
        if abs(ratio - 1) < 0.1:
            line = f"Simulated, {q.label}: dense segments of {a.dense_length_D:.0f} D in both boxes, a selected length"
        else:
            line = (f"Simulated, {q.label}: the dense segment grows with the box ({a.dense_length_D:.0f} D in a "
                    f"{a.box_D:.0f} D box, {b.dense_length_D:.0f} D in {b.box_D:.0f} D): the model selects no plug "
                    "length")
        if max(a.c_max, b.c_max) > 0.64:
            line += f"; it packs grains to c = {max(a.c_max, b.c_max):.2f}, above random close packing"
        if all(n.seen_as_movie.startswith("no plugs") for n in q.nonlinear):
            line += (f"; the compactness stays within {min(a.c_min, b.c_min):.2f}..{max(a.c_max, b.c_max):.2f}, so no "
                     "air bubble forms and the movie analysis sees no plugs")
        out.append(line + ".")
    for q in preds:
        if q.note and q.phase_speed_m_s is None and q.growth_per_s is not None:
            out.append(f"{q.label[0].upper()}{q.label[1:]}: {q.note}.")
    return out


def panel_rows(preds: list[Prediction]) -> tuple[list[str], list[list[str]]]:
    """Headers and rows of the panel's table (one row per set-up and box)."""
    def f(x: float | None, fmt: str) -> str:
        return "—" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, fmt)

    headers = ["set-up", "most unstable λ/D", "cut-off λ/D", "phase speed (m/s)", "box (D)", "waves",
               "dense segment (D)", "front speed (m/s)", "c range", "seen by the movie analysis",
               "movie: plug (mm)", "movie: bubble (mm)", "movie: celerity (m/s)", "note"]
    rows = []
    for q in preds:
        lin = [q.label, f(q.lambda_D, ".1f"), ", ".join(format(c, ".1f") for c in q.cutoff_lambda_D) or "—",
               f(q.phase_speed_m_s, "+.3f")]
        if not q.nonlinear:
            rows.append([*lin, "—", "—", "—", "—", "—", "—", "—", "—", "—", q.note or "not simulated"])
        for n in q.nonlinear:
            rows.append([*lin, f(n.box_D, ".0f"), str(n.n_waves), f(n.dense_length_D, ".1f"),
                         f(n.front_speed_m_s, "+.3f"), f"{n.c_min:.2f}–{n.c_max:.2f}", n.seen_as_movie,
                         f(n.plug_length_mm, ".1f"), f(n.bubble_length_mm, ".1f"), f(n.celerity_m_s, "+.3f"), q.note])
    return headers, rows


@dataclass(frozen=True)
class ModelPanel:
    """Measured, predicted, and the sentences that compare them."""

    measured: Measured
    predictions: list[Prediction]
    verdict: list[str]
    diameter_mm: float

    @property
    def simulated(self) -> bool:
        """Whether nonlinear simulations were run for the panel."""
        return any(q.nonlinear for q in self.predictions)

    def as_dict(self) -> dict[str, object]:
        return {"measured": self.measured.as_dict(), "predictions": [q.as_dict() for q in self.predictions],
                "verdict": self.verdict, "diameter_mm": self.diameter_mm,
                "nonlinear_runs": {"boxes_D": list(BOXES_D), "cells_per_D": CELLS_PER_D, "duration_tc": DURATION_TC,
                                   "noise": NOISE, "seed": 0} if self.simulated else None}


def model_panel(measured: Measured, *, diameter_mm: float = 3.0, simulate: bool = True) -> ModelPanel:
    """Predict with every set-up and compare with ``measured``."""
    preds = predict(diameter_mm=diameter_mm, simulate=simulate)
    return ModelPanel(measured, preds, verdict(measured, preds, diameter_mm=diameter_mm), diameter_mm)


def panel_html(panel: ModelPanel, figure: str | None) -> str:
    """The panel as an HTML section (sentences, table, figure)."""
    import html

    from ..reports import table

    headers, rows = panel_rows(panel.predictions)
    m = panel.measured
    wl = "not measured" if m.wavelength_mm is None else f"{m.wavelength_mm:.1f} mm"
    out = ("<h2>Model against experiment</h2>"
           f"<p>Measured ({html.escape(m.source)}, {m.n_runs} runs): celerity {m.celerity_min_m_s:+.3f} to "
           f"{m.celerity_max_m_s:+.3f} m/s, mean plug length {m.plug_length_mm:.1f} mm "
           f"({m.plug_length_mm / panel.diameter_mm:.1f} D), plug + bubble {wl}.</p>"
           "<ul>" + "".join(f"<li>{html.escape(s)}</li>" for s in panel.verdict) + "</ul>"
           + table(headers, rows)
           + "<p>Linear theory: grainplug.stability with the paper's inputs. "
           + (f"Simulated: grainplug.simulation in periodic boxes of {' and '.join(f'{b:.0f}' for b in BOXES_D)} D "
              f"from noise of {NOISE:g}, {DURATION_TC:.0f} t_c; the dense segment is where c is above the middle of "
              "its range. " if panel.simulated else "No simulation was run. ")
           + "See docs/model.md.</p>")
    if figure:
        out += (f'<figure><img src="{html.escape(figure)}" alt="model against experiment" style="max-width:100%">'
                "<figcaption>Colour: set-up; marker: linear theory (filled) or simulation (open). Celerity "
                "positive downstream.</figcaption></figure>")
    return out
