"""The model-against-experiment figure: celerity and lengths, measured and predicted."""

from __future__ import annotations

import textwrap
from typing import TYPE_CHECKING

from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from ._figure import new_figure, pt
from .palette import foreground

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ..campaigns.model_panel import Measured, Prediction

#: one colour-blind-safe colour per set-up (Okabe-Ito); measured data and marker keys in black
COLOURS = ("#0072b2", "#d55e00", "#009e73", "#cc79a7", "#e69f00", "#56b4e9")
MARKERS = {"linear": "o", "cutoff": "v", "box0": "s", "box1": "D"}


def plot_model_panel(measured: Measured, preds: list[Prediction], *, diameter_mm: float = 3.0) -> Figure:
    """(a) celerity: the measured range against the growing waves' speeds; (b) lengths in D.

    Colour = set-up (the tick labels); marker = what is predicted (legend, in black).
    Only set-ups with a growing wave that fits in the pipe are drawn.
    """
    fig, axes = new_figure(1, 2, figsize=(10, 5), constrained_layout=True)
    ax, bx = axes
    fg = foreground()  # black, or the style sheet's text colour (white on a dark background)
    ax.axhspan(measured.celerity_min_m_s, measured.celerity_max_m_s, color=fg, alpha=0.25)
    bx.axhline(measured.plug_length_mm / diameter_mm, color=fg, lw=2)
    if measured.wavelength_mm is not None:
        bx.axhline(measured.wavelength_mm / diameter_mm, color=fg, lw=1.2, ls="--")
    boxes = sorted({n.box_D for q in preds for n in q.nonlinear})
    for i, q in enumerate(preds):
        col = COLOURS[i % len(COLOURS)]
        if q.lambda_D is None:
            continue
        ax.plot([i], [q.phase_speed_m_s], MARKERS["linear"], color=col, ms=7)
        bx.plot([i], [q.lambda_D], MARKERS["linear"], color=col, ms=7)
        for c in q.cutoff_lambda_D:
            bx.plot([i], [c], MARKERS["cutoff"], color=col, ms=7)
        for n in q.nonlinear:
            mk = MARKERS["box0"] if n.box_D == boxes[0] else MARKERS["box1"]
            ax.plot([i], [n.front_speed_m_s], mk, mfc="none", mew=1.5, color=col, ms=8)
            bx.plot([i], [n.dense_length_D], mk, mfc="none", mew=1.5, color=col, ms=8)
    key = [Line2D([], [], ls="", marker=MARKERS["linear"], color=fg, label="linear theory")]
    key += [Line2D([], [], ls="", marker=MARKERS[f"box{j}"], mfc="none", color=fg,
                   label=f"simulated, {b:.0f} D box") for j, b in enumerate(boxes[:2])]
    ax.legend(handles=[Patch(color=fg, alpha=0.25, label=f"measured ({measured.n_runs} runs)"), *key],
              fontsize=pt(7), loc="center left")
    bkey = [Line2D([], [], color=fg, lw=2, label="measured plug length")]
    if measured.wavelength_mm is not None:
        bkey.append(Line2D([], [], color=fg, lw=1.2, ls="--", label="measured plug + bubble"))
    bkey += [Line2D([], [], ls="", marker=MARKERS["linear"], color=fg, label="linear, most unstable λ"),
             Line2D([], [], ls="", marker=MARKERS["cutoff"], color=fg, label="linear, cut-off λ")]
    bkey += [Line2D([], [], ls="", marker=MARKERS[f"box{j}"], mfc="none", color=fg,
                    label=f"simulated dense segment, {b:.0f} D box") for j, b in enumerate(boxes[:2])]
    bx.legend(handles=bkey, fontsize=pt(7), loc="upper left")
    for a in axes:
        a.set_xticks(range(len(preds)))
        a.set_xticklabels([textwrap.fill(q.label, 14) for q in preds], fontsize=pt(7))
        for lab, i in zip(a.get_xticklabels(), range(len(preds)), strict=True):
            lab.set_color(COLOURS[i % len(COLOURS)])
        a.set_xlim(-0.6, len(preds) - 0.4)
    ax.set_yscale("symlog", linthresh=0.05)
    tops = [q.phase_speed_m_s for q in preds if q.lambda_D is not None] + [
        n.front_speed_m_s for q in preds for n in q.nonlinear]
    hi = max([measured.celerity_max_m_s, 0.1, *tops])
    lo = min([measured.celerity_min_m_s, -0.1, *tops])
    ax.set_ylim(lo * (3 if lo < 0 else 0.5), hi * 3)
    ax.axhline(0, color="0.5", lw=0.7)
    ax.set_ylabel("celerity v_p (m s⁻¹), positive downstream")
    ax.set_title("(a) wave speed", loc="left", fontsize=pt(10))
    bx.set_yscale("log")
    bx.set_ylabel("length λ/D")
    bx.set_title("(b) lengths", loc="left", fontsize=pt(10))
    fig.suptitle(f"model against experiment ({measured.source}); set-ups without a growing wave that fits in "
                 "the pipe are not drawn", fontsize=pt(9))
    return fig
