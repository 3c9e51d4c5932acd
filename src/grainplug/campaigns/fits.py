"""Straight-line fits of plug celerity and length against the mass flow rate, and a campaign's fits.

:func:`fit_selection` chooses the runs of a campaign table that the fits use (and says why the
others are left out), :func:`campaign_fits` fits them per group and over all runs. The batch
(:mod:`.batch`), its report (:mod:`.report`) and the command line read the fits from here.

Notes
-----
Ordinary least squares ``y = a + b x`` with the textbook standard errors

.. math:: s^2 = \\frac{\\sum r_i^2}{n - 2}, \\quad
          \\mathrm{se}(b) = \\frac{s}{\\sqrt{S_{xx}}}, \\quad
          \\mathrm{se}(a) = s \\sqrt{\\frac{1}{n} + \\frac{\\bar x^2}{S_{xx}}}

and the 95% confidence band of the mean response
``a + b x +- t_{0.975, n-2} s sqrt(1/n + (x - xbar)^2 / S_xx)``
(e.g. Montgomery & Runger, *Applied Statistics and Probability for Engineers*, ch. 11).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats

from .schema import COLUMNS


@dataclass(frozen=True)
class LinearFit:
    """``y = intercept + slope * x`` by least squares."""

    slope: float
    intercept: float
    slope_stderr: float
    intercept_stderr: float
    r2: float
    n: int
    residual_sd: float
    x_mean: float
    sxx: float
    x_min: float
    x_max: float

    def predict(self, x: np.ndarray | float) -> np.ndarray:
        return self.intercept + self.slope * np.asarray(x, float)

    def band(self, x: np.ndarray | float, level: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
        """Confidence band of the mean response at ``x``."""
        x = np.asarray(x, float)
        if self.n < 3:
            y = self.predict(x)
            return y, y
        tq = stats.t.ppf(0.5 + level / 2, self.n - 2)
        half = tq * self.residual_sd * np.sqrt(1 / self.n + (x - self.x_mean) ** 2 / self.sxx)
        y = self.predict(x)
        return y - half, y + half

    def as_dict(self, x_unit: str = "g_s", y_unit: str = "m_s") -> dict[str, float | int]:
        """Keys with units, e.g. ``slope_m_s_per_g_s`` and ``intercept_m_s``."""
        return {
            f"slope_{y_unit}_per_{x_unit}": self.slope, f"intercept_{y_unit}": self.intercept,
            "slope_stderr": self.slope_stderr, "intercept_stderr": self.intercept_stderr,
            "r2": self.r2, "n": self.n, "residual_sd": self.residual_sd,
            f"x_min_{x_unit}": self.x_min, f"x_max_{x_unit}": self.x_max,
        }


def fit_line(x: np.ndarray, y: np.ndarray) -> LinearFit | None:
    """Least-squares line through ``(x, y)`` (None with fewer than 2 points or no spread in x)."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    n = len(x)
    if n < 2 or np.ptp(x) == 0:
        return None
    xm = float(x.mean())
    sxx = float(((x - xm) ** 2).sum())
    slope = float(((x - xm) * (y - y.mean())).sum() / sxx)
    intercept = float(y.mean() - slope * xm)
    res = y - (intercept + slope * x)
    ss_res = float((res**2).sum())
    ss_tot = float(((y - y.mean()) ** 2).sum())
    r2 = 1 - ss_res / ss_tot if ss_tot > 0 else 1.0
    s = math.sqrt(ss_res / (n - 2)) if n > 2 else float("nan")
    return LinearFit(slope, intercept, s / math.sqrt(sxx), s * math.sqrt(1 / n + xm**2 / sxx), r2, n, s,
                     xm, sxx, float(x.min()), float(x.max()))


@dataclass(frozen=True)
class LengthSummary:
    """Plug lengths of a group: mean, spread, lambda/D and the trend with mass flow rate."""

    mean_mm: float
    sd_mm: float  # NaN for one run (null in fits.json)
    n: int
    mean_over_diameter: float
    ci95_mm: tuple[float, float]  # NaN for one run (null in fits.json)
    trend: LinearFit | None

    def as_dict(self) -> dict[str, object]:
        spread = self.n > 1  # one run has no spread: null, not a zero-width interval
        d = {"mean_mm": self.mean_mm, "sd_mm": self.sd_mm if spread else None, "n": self.n,
             "mean_over_diameter": self.mean_over_diameter, "ci95_mm": list(self.ci95_mm) if spread else None}
        if self.trend is not None:
            d["trend_vs_mass_flow"] = self.trend.as_dict("g_s", "mm")
            d["trend_slope_p_value"] = slope_p_value(self.trend)
        return d


def slope_p_value(fit: LinearFit) -> float | None:
    """Two-sided p-value of ``slope = 0``."""
    if fit.n < 3 or not fit.slope_stderr > 0:
        return None
    return float(2 * stats.t.sf(abs(fit.slope / fit.slope_stderr), fit.n - 2))


def summarize_lengths(mass_flow_g_s: np.ndarray, length_mm: np.ndarray, *,
                      diameter_mm: float) -> LengthSummary | None:
    """Mean plug length of a group, its spread and its (lack of) trend with the flow rate."""
    L = np.asarray(length_mm, float)
    ok = np.isfinite(L)
    if not ok.any():
        return None
    L = L[ok]
    n = len(L)
    m = float(L.mean())
    sd = float(L.std(ddof=1)) if n > 1 else math.nan  # one run: no spread to state
    half = float(stats.t.ppf(0.975, n - 1) * sd / math.sqrt(n)) if n > 1 else math.nan
    trend = fit_line(np.asarray(mass_flow_g_s, float)[ok], L)
    return LengthSummary(m, sd, n, m / diameter_mm, (m - half, m + half), trend)


def _group(row: pd.Series) -> str | None:
    if isinstance(row.get("group"), str) and row["group"]:
        return row["group"]
    regime = row.get("regime")
    if not isinstance(regime, str) or regime == "none":
        return None
    surface = row.get("surface")
    return f"{regime}/{surface}" if isinstance(surface, str) and surface else regime


#: the reason :func:`fit_selection` gives, under this key, when no run can be fitted at all
ALL_RUNS = ""


#: a run's celerity interval this many times wider than the campaign's typical one, holding 0, says nothing
#: of its speed (a scene that is no plug train: +1.1 +- 1.2 m/s among runs known to +- 1e-5 m/s)
WIDE_INTERVAL = 10.0


def wide_and_still(ok: pd.DataFrame) -> pd.Series:
    """Runs whose celerity interval holds 0 and is :data:`WIDE_INTERVAL` times wider than the median
    (of at least 3 runs): they say nothing of the speed. A narrow interval about 0 is a measured still drift."""
    if not {"celerity_ci95_low_m_s", "celerity_ci95_high_m_s"} <= set(ok) or ok.empty:
        return pd.Series(False, index=ok.index)
    lo = ok.celerity_ci95_low_m_s.to_numpy(dtype=float, na_value=np.nan)
    hi = ok.celerity_ci95_high_m_s.to_numpy(dtype=float, na_value=np.nan)
    half = 0.5 * (hi - lo)
    finite = np.isfinite(half)
    if finite.sum() < 3:
        return pd.Series(False, index=ok.index)
    typical = float(np.median(half[finite]))
    with np.errstate(invalid="ignore"):
        return pd.Series(finite & (lo <= 0) & (hi >= 0) & (half > WIDE_INTERVAL * typical), index=ok.index)


def fit_selection(table: pd.DataFrame) -> tuple[pd.DataFrame, dict[str, str]]:
    """The analysed runs the fits against mass flow rate use (with their ``fit_group``, and ``fit_celerity``:
    whether the celerity fit uses them too), and why each other analysed run is left out of a fit
    (``{run: reason}``; under :data:`ALL_RUNS` when no run can be fitted).

    Left out of every fit: a run without a mass flow rate, a run without plugs. Left out of the celerity
    fit only: a run without a celerity, and one whose celerity's interval holds 0 and is many times wider
    than the campaign's (:func:`wide_and_still`: a least-squares line would weigh it as much as a
    well-measured run).
    """
    ok = table[table.status == "ok"].copy() if "status" in table else table.copy()
    empty = ok.iloc[:0].assign(fit_group=pd.Series(dtype=object), fit_celerity=pd.Series(dtype=bool))
    if ok.empty:
        return empty, {}
    if "mass_flow_rate_g_s" not in ok:  # a campaign without fits; said when a column looks meant for it
        # a column of grainplug's own table (the rate measured from the movies) is not one the manifest meant
        near = [str(c) for c in ok.columns if ("mass" in str(c).lower() or "flow_rate" in str(c).lower())
                and str(c) not in COLUMNS]
        return empty, {ALL_RUNS: f"the manifest has no mass_flow_rate_g_s column (is {near[0]!r} meant? name it "
                                 "mass_flow_rate_g_s): nothing to fit the runs against"} if near else {}
    ok["fit_group"] = ok.apply(_group, axis=1)
    wide = wide_and_still(ok)
    why: dict[str, str] = {}
    keep, celerity = [], []
    for i, r in ok.iterrows():
        run = str(r.run)
        no_plugs = pd.isna(r.fit_group) or r.get("regime") == "none"
        if pd.isna(r.mass_flow_rate_g_s):
            why[run] = "left out of the fits: no mass flow rate in the manifest"
        elif no_plugs:
            why[run] = "left out of the fits: no plugs measured"
        keep.append(run not in why)
        if run in why:
            celerity.append(False)
        elif pd.isna(r.get("celerity_m_s")):
            why[run] = "left out of the celerity fit: no celerity measured"
            celerity.append(False)
        elif wide[i]:
            why[run] = ("left out of the celerity fit: no direction of travel, its celerity's 95 % interval holds 0 "
                        f"and is over {WIDE_INTERVAL:g} times wider than the campaign's")
            celerity.append(False)
        else:
            celerity.append(True)
    ok["fit_celerity"] = celerity
    return ok[np.asarray(keep, bool)], why


def campaign_fits(table: pd.DataFrame, *, diameter_mm: float = 3.0) -> dict[str, dict]:
    """Celerity and length against mass flow rate, per group and over all runs (those of
    :func:`fit_selection`)."""
    ok, _ = fit_selection(table)
    if ok.empty:
        return {}
    out: dict[str, dict] = {}
    for name, sub in [*ok.groupby("fit_group"), ("all", ok)]:
        x = sub.mass_flow_rate_g_s.to_numpy(dtype=float, na_value=np.nan)
        moving = sub[sub.fit_celerity]
        fc = fit_line(moving.mass_flow_rate_g_s.to_numpy(dtype=float, na_value=np.nan),
                      moving.celerity_m_s.to_numpy(dtype=float, na_value=np.nan))
        ls = summarize_lengths(x, sub.plug_length_mm.to_numpy(dtype=float, na_value=np.nan), diameter_mm=diameter_mm)
        out[str(name)] = {"celerity": fc.as_dict("g_s", "m_s") if fc else None,
                          "length": ls.as_dict() if ls else None, "runs": sub.run.tolist(),
                          "celerity_runs": moving.run.tolist()}
    return out
