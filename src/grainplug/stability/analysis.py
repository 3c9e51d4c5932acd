"""Most unstable mode, cut-off wavenumbers and parameter sweeps."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from ..errors import ParameterError
from .model import roots
from .params import ModelParams


@dataclass(frozen=True)
class Mode:
    """A normal mode at one wavenumber.

    Attributes
    ----------
    k : float
        Dimensionless wavenumber ``k* = k D``.
    growth_rate : float
        ``omega_i*`` (units of ``1/t_c``).
    phase_speed : float
        ``omega_r* / k*`` (units of ``v_c``; positive downstream).
    wavelength_over_diameter : float
        ``lambda / D = 2 pi / k*``.
    root : int
        Which of the three tracked roots.
    at_range_edge : {"k_min", "k_max"}, optional
        Set when the growth rate is largest at that end of the range scanned: it still rises
        beyond it, so this is the range's largest growth, not a maximum of the model (widen
        the range; with ``"k_max"`` and no cut-off the growth may rise to the shortest waves).
    """

    k: float
    growth_rate: float
    phase_speed: float
    wavelength_over_diameter: float
    root: int
    at_range_edge: str | None = None

    def as_dict(self) -> dict[str, float | int | str | None]:
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class StabilityResult:
    """The three roots over a range of wavenumbers, and what they mean.

    Attributes
    ----------
    params : ModelParams
    k : ndarray
        Wavenumbers ``k*``.
    omega : ndarray, shape (n_k, 3)
        Roots ``omega*``, each column one root followed along ``k*``.
    most_unstable : Mode or None
        The largest positive growth rate over the range, refined; None when no
        ``k*`` in the range is unstable.
    cutoff_k : list of float
        Every ``k*`` where the largest growth rate crosses zero (edges of the
        unstable bands inside the range), refined by root finding.
    unstable_bands : list of (float, float)
        Ranges of ``k*`` with a positive growth rate.
    """

    params: ModelParams
    k: np.ndarray
    omega: np.ndarray
    most_unstable: Mode | None
    cutoff_k: list[float]
    unstable_bands: list[tuple[float, float]]

    @property
    def cutoff_wavelength_over_diameter(self) -> list[float]:
        return [2 * math.pi / k for k in self.cutoff_k]

    def __repr__(self) -> str:
        """A few lines: the set-up, the most unstable mode and the cut-offs (not the arrays)."""
        m = self.most_unstable
        head = (f"<StabilityResult {self.params.variant} ({self.params.law} friction), k* in "
                f"[{self.k[0]:g}, {self.k[-1]:g}] ({len(self.k)} points)")
        if m is None:
            lines = [head, "stable: no wavenumber in the range grows"]
        else:
            what = ("most unstable" if m.at_range_edge is None else
                    f"largest growth, at the range's end {m.at_range_edge}")
            lines = [head, f"{what}: k* = {m.k:.4g}, lambda/D = {m.wavelength_over_diameter:.4g}, growth "
                           f"{m.growth_rate:.4g}/t_c, phase speed {m.phase_speed:+.4g} v_c"]
        if self.cutoff_k:
            lines.append("cut-off lambda/D: " + ", ".join(f"{x:.4g}" for x in self.cutoff_wavelength_over_diameter))
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n  ".join(lines) + ">"

    @property
    def stable(self) -> bool:
        return self.most_unstable is None

    @property
    def warnings(self) -> list[str]:
        """What the range scanned leaves unsure: a largest growth at one of its ends."""
        m = self.most_unstable
        if m is None or m.at_range_edge is None:
            return []
        way = "longer" if m.at_range_edge == "k_min" else "shorter"
        end = "lower" if m.at_range_edge == "k_min" else "upper"
        return [f"the growth rate is largest at the edge of the range, {m.at_range_edge} = {m.k:g}: it still rises "
                f"toward {way} waves, so no most unstable wavelength was found inside the range (the λ/D given is "
                f"the range's end) — move its {end} end ({m.at_range_edge}=)"]

    def as_dict(self) -> dict[str, object]:
        """JSON-ready: the CLI's ``--json`` (see docs/stability.md)."""
        p = self.params
        return {
            "variant": p.variant,
            "setup": {"friction_law": p.law, "base_pressure_pa": p.base_pressure_abs_pa, "P0_star": p.P0_star,
                      "base_velocity": p.base_velocity, "v0_star": p.v0_star, "B_star": p.B_star,
                      "base_state_residual": p.base_state_residual, "printed": p.is_printed,
                      "jamming": p.jamming, "jamming_slope": p.jamming_slope,
                      "caveats": p.caveats()},
            "B1_star": p.B1_star,
            "inputs": p.as_dict(),
            "k": self.k.tolist(),
            "omega_real": [self.omega[:, j].real.tolist() for j in range(3)],
            "omega_imag": [self.omega[:, j].imag.tolist() for j in range(3)],
            "most_unstable": self.most_unstable.as_dict() if self.most_unstable else None,
            "cutoff_k": self.cutoff_k,
            "cutoff_wavelength_over_diameter": self.cutoff_wavelength_over_diameter,
            "unstable_bands": [list(b) for b in self.unstable_bands],
            "stable": self.stable,
            "warnings": self.warnings,
        }


def max_growth(p: ModelParams, k: float) -> float:
    """Largest growth rate of the three roots at one ``k*``."""
    return float(roots(p, np.array([k]), track=False)[0].imag.max())


def _mode(p: ModelParams, k: float) -> Mode:
    w = roots(p, np.array([k]), track=False)[0]
    j = int(np.argmax(w.imag))
    return Mode(float(k), float(w[j].imag), float(w[j].real / k), 2 * math.pi / k, j)


def analyze_stability(p: ModelParams, k: np.ndarray | None = None, *, k_min: float = 1e-3,
                      k_max: float = 3.0, n_k: int = 1000) -> StabilityResult:
    """Roots, most unstable mode and cut-offs over ``k*`` in ``[k_min, k_max]``.

    Parameters
    ----------
    p : ModelParams
        The set-up (the paper's printed model by default; variants and switches in
        :class:`ModelParams`).
    k : array_like, optional
        Dimensionless wavenumbers ``k* = k D``; by default ``n_k`` evenly spaced in
        ``[k_min, k_max]``.
    k_min, k_max : float
        The range scanned when ``k`` is not given (``0 < k_min < k_max``). A largest
        growth at one of its ends is flagged (:attr:`Mode.at_range_edge`) and warned
        about (:attr:`StabilityResult.warnings`): move that end.
    n_k : int
        Number of wavenumbers in the range (2 to 10^6).

    Returns
    -------
    StabilityResult
        The three roots at each ``k*``, the most unstable mode (refined between grid
        points), the cut-offs and the unstable bands.

    Examples
    --------
    >>> import grainplug as gp
    >>> res = gp.analyze_stability(gp.ModelParams(variant="frozen-friction"))
    >>> round(res.most_unstable.wavelength_over_diameter, 1)
    42.6
    """
    if k is None:
        if not (np.isfinite(k_min) and np.isfinite(k_max) and 0 < k_min < k_max):
            raise ParameterError(f"need finite 0 < k_min < k_max, got {k_min} and {k_max}", param="k_min")
        if not 2 <= n_k <= 1_000_000:
            raise ParameterError(f"n_k must be between 2 and 1e6 wavenumbers, got {n_k}", param="n_k")
        k = np.linspace(k_min, k_max, int(n_k))
    k = np.asarray(k, float)
    if not np.all(np.isfinite(k)):
        raise ParameterError("the wavenumbers must be finite", param="k")
    w = roots(p, k)
    g = w.imag.max(axis=1)
    pos = g > 0
    bands: list[tuple[float, float]] = []
    cutoffs: list[float] = []

    def f(x: float) -> float:
        return max_growth(p, x)

    edges = np.nonzero(np.diff(pos.astype(int)))[0]
    for i in edges:
        try:
            kc = optimize.brentq(f, k[i], k[i + 1], xtol=1e-12)
        except ValueError:
            kc = 0.5 * (k[i] + k[i + 1])
        cutoffs.append(float(kc))
    # bands from the sign changes (the range ends bound open bands)
    starts = [float(k[0])] if pos[0] else []
    stops: list[float] = []
    for i, kc in zip(edges, cutoffs, strict=True):
        (starts if pos[i + 1] else stops).append(kc)
    if pos[-1]:
        stops.append(float(k[-1]))
    bands = list(zip(starts, stops, strict=False))
    most = None
    if pos.any():
        j = int(np.argmax(g))
        lo, hi = k[max(j - 1, 0)], k[min(j + 1, len(k) - 1)]
        if hi > lo:
            r = optimize.minimize_scalar(lambda x: -f(x), bounds=(lo, hi), method="bounded",
                                         options={"xatol": 1e-10})
            kk = float(r.x) if -r.fun >= g[j] else float(k[j])
        else:
            kk = float(k[j])
        most = _mode(p, kk)
        end = k[0] if j == 0 else k[-1] if j == len(k) - 1 else None
        # the growth still rising beyond the range: the refined maximum sits on its end (between the end and the
        # next grid point, it is the model's)
        if end is not None and len(k) > 1 and abs(kk - end) <= 1e-6 * abs(k[1] - k[0]) + 1e-9:
            most = dataclasses.replace(most, at_range_edge="k_min" if j == 0 else "k_max")
    return StabilityResult(p, k, w, most, cutoffs, bands)


def sweep(p: ModelParams, name: str, values: np.ndarray, **kwargs: float) -> list[dict[str, object]]:
    """Most unstable mode and cut-offs as one input varies.

    Parameters
    ----------
    p : ModelParams
        Base inputs.
    name : str
        A field of :class:`ModelParams` (e.g. ``"grain_diameter_um"``, ``"c0"``,
        ``"B1_star_override"``).
    values : array_like
        Values to take.
    **kwargs
        Passed to :func:`analyze_stability` (``k_min``, ``k_max``, ``n_k``).

    Returns
    -------
    list of dict
        One row per value: the value, ``B1*``, the most unstable ``k*``, growth rate
        and ``lambda/D``, and the cut-offs with their ``lambda/D``.
    """
    if name not in {f.name for f in dataclasses.fields(ModelParams)}:
        raise ValueError(f"unknown input {name!r}")
    rows = []
    for v in np.asarray(values, float):
        q = dataclasses.replace(p, **{name: float(v)})
        r = analyze_stability(q, **kwargs)
        m = r.most_unstable
        rows.append({
            name: float(v), "B1_star": q.B1_star,
            "most_unstable_k": m.k if m else None,
            "most_unstable_growth_rate": m.growth_rate if m else None,
            "most_unstable_wavelength_over_diameter": m.wavelength_over_diameter if m else None,
            "most_unstable_at_range_edge": m.at_range_edge if m else None,
            "cutoff_k": r.cutoff_k,
            "cutoff_wavelength_over_diameter": r.cutoff_wavelength_over_diameter,
        })
    return rows
