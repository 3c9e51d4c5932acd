"""The grains' mass flow rate from the movie: compactness, grain velocity and the pattern's celerity.

Notes
-----
Across a plug edge travelling at the celerity :math:`U`, no grain is created or lost: the flux
of grains through the edge, in the edge's frame, is the same on both sides,

.. math:: c_p (v_p - U) = c_b (v_b - U) = j,

with :math:`c_p, v_p` the plugs' compactness and grain velocity and :math:`c_b, v_b` the
bubbles'. At a fixed section the flux is :math:`c v = j + c U` at every instant, so its mean
over the record is :math:`j + U \\bar c`, :math:`\\bar c` the section's mean compactness (for a
pattern travelling steadily, the mean over the view and the record). Hence

.. math:: Q = \\rho_s \\frac{\\pi D^2}{4} \\left[ c_p v_p + U (\\bar c - c_p) \\right],

:math:`\\rho_s` the grains' density and :math:`D` the bore. Written so, it needs neither the bubbles'
compactness (a few per cent, hard to read) nor their grains' speed: the first term is the grains
creeping through the plugs; the second, with :math:`U < 0` (climbing) and :math:`\\bar c < c_p`, the
grains the climbing pattern hands from one plug to the next through the bubble between them. Both
are positive in the paper's propagative regime.

In an oscillating regime the pattern does not travel steadily: the formula holds for its drift
and its mean motion only (the grains move with the plugs; with :math:`v_p = U` it is the column's
mean content carried at the drift, :math:`\\bar c U`). The result says so.

The 95 % interval propagates the intervals of :math:`c_p`, :math:`v_p`, :math:`U` and
:math:`\\bar c` to first order, taken as independent (the compactnesses share the light model's
error, which makes the interval a little wide rather than narrow). The bore and the density are
taken as given, exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: the formula, as said in the outputs
FORMULA = "Q = rho_s * pi D^2 / 4 * [c_p v_p + U (c_mean - c_p)]"

#: time blocks the record's mean compactness is cut into for its interval
MEAN_BLOCKS = 8


@dataclass(frozen=True)
class MassFlow:
    """The grains' mass flow rate through a fixed section, or why it is not given.

    Attributes
    ----------
    rate_g_s : float or None
        The mass flow rate, g/s (positive downstream).
    ci95_g_s : tuple of float or None
        Its 95 % interval.
    creep_g_s, pattern_g_s : float or None
        The formula's two terms: the grains creeping through the plugs (:math:`c_p v_p`) and those
        handed on by the travelling pattern (:math:`U (\\bar c - c_p)`), g/s.
    mean_compactness : float or None
        The record's mean compactness over the view, :math:`\\bar c`.
    mean_compactness_ci95 : tuple of float or None
        Its 95 % interval.
    note : str
        Why it is not given, or what it rests on (empty when nothing is to be said).
    """

    rate_g_s: float | None
    ci95_g_s: tuple[float, float] | None
    creep_g_s: float | None = None
    pattern_g_s: float | None = None
    mean_compactness: float | None = None
    mean_compactness_ci95: tuple[float, float] | None = None
    note: str = ""


def mean_compactness(field: np.ndarray, *, half_width_floor: float = 0.0,
                     blocks: int = MEAN_BLOCKS) -> tuple[float | None, tuple[float, float] | None]:
    """The mean of the compactness field ``c(t, z)`` over the record and the view, and its 95 % interval.

    The interval is Student's over the means of ``blocks`` consecutive stretches of the record (the
    pattern's own variation from stretch to stretch), with ``half_width_floor`` (the light model's error)
    added in quadrature. None with no finite value.
    """
    from .._filters import t_quantile_975

    per_frame = np.array([np.nan if not np.isfinite(row).any() else float(np.nanmean(row)) for row in field])
    ok = np.isfinite(per_frame)
    if not ok.any():
        return None, None
    values = per_frame[ok]
    m = float(values.mean())
    k = int(min(blocks, values.size))
    if k < 2:
        return m, (m - half_width_floor, m + half_width_floor) if half_width_floor > 0 else None
    means = np.array([b.mean() for b in np.array_split(values, k)])
    half = float(t_quantile_975(k - 1) * means.std(ddof=1) / math.sqrt(k))
    half = math.hypot(half, half_width_floor)
    return m, (m - half, m + half)


def mass_flow_rate(*, c_plug: float | None, c_plug_ci95: tuple[float, float] | None,
                   v_plug_m_s: float | None, v_plug_ci95_m_s: tuple[float, float] | None,
                   celerity_m_s: float | None, celerity_ci95_m_s: tuple[float, float] | None,
                   c_mean: float | None, c_mean_ci95: tuple[float, float] | None,
                   bore_mm: float, grain_density_kg_m3: float, oscillating: bool = False,
                   missing: str = "") -> MassFlow:
    """The grains' mass flow rate from the plugs' compactness and grain velocity, the celerity and the mean
    compactness (module notes); ``missing``: why an input is absent, said in the note when the rate is not
    given."""
    named = {"the plugs' compactness": c_plug, "the grains' velocity in the plugs": v_plug_m_s,
             "the celerity": celerity_m_s, "the mean compactness": c_mean}
    absent = [name for name, v in named.items() if v is None or not np.isfinite(v)]
    if absent:
        why = f"not given: {', '.join(absent)} not measured" + (f" ({missing})" if missing else "")
        return MassFlow(None, None, mean_compactness=c_mean, mean_compactness_ci95=c_mean_ci95, note=why)
    assert c_plug is not None and v_plug_m_s is not None and celerity_m_s is not None and c_mean is not None
    # kg/m^3 * m^2 * m/s = kg/s; * 1000 -> g/s
    k = grain_density_kg_m3 * math.pi * (bore_mm * 1e-3) ** 2 / 4.0 * 1000.0
    creep = k * c_plug * v_plug_m_s
    pattern = k * celerity_m_s * (c_mean - c_plug)
    rate = creep + pattern

    def half(ci: tuple[float, float] | None) -> float:
        return 0.0 if ci is None else 0.5 * abs(ci[1] - ci[0])

    parts = (k * (v_plug_m_s - celerity_m_s) * half(c_plug_ci95), k * c_plug * half(v_plug_ci95_m_s),
             k * (c_mean - c_plug) * half(celerity_ci95_m_s), k * celerity_m_s * half(c_mean_ci95))
    h = math.sqrt(sum(p * p for p in parts))
    unknown = [name for name, ci in (("the plugs' compactness", c_plug_ci95),
                                     ("the grains' velocity", v_plug_ci95_m_s), ("the celerity", celerity_ci95_m_s),
                                     ("the mean compactness", c_mean_ci95)) if ci is None]
    notes = []
    if unknown:
        notes.append(f"no interval: {', '.join(unknown)} without one")
    if oscillating:
        notes.append("the plugs oscillate: the formula holds for the pattern's drift and the grains' mean motion")
    return MassFlow(rate, None if unknown else (rate - h, rate + h), creep, pattern, c_mean, c_mean_ci95,
                    "; ".join(notes))
