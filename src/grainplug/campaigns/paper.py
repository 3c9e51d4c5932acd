"""Reproduce the paper's numbers from its own tables, and say where they agree.

Each *claim* below is a statement of the paper (quoted, with its section); the
*reproduced* value is computed here from the shipped Tables 1 and 2 (or from
``grainplug.stability``); ``agrees`` is decided by the stated criterion, never
by hand. Nothing is tuned: where the paper and its tables disagree, the
reproduction says so.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from scipy import stats

from .. import datasets
from ..stability import ModelParams, analyze_stability
from ..stability.resonance import ResonanceInputs, resonance
from .fits import LinearFit, fit_line, summarize_lengths
from .model_panel import ModelPanel, measured_from, model_panel

if TYPE_CHECKING:
    import pandas as pd

GROUPS = ("propagative/rough", "propagative/smooth", "oscillating")
D_MM = 3.0


@dataclass(frozen=True)
class Check:
    """One statement of the paper against its reproduction."""

    claim: str
    where: str
    paper: object
    reproduced: object
    agrees: bool
    note: str = ""

    def as_dict(self) -> dict[str, object]:
        return {"claim": self.claim, "where": self.where, "paper": self.paper,
                "reproduced": self.reproduced, "agrees": self.agrees, "note": self.note}


@dataclass(frozen=True)
class PaperReproduction:
    fits: dict[str, LinearFit]
    lengths: dict[str, dict]
    checks: list[Check]
    stability: dict[str, object]
    resonance: dict[str, object]
    source: dict = field(default_factory=dict)
    model_panel: ModelPanel | None = None

    def as_dict(self) -> dict[str, object]:
        return {
            "source": self.source,
            "fits": {k: v.as_dict("g_s", "m_s") for k, v in self.fits.items()},
            "fits_note": "celerity (m/s, positive downstream) against mass flow rate (g/s), "
                         "ordinary least squares per group",
            "lengths": self.lengths,
            "stability": self.stability,
            "resonance": self.resonance,
            "checks": [c.as_dict() for c in self.checks],
            "n_checks": len(self.checks),
            "n_agree": sum(c.agrees for c in self.checks),
            "model_vs_experiment": None if self.model_panel is None else self.model_panel.as_dict(),
        }


def _r(x: float, nd: int = 4) -> float:
    return round(float(x), nd)


def reproduce(*, simulate: bool = True) -> PaperReproduction:
    """Fits, lengths, stated ranges, stability and resonance, each checked against the text, and the
    model against the measurements (:mod:`.model_panel`; ``simulate=False`` skips its nonlinear runs,
    about 4 s)."""
    runs = datasets.paper_runs()
    fits: dict[str, LinearFit] = {}
    lengths: dict[str, dict] = {}
    for g in GROUPS:
        sub = runs[runs.group == g]
        fits[g] = fit_line(sub.mass_flow_rate_g_s.to_numpy(), sub.celerity_m_s.to_numpy())
        lengths[g] = summarize_lengths(sub.mass_flow_rate_g_s.to_numpy(), sub.plug_length_mm.to_numpy(),
                                       diameter_mm=D_MM).as_dict()
    prop = runs[runs.regime == "propagative"]
    osc = runs[runs.regime == "oscillating"]
    lengths["propagative"] = summarize_lengths(prop.mass_flow_rate_g_s.to_numpy(), prop.plug_length_mm.to_numpy(),
                                               diameter_mm=D_MM).as_dict()
    lengths["all"] = summarize_lengths(runs.mass_flow_rate_g_s.to_numpy(), runs.plug_length_mm.to_numpy(),
                                       diameter_mm=D_MM).as_dict()
    checks: list[Check] = []

    def add(claim, where, paper, reproduced, agrees, note=""):
        checks.append(Check(claim, where, paper, reproduced, bool(agrees), note))

    # -- ranges stated in the text --------------------------------------------------------
    vr = [_r(prop.celerity_m_s.min()), _r(prop.celerity_m_s.max())]
    add("propagative celerity ranges between -0.0366 and -0.0963 m/s", "Propagative wave regime",
        [-0.0963, -0.0366], vr, vr == [-0.0963, -0.0366])
    vo = [_r(osc.celerity_m_s.min()), _r(osc.celerity_m_s.max())]
    add("oscillating v_p 'within 0.2 - 0.65 m/s'", "Oscillating wave regime", [0.2, 0.65], vo,
        math.isclose(vo[0], 0.2, rel_tol=0.05) and math.isclose(vo[1], 0.65, rel_tol=0.05),
        "Table 2 holds 0.0200-0.0652 m/s: the text's range is ten times too large (misprint)")
    mo = [_r(osc.mass_flow_rate_g_s.min(), 3), _r(osc.mass_flow_rate_g_s.max(), 3)]
    add("oscillating regime at mass flow rates between 0.25 and 0.4 g/s", "Oscillating wave regime",
        [0.25, 0.4], mo, mo[0] >= 0.25 and mo[1] <= 0.4,
        "Table 2, run 3 is at 0.41 g/s" if mo[1] > 0.4 else "")
    ma = [_r(runs.mass_flow_rate_g_s.min(), 3), _r(runs.mass_flow_rate_g_s.max(), 3)]
    add("density waves at mass flow rates between 0.1 and 0.95 g/s", "Conclusions", [0.1, 0.95], ma,
        ma[0] >= 0.1 and ma[1] <= 0.95,
        "Tables 1-2 span 0.25-1.05 g/s (Table 1, run 12 at 1.05 g/s; run 17 at 0.96 g/s)")
    # -- linear dependence, smooth vs rough ------------------------------------------------
    for g in GROUPS:
        f = fits[g]
        add(f"celerity depends linearly on the mass flow rate ({g})",
            "Propagative / Oscillating wave regime", "linear", {"r2": _r(f.r2), "n": f.n}, f.r2 >= 0.9,
            "criterion: R^2 >= 0.9")
    m_common = 0.55
    v_s = float(fits["propagative/smooth"].predict(m_common))
    v_r = float(fits["propagative/rough"].predict(m_common))
    add("smooth-grained plugs are faster than rough-grained ones", "Propagative wave regime",
        "|v_smooth| > |v_rough|", {"mass_flow_g_s": m_common, "v_smooth_m_s": _r(v_s, 5), "v_rough_m_s": _r(v_r, 5)},
        abs(v_s) > abs(v_r), "compared on the fitted lines at 0.55 g/s, inside both groups' ranges")
    # -- lengths ------------------------------------------------------------------------------
    for name in ("propagative", "oscillating"):
        ld = lengths[name]["mean_over_diameter"]
        add(f"mean plug length about 10 D (about 30 mm), {name}", f"{name.capitalize()} wave regime", 10.0,
            _r(ld, 3), abs(ld - 10) <= 1.0, "criterion: within 1 D")
    for name in ("propagative", "oscillating"):
        p = lengths[name].get("trend_slope_p_value")
        add(f"plug length independent of the mass flow rate ({name})", f"{name.capitalize()} wave regime",
            "no trend", {"slope_mm_per_g_s": _r(lengths[name]["trend_vs_mass_flow"]["slope_mm_per_g_s"], 3),
                         "p_value": None if p is None else _r(p, 4)}, p is None or p > 0.05,
            "criterion: slope not significant at 5%")
    t1 = datasets.table1()
    a, b = t1[t1.surface == "rough"].plug_length_mm, t1[t1.surface == "smooth"].plug_length_mm
    pv = float(stats.ttest_ind(a, b, equal_var=False).pvalue)
    add("plug length independent of the surface state", "Propagative wave regime", "no difference",
        {"rough_mm": _r(a.mean(), 2), "smooth_mm": _r(b.mean(), 2), "welch_p": _r(pv, 4)}, pv > 0.05,
        "criterion: Welch t-test not significant at 5%")
    pv2 = float(stats.ttest_ind(prop.plug_length_mm, osc.plug_length_mm, equal_var=False).pvalue)
    add("the propagative regime presented identical lengths (length independent of the regime)",
        "Oscillating wave regime", "identical",
        {"propagative_mm": _r(prop.plug_length_mm.mean(), 2), "oscillating_mm": _r(osc.plug_length_mm.mean(), 2),
         "welch_p": _r(pv2, 5)}, pv2 > 0.05,
        "criterion: Welch t-test not significant at 5%; the oscillating plugs are ~1.7 mm longer")
    # -- figure captions against the tables -----------------------------------------------------
    # (the large-amplitude figure's run, 0.25 g/s and 0.0190 m/s, is not looked for: Table 2 holds the
    # low-amplitude runs only, as its caption says, and the paper does not claim to tabulate it)
    captions = [("Fig. propag_2 caption", 1, 0.55, -0.0538), ("Fig. propag_nov caption", 1, 0.40, -0.0408),
                ("Fig. vista caption", 1, 0.37, -0.0366), ("Fig. small (a) caption", 2, 0.26, 0.0250),
                ("Fig. small (b) caption", 2, 0.37, 0.0501)]
    for where, table, mdot, v in captions:
        hit = runs[(runs.table == table) & np.isclose(runs.mass_flow_rate_g_s, mdot) & np.isclose(runs.celerity_m_s, v)]
        add(f"a run with mass flow {mdot} g/s and v_p = {v} m/s (Table {table})", where, [mdot, v],
            [int(r) for r in hit.run] if len(hit) else None, len(hit) > 0,
            "" if len(hit) else "no such run")
    # -- bibliography ----------------------------------------------------------------------------
    bib = "E.~M. Franklin, C.~A. Zambrano"  # the paper's reference list, entry Franklin_7
    # C. A. Zambrano there and this paper's author Carlos A. Alvarez are one person, Carlos Alvarez Zambrano,
    # under either of his surnames: the citation is right (an earlier version called it a disagreement)
    add("'Franklin and Alvarez [Franklin_7]' cited for the Janssen closure and 3 < lambda/D < 11",
        "Introduction, model", "Franklin and Alvarez", bib, "Zambrano" in bib,
        "the reference list names the co-author by his second surname (Carlos A. Alvarez Zambrano)")
    # -- free fall in the bubbles ---------------------------------------------------------------------
    L_b = lengths["propagative"]["mean_mm"] * 1e-3
    v_ff = math.sqrt(2 * 9.81 * L_b)
    add("free fall through a bubble gives about 0.9 m/s (measured ~0.8 m/s)", "Propagative wave regime", 0.9,
        _r(v_ff, 3), abs(v_ff - 0.9) <= 0.1,
        "sqrt(2 g L) over one bubble of the mean plug length (bubbles ~ plugs, ~10 D); "
        "0.9 m/s needs a 41 mm fall")
    # -- stability ------------------------------------------------------------------------------------------
    stab: dict[str, object] = {}
    for variant in ("printed", "frozen-friction"):
        res = analyze_stability(ModelParams(variant=variant), k_min=1e-3, k_max=3.0, n_k=3000)
        m = res.most_unstable
        stab[variant] = {
            "B1_star": res.params.B1_star,
            "most_unstable": m.as_dict() if m else None,
            "cutoff_k": res.cutoff_k,
            "cutoff_wavelength_over_diameter": res.cutoff_wavelength_over_diameter,
        }
    pm = stab["printed"]["most_unstable"]
    add("long-wave instability, most unstable k* ~ 0.2, cut-off k* ~ 0.6 (printed model)", "Stability analysis",
        {"k": 0.2, "cutoff_k": 0.6}, {"most_unstable": pm, "cutoff_k": stab["printed"]["cutoff_k"]}, pm is not None,
        "the printed equations with the paper's inputs are stable at every k* (docs/stability.md)")
    fm = stab["frozen-friction"]["most_unstable"]
    fc = stab["frozen-friction"]["cutoff_k"]
    add("most unstable k* ~ 0.2 and cut-off ~ 0.6 (variant frozen-friction)", "Stability analysis",
        {"k": 0.2, "cutoff_k": 0.6}, {"k": _r(fm["k"]), "cutoff_k": [_r(c) for c in fc]},
        abs(fm["k"] - 0.2) <= 0.06 and len(fc) == 1 and abs(fc[0] - 0.6) <= 0.1,
        "variant: wall friction not perturbed; criterion: within 0.06 and 0.1")
    lam_mu = fm["wavelength_over_diameter"]
    lam_c = stab["frozen-friction"]["cutoff_wavelength_over_diameter"][0]
    add("wavelengths in the order of 10 D (comparison uses the cut-off wavelength)", "Stability analysis", 10.0,
        {"cutoff_lambda_over_D": _r(lam_c, 2), "most_unstable_lambda_over_D": _r(lam_mu, 2)},
        abs(lam_c - 10) <= 2,
        "the most unstable wavelength is ~43 D; only the cut-off wavelength is ~10 D")
    # -- resonance ---------------------------------------------------------------------------------------------
    res_a = resonance(ResonanceInputs())
    q = res_a["quarter_wave_hz"][0]
    h = res_a["half_wave_hz"][0]
    add("an acoustic resonance of about 4 Hz (measured oscillations 7 Hz)", "Oscillating wave regime", 4.0,
        {"quarter_wave_hz": _r(q, 2), "half_wave_hz": _r(h, 2)}, abs(q - 4) <= 1,
        "1 m column, c = 0.55, adiabatic air (Wood); the half-wave mode is ~7.6 Hz")
    panel = model_panel(measured_from(prop.celerity_m_s.to_numpy(), prop.plug_length_mm.to_numpy(), None,
                                      source="the paper's Table 1, propagative regime"),
                        diameter_mm=D_MM, simulate=simulate)
    panel = dataclasses.replace(panel, verdict=[*panel.verdict, _table2_celerity(osc, panel)])
    return PaperReproduction(fits, lengths, checks, stab, res_a, datasets.source(), panel)


def _table2_celerity(osc: pd.DataFrame, panel: ModelPanel) -> str:
    """The panel compares Table 1; Table 2's plugs (low-amplitude oscillating) move down, the model's way: how
    their speed compares with its growing waves'."""
    lo, hi = float(osc.celerity_m_s.min()), float(osc.celerity_m_s.max())
    speeds = [q.phase_speed_m_s for q in panel.predictions if q.phase_speed_m_s is not None and q.lambda_D is not None]
    text = (f"Celerity, Table 2 (low-amplitude oscillating plugs, not in the comparison above): they move down, "
            f"{lo:+.3f} to {hi:+.3f} m/s")
    if not speeds:
        return text + "; no set-up has a growing wave to compare."
    same = [v for v in speeds if v > 0]
    if not same:
        return text + (f"; the model's growing waves travel the other way ({min(speeds):+.2f} to "
                       f"{max(speeds):+.2f} m/s).")
    return (text + f": the direction of the model's growing waves ({min(same):+.2f} to {max(same):+.2f} m/s), "
            f"which are {min(same) / hi:.0f} to {max(same) / lo:.0f} times faster.")


def reproduction_text(rep: PaperReproduction) -> str:
    """Markdown: where the reproduction agrees with the paper and where it does not."""
    lines = ["# Reproduction of Alvarez & Franklin (2017) from its own tables", "",
             f"Source: {rep.source.get('citation')} (doi:{rep.source.get('doi')}).", "",
             "## Fits of celerity against mass flow rate", "",
             "| group | slope (m/s per g/s) | intercept (m/s) | R² | n |", "| --- | --- | --- | --- | --- |"]
    for g, f in rep.fits.items():
        lines.append(f"| {g} | {f.slope:+.4f} ± {f.slope_stderr:.4f} | {f.intercept:+.4f} ± "
                     f"{f.intercept_stderr:.4f} | {f.r2:.3f} | {f.n} |")
    lines += ["", "## Plug lengths", "", "| group | mean (mm) | sd (mm) | λ/D | n |", "| --- | --- | --- | --- | --- |"]
    for g, ld in rep.lengths.items():
        sd = "—" if ld["sd_mm"] is None else f"{ld['sd_mm']:.2f}"  # one run: no spread
        lines.append(f"| {g} | {ld['mean_mm']:.2f} | {sd} | {ld['mean_over_diameter']:.2f} | {ld['n']} |")
    agree = [c for c in rep.checks if c.agrees]
    disagree = [c for c in rep.checks if not c.agrees]
    lines += ["", f"## Where the reproduction agrees ({len(agree)})", ""]
    lines += [f"- **{c.claim}** ({c.where}): paper {c.paper}; reproduced {c.reproduced}."
              + (f" {c.note}" if c.note else "") for c in agree]
    lines += ["", f"## Where it does not ({len(disagree)})", ""]
    lines += [f"- **{c.claim}** ({c.where}): paper {c.paper}; reproduced {c.reproduced}. {c.note}"
              for c in disagree]
    lines += ["", "The stability figures are written for the printed model and for the `frozen-friction` "
              "variant; see docs/stability.md for why only the variant is unstable.", ""]
    if rep.model_panel is not None:
        lines += ["## Model against experiment", ""] + [f"- {s}" for s in rep.model_panel.verdict] + [""]
    return "\n".join(lines)
