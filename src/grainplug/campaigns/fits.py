"""Straight-line fits of plug celerity and length against the mass flow rate.

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
from scipy import stats


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
