"""Most unstable mode, cut-off wavenumbers and parameter sweeps."""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from .._system import free_memory_bytes
from ..errors import ParameterError
from .model import CHUNK_SIZE, WORK_BYTES_PER_K, _raw_roots, _RootTracker, roots
from .params import ModelParams

log = logging.getLogger(__name__)

#: wavenumbers whose roots a result keeps in full; beyond, it keeps a curve of about CURVE_POINTS of them
MAX_POINTS = 100_000
#: wavenumbers of the curve kept beyond MAX_POINTS (evenly spread; and the peak's and the cut-offs' brackets)
CURVE_POINTS = 10_000
#: a sweep's duration is estimated again once it ran this long, seconds
SWEEP_RECHECK_S = 2.0
#: the longest computation started unasked, seconds (``max_seconds=None`` lifts it)
MAX_SECONDS = 3600.0
#: sign changes of the largest growth rate beyond which the cut-offs are a root neutral to round-off
MAX_CUTOFFS = 100_000
#: share of the free memory (MemAvailable) that a computation may plan to use
MEMORY_SHARE = 0.8
#: bytes a kept wavenumber takes: k* and its three complex roots
ROW_BYTES = 8 + 3 * 16
#: bytes a sweep needs per value: its row, and the command line's table, figure and JSON of it (measured: 3.5 kB)
SWEEP_BYTES_PER_VALUE = 4096


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
    n_k : int
        How many wavenumbers were analysed (``len(k)`` unless :attr:`decimated`).

    Notes
    -----
    Up to ``max_points`` wavenumbers (10^5 by default, :func:`analyze_stability`)
    ``k`` and ``omega`` hold every one; beyond, they hold a curve of about 10^4 of
    them (:attr:`decimated`): 10^4 evenly spread over the grid (the first and last
    included), the grid point of the largest growth rate and both grid points around
    each sign change of the largest growth rate, with their roots exactly as computed. The most unstable mode, the
    cut-offs and the bands are always those of every wavenumber.
    """

    params: ModelParams
    k: np.ndarray
    omega: np.ndarray
    most_unstable: Mode | None
    cutoff_k: list[float]
    unstable_bands: list[tuple[float, float]]
    n_k: int = -1

    def __post_init__(self) -> None:
        if self.n_k < 0:
            object.__setattr__(self, "n_k", len(self.k))

    @property
    def decimated(self) -> bool:
        """Whether ``k`` and ``omega`` hold a curve of the wavenumbers analysed rather than all of them."""
        return len(self.k) < self.n_k

    @property
    def cutoff_wavelength_over_diameter(self) -> list[float]:
        return [2 * math.pi / k for k in self.cutoff_k]

    def __repr__(self) -> str:
        """A few lines: the set-up, the most unstable mode and the cut-offs (not the arrays)."""
        m = self.most_unstable
        head = (f"<StabilityResult {self.params.variant} ({self.params.law} friction), k* in "
                f"[{self.k[0]:g}, {self.k[-1]:g}] ({self.n_k} points"
                + (f", a curve of {len(self.k)} kept)" if self.decimated else ")"))
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
            "n_k": self.n_k,
            "decimated": self.decimated,
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
                      k_max: float = 3.0, n_k: int = 1000, max_points: int | None = MAX_POINTS,
                      curve_points: int = CURVE_POINTS, chunk_size: int = CHUNK_SIZE,
                      max_seconds: float | None = MAX_SECONDS) -> StabilityResult:
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
        Number of wavenumbers in the range (at least 2). They are solved
        ``chunk_size`` at a time, so the memory does not grow with ``n_k`` (about
        2.5 µs a wavenumber; 10^8 in a few minutes).
    max_points : int or None
        Keep the roots of every wavenumber when there are at most this many (None:
        always, if the memory allows); beyond, keep a curve of about ``curve_points``
        of them (:attr:`StabilityResult.decimated`).
    curve_points : int
        Size of that curve (at least 2): so many wavenumbers evenly spread over the grid
        (the first and last included), plus the grid point of the largest growth rate
        and the two around each cut-off.
    chunk_size : int
        Wavenumbers solved at a time (about 1.2 kB of working memory each). The
        results do not depend on it.
    max_seconds : float or None
        Refuse (:class:`~grainplug.errors.ParameterError`) a computation estimated,
        from the time of its first chunk, to take longer; None: no limit.

    Returns
    -------
    StabilityResult
        The three roots at each ``k*`` (or a curve of them), the most unstable mode
        (refined between grid points), the cut-offs and the unstable bands.

    Raises
    ------
    ParameterError
        A bad range or count; results that would not fit in the free memory, or a
        computation longer than ``max_seconds``; more than 10^5 sign changes of the
        largest growth rate (a root neutral to round-off, whose cut-offs would be noise).

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
        if not (np.isfinite(n_k) and n_k >= 2):
            raise ParameterError(f"n_k must be at least 2 wavenumbers, got {n_k}", param="n_k")
        ks = _Wavenumbers(None, float(k_min), float(k_max), int(n_k))
        param = "n_k"
    else:
        k = np.atleast_1d(np.asarray(k, float))
        if not np.all(np.isfinite(k)):
            raise ParameterError("the wavenumbers must be finite", param="k")
        if k.size == 0:
            raise ParameterError("no wavenumbers given", param="k")
        ks = _Wavenumbers(k, float(k[0]), float(k[-1]), k.size)
        param = "k"
    if max_points is not None and max_points < 0:
        raise ParameterError(f"max_points must be >= 0 or None, got {max_points}", param="max_points")
    if not curve_points >= 2:
        raise ParameterError(f"curve_points must be at least 2, got {curve_points}", param="curve_points")
    if not chunk_size >= 1:
        raise ParameterError(f"chunk_size must be at least 1, got {chunk_size}", param="chunk_size")
    n = ks.n
    keep_all = max_points is None or n <= max_points
    _check_memory(n, keep_all=keep_all, curve_points=int(curve_points), chunk_size=int(chunk_size), param=param)
    scan = _scan(p, ks, keep_all=keep_all, curve_points=int(curve_points), chunk_size=int(chunk_size),
                 max_seconds=max_seconds, param=param)
    most = None
    if scan.best_g > 0:
        j = scan.best_j
        lo, hi = ks.at(max(j - 1, 0)), ks.at(min(j + 1, n - 1))
        if hi > lo:
            r = optimize.minimize_scalar(lambda x: -max_growth(p, x), bounds=(lo, hi), method="bounded",
                                         options={"xatol": 1e-10})
            kk = float(r.x) if -r.fun >= scan.best_g else ks.at(j)
        else:
            kk = ks.at(j)
        most = _mode(p, kk)
        end = ks.at(0) if j == 0 else ks.at(n - 1) if j == n - 1 else None
        # the growth still rising beyond the range: the refined maximum sits on its end (between the end and the
        # next grid point, it is the model's)
        if end is not None and n > 1 and abs(kk - end) <= 1e-6 * abs(ks.at(1) - ks.at(0)) + 1e-9:
            most = dataclasses.replace(most, at_range_edge="k_min" if j == 0 else "k_max")
    return StabilityResult(p, scan.k, scan.omega, most, scan.cutoffs, scan.bands, n_k=n)


class _Wavenumbers:
    """The wavenumbers scanned, read a chunk at a time: the array given, or ``n`` evenly spaced.

    The evenly spaced ones are computed as :func:`numpy.linspace` computes them, so that a chunk
    holds the same numbers, to the last bit, as the same slice of ``np.linspace(k_min, k_max, n)``.
    """

    def __init__(self, k: np.ndarray | None, k_min: float, k_max: float, n: int) -> None:
        self.given, self.k_min, self.k_max, self.n = k, k_min, k_max, n
        self.step = (k_max - k_min) / (n - 1) if n > 1 else 0.0

    def chunk(self, i0: int, i1: int) -> np.ndarray:
        if self.given is not None:
            return self.given[i0:i1]
        y = np.arange(i0, i1, dtype=float)
        y *= self.step
        y += self.k_min
        if i1 == self.n:
            y[-1] = self.k_max
        return y

    def at(self, i: int) -> float:
        if self.given is not None:
            return float(self.given[i])
        return self.k_max if i == self.n - 1 else float(i) * self.step + self.k_min


@dataclass
class _Scanned:
    """What a scan of the wavenumbers keeps."""

    k: np.ndarray
    omega: np.ndarray
    cutoffs: list[float]
    bands: list[tuple[float, float]]
    best_g: float  # the largest growth rate on the grid (-inf: none)
    best_j: int  # its first index


def _scan(p: ModelParams, ks: _Wavenumbers, *, keep_all: bool, curve_points: int, chunk_size: int,
          max_seconds: float | None, param: str) -> _Scanned:
    """Solve the wavenumbers a chunk at a time, keeping the running maximum, the sign changes and a curve.

    The same as solving all at once: the roots are followed across chunk boundaries
    (:class:`~grainplug.stability.model._RootTracker`), the first largest growth rate wins, and a sign
    change between the last wavenumber of a chunk and the first of the next is a cut-off like any other.
    """
    n = ks.n
    tracker = _RootTracker()
    if keep_all:
        k_all = ks.given if ks.given is not None else np.empty(n)
        w_all = np.empty((n, 3), complex)
    pieces: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # the curve: (index, k, omega)
    cutoffs: list[float] = []
    starts: list[float] = []
    stops: list[float] = []
    best_g, best_j = -math.inf, -1
    best_row: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    prev: tuple[bool, float, np.ndarray] | None = None  # the previous chunk's last wavenumber: positive, k, roots

    def growth(x: float) -> float:
        return max_growth(p, x)

    t0 = time.perf_counter()
    for i0 in range(0, n, chunk_size):
        i1 = min(i0 + chunk_size, n)
        kc = ks.chunk(i0, i1)
        w = tracker.follow(_raw_roots(p, kc))
        g = w.imag.max(axis=1)
        pos = g > 0
        if i0 == 0 and pos[0]:
            starts.append(float(kc[0]))
        # sign changes: i and i + 1 on either side (i = i0 - 1: across the boundary with the previous chunk)
        edges = (np.nonzero(pos[1:] != pos[:-1])[0] + i0).tolist()
        if prev is not None and prev[0] != pos[0]:
            edges.insert(0, i0 - 1)
        if len(cutoffs) + len(edges) > MAX_CUTOFFS:
            raise ParameterError(
                f"the largest growth rate changes sign more than {MAX_CUTOFFS:,} times in the range: a root "
                "neutral to round-off, whose cut-offs would be noise — give fewer wavenumbers"
                + (" (n_k=)" if param == "n_k" else ""), param=param)
        for i in edges:
            a, b = ks.at(i), ks.at(i + 1)
            try:
                kcut = optimize.brentq(growth, a, b, xtol=1e-12)
            except ValueError:
                kcut = 0.5 * (a + b)
            cutoffs.append(float(kcut))
            (starts if pos[i + 1 - i0] else stops).append(float(kcut))
        j = int(np.argmax(g))
        if g[j] > best_g:  # strictly: the first of equal maxima, as np.argmax over all
            best_g, best_j = float(g[j]), i0 + j
            best_row = (np.array([i0 + j]), kc[j:j + 1].copy(), w[j:j + 1].copy())
        if keep_all:
            if ks.given is None:
                k_all[i0:i1] = kc
            w_all[i0:i1] = w
        else:
            keep = np.zeros(i1 - i0, bool)
            keep[_evenly_spread(n, curve_points, i0, i1) - i0] = True
            for i in edges:
                keep[i + 1 - i0] = True
                if i >= i0:
                    keep[i - i0] = True
                elif prev is not None:
                    pieces.append((np.array([i]), np.array([prev[1]]), prev[2][None, :]))
            where = np.nonzero(keep)[0]
            pieces.append((where + i0, kc[where], w[where]))
        prev = (bool(pos[-1]), float(kc[-1]), w[-1].copy())
        if i0 == 0 and i1 < n:
            _check_time(time.perf_counter() - t0, i1, n, max_seconds, param)
    assert prev is not None
    if prev[0]:
        stops.append(float(ks.at(n - 1)))
    if keep_all:
        k_out, w_out = k_all, w_all
    else:
        if best_row is not None:
            pieces.append(best_row)
        idx = np.concatenate([q[0] for q in pieces])
        _, first = np.unique(idx, return_index=True)  # sorted, each index once
        k_out = np.concatenate([q[1] for q in pieces])[first]
        w_out = np.concatenate([q[2] for q in pieces])[first]
    log.debug("stability: %d wavenumbers in %.3g s, %d kept", n, time.perf_counter() - t0, len(k_out))
    return _Scanned(k_out, w_out, cutoffs, list(zip(starts, stops, strict=False)), best_g, best_j)


def _evenly_spread(n: int, count: int, i0: int, i1: int) -> np.ndarray:
    """The indices in ``[i0, i1)`` of ``count`` evenly spread over ``n`` (``m (n - 1) // (count - 1)``, first and
    last included)."""
    span, parts = n - 1, count - 1
    m = np.arange(-((-i0 * parts) // span), -((-i1 * parts) // span), dtype=np.int64)  # i0 <= m span / parts < i1
    return m * span // parts


def _check_memory(n: int, *, keep_all: bool, curve_points: int, chunk_size: int, param: str) -> None:
    """Refuse, before allocating anything, a scan whose working arrays and results would not fit in memory."""
    kept = n if keep_all else curve_points + 2 * MAX_CUTOFFS + 1
    need = min(n, chunk_size) * WORK_BYTES_PER_K + min(n, kept) * ROW_BYTES
    free = free_memory_bytes()
    if need > MEMORY_SHARE * free:
        fix = ("keep a curve of them (max_points=, e.g. its default of 100000)" if keep_all else
               "solve fewer at a time (chunk_size=)")
        raise ParameterError(f"{n:,} wavenumbers need {_size(need)} of memory, more than the {_size(free)} free: "
                             f"{fix}", param=param)


def _check_time(elapsed: float, done: int, n: int, max_seconds: float | None, param: str) -> None:
    """Refuse a scan that the time of its first ``done`` wavenumbers says would take over ``max_seconds``."""
    estimate = elapsed / done * n
    log.info("stability: %d wavenumbers, about %s (%.2g µs each)", n, _duration(estimate), elapsed / done * 1e6)
    if max_seconds is not None and estimate > max_seconds:
        raise ParameterError(
            f"{n:,} wavenumbers would take about {_duration(estimate)} ({elapsed / done * 1e6:.2g} µs each, "
            f"measured on the first {done:,}), over the limit of {_duration(max_seconds)}: give fewer"
            + (" (n_k=; 10^7 resolve k* to 3e-7 over the default range)" if param == "n_k" else "")
            + ", or in Python lift the limit (max_seconds=None)", param=param)


def _size(nbytes: float) -> str:
    """``nbytes`` in words: 5.6 MB, 7.3 TB."""
    for unit, scale in (("PB", 1e15), ("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if nbytes >= scale:
            return f"{nbytes / scale:.3g} {unit}"
    return f"{nbytes:.0f} B"


def _duration(seconds: float) -> str:
    """``seconds`` in words: 40 s, 12 min, 3.1 h, 4.2 days, 3e+04 years."""
    for unit, scale, least in (("years", 3.156e7, 3.156e7), ("days", 86400.0, 2 * 86400.0), ("h", 3600.0, 3600.0),
                               ("min", 60.0, 120.0)):
        if seconds >= least:
            return f"{seconds / scale:.3g} {unit}"
    return f"{seconds:.2g} s"


def sweep(p: ModelParams, name: str, values: np.ndarray, *, max_seconds: float | None = MAX_SECONDS,
          on_estimate: Callable[[float], None] | None = None, **kwargs: float) -> list[dict[str, object]]:
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
    max_seconds : float or None
        Refuse a sweep estimated, from the time of its first value, to take longer
        (None: no limit); also each value's own limit (:func:`analyze_stability`). The estimate is
        made again on the values of the first seconds (the first one alone is a poor guide).
    on_estimate : callable, optional
        Called with the estimated duration of the whole sweep, seconds, each time it is estimated
        (a front end tells its user of a long one).
    **kwargs
        Passed to :func:`analyze_stability` (``k_min``, ``k_max``, ``n_k``...).

    Returns
    -------
    list of dict
        One row per value: the value, ``B1*``, the most unstable ``k*``, growth rate
        and ``lambda/D``, and the cut-offs with their ``lambda/D``.

    Raises
    ------
    ParameterError
        ``param="values"``: rows that would not fit in the free memory (checked before
        the first), or a sweep longer than ``max_seconds``.

    Notes
    -----
    Each value is one analysis with flat memory (:func:`analyze_stability`); only its
    row is kept.
    """
    if name not in {f.name for f in dataclasses.fields(ModelParams)}:
        raise ValueError(f"unknown input {name!r}")
    values = np.atleast_1d(np.asarray(values, float))
    check_sweep_size(values.size)
    rows = []
    t0 = time.perf_counter()
    checks = iter((0.0, SWEEP_RECHECK_S))  # estimated after the first value, then on the values of the first seconds
    next_check = next(checks)
    for i, v in enumerate(values):
        q = dataclasses.replace(p, **{name: float(v)})
        r = analyze_stability(q, max_seconds=max_seconds, **kwargs)
        elapsed = time.perf_counter() - t0
        if next_check is not None and elapsed >= next_check and i + 1 < values.size:
            next_check = next(checks, None)
            each = elapsed / (i + 1)
            estimate = each * values.size
            log.info("stability sweep: %d values, about %s", values.size, _duration(estimate))
            if max_seconds is not None and estimate > max_seconds:
                raise ParameterError(
                    f"{values.size:,} values would take about {_duration(estimate)} "
                    f"({_duration(each)} each, measured on the first {i + 1:,}), over the limit of "
                    f"{_duration(max_seconds)}: give fewer values or fewer wavenumbers (n_k=), or in Python lift "
                    "the limit (max_seconds=None)", param="values")
            if on_estimate is not None:
                on_estimate(estimate)
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


def check_sweep_size(n_values: int, *, param: str = "values") -> None:
    """Refuse, before anything is allocated, a sweep whose ``n_values`` rows would not fit in memory.

    Parameters
    ----------
    n_values : int
        Values the sweep would take.
    param : str
        The parameter named by the error (the command line's ``"sweep"``).

    Raises
    ------
    ParameterError
        When the rows (and a front end's table, figure and JSON of them, about
        4 kB a value) would take more than 80 % of the free memory.
    """
    need = float(n_values) * SWEEP_BYTES_PER_VALUE
    free = free_memory_bytes()
    if need > MEMORY_SHARE * free:
        raise ParameterError(f"{n_values:,} values would keep about {_size(need)} of results, more than the "
                             f"{_size(free)} free: give fewer values", param=param)
