"""The nonlinear state of a run, measured on the fields: waves, dense segments, fronts.

Notes
-----
A cell is *dense* when its compactness is above the midpoint of the final field's
range, ``(min c + max c) / 2``. A dense segment is a run of dense cells (joined
across the ends of a periodic box); its length runs between the points where the
compactness crosses that threshold, interpolated linearly between cell centres (a
count of cells would move in steps of one cell between grids). Its *front* is its downstream end, where the
compactness falls. Front speeds come from following each front between consecutive
outputs (the nearest front to its last position, unwrapped across a periodic box) over
the last quarter of the run, fitted by a straight line.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .state import INLET_CELLS, MIN_WAVE_RANGE_C, SimulationResult

__all__ = ["INLET_CELLS", "MIN_WAVE_RANGE_C", "WaveState", "segment_counts", "wave_state"]


@dataclass(frozen=True)
class WaveState:
    """The waves at the end of a run (lengths in ``D``, speeds in ``v_c``)."""

    n_waves: int
    dense_length_D: float
    dense_fraction: float
    wavelength_D: float
    front_speed: float
    threshold_c: float
    c_min: float
    c_max: float
    #: why there are no waves (empty when there are)
    why_none: str = ""

    def as_dict(self, *, D_mm: float, v_c_m_s: float) -> dict[str, float | int | str]:
        return {"n_waves": self.n_waves, "dense_length_D": self.dense_length_D, "dense_fraction": self.dense_fraction,
                "wavelength_D": self.wavelength_D, "front_speed_v_c": self.front_speed,
                "dense_length_mm": self.dense_length_D * D_mm, "wavelength_mm": self.wavelength_D * D_mm,
                "front_speed_m_s": self.front_speed * v_c_m_s, "threshold_c": self.threshold_c,
                "c_min": self.c_min, "c_max": self.c_max, "why_none": self.why_none}


def _segments(dense: np.ndarray, periodic: bool) -> list[tuple[int, int]]:
    """(start, end) cell indices of runs of True, end exclusive; a run across a periodic edge ends past n."""
    n = len(dense)
    if not dense.any():
        return []
    if dense.all():
        return [(0, n)]
    d = dense.astype(np.int8)
    if periodic:
        k = int(np.argmin(dense))  # start the scan on a light cell
        d = np.roll(d, -k)
    else:
        k = 0
    edges = np.diff(np.concatenate([[0], d, [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return [(int(s) + k, int(e) + k) for s, e in zip(starts, ends, strict=True)]


def _length(c: np.ndarray, start: int, end: int, thr: float, periodic: bool) -> float:
    """Length (in cells) of the dense run ``start .. end - 1``, from where ``c`` rises through ``thr`` to where
    it falls through it, both interpolated between cell centres; a run that reaches an end of an open pipe
    is measured from that end."""
    n = len(c)
    if end - start >= n:
        return float(n)
    # positions in cell widths from the upstream face of cell 0 (cell i's centre is at i + 0.5)
    if periodic or start > 0:
        a, b = c[(start - 1) % n], c[start % n]
        lo = start + 0.5 - (b - thr) / max(b - a, 1e-300)
    else:
        lo = 0.0
    if periodic or end < n:
        a, b = c[(end - 1) % n], c[end % n]
        hi = end - 0.5 + (a - thr) / max(a - b, 1e-300)
    else:
        hi = float(n)
    return hi - lo


def _waves(segs: list[tuple[int, int]], periodic: bool) -> list[tuple[int, int]]:
    """The dense runs that are waves: in an open pipe, not a run of the first :data:`INLET_CELLS` cells alone (the
    fed cell)."""
    return segs if periodic else [(s, e) for s, e in segs if not (s == 0 and e <= INLET_CELLS)]


def _fronts(c: np.ndarray, thr: float, dx: float, periodic: bool) -> np.ndarray:
    """Positions (units of D) where ``c`` falls through ``thr`` going downstream (in an open pipe, not the fed
    cells' own edge at the inlet)."""
    nxt = np.roll(c, -1) if periodic else np.concatenate([c[1:], c[-1:]])
    i = np.flatnonzero((c > thr) & (nxt <= thr))
    if not periodic:
        i = i[i >= INLET_CELLS]
    frac = (c[i] - thr) / np.maximum(c[i] - nxt[i], 1e-300)
    return (i + 0.5 + frac) * dx




def wave_state(res: SimulationResult) -> WaveState:
    """The dense segments at the end of the run and the speed of their fronts (none below
    :data:`MIN_WAVE_RANGE_C` of compactness range, nor an open pipe's inlet cells alone)."""
    c_end = res.c[-1]
    periodic = res.params.boundary == "periodic"
    lo, hi = float(c_end.min()), float(c_end.max())
    thr = 0.5 * (lo + hi)
    dx, L = res.params.dx, res.params.length_D
    if hi - lo < MIN_WAVE_RANGE_C:
        return WaveState(0, 0.0, 0.0, float("nan"), float("nan"), thr, lo, hi,
                         f"c stays within {lo:.4f}..{hi:.4f}, a range under {MIN_WAVE_RANGE_C:g}: the base flow, "
                         "with small ripples at most")
    segs = _waves(_segments(c_end > thr, periodic), periodic)
    if not segs:
        return WaveState(0, 0.0, 0.0, float("nan"), float("nan"), thr, lo, hi,
                         f"only the fed cells at the inlet are dense (c {lo:.3f}..{hi:.3f})")
    lengths = np.array([_length(c_end, s, e, thr, periodic) for s, e in segs]) * dx
    n = len(segs)
    # fronts: the downstream end of each dense segment, where c falls through the threshold
    # (interpolated between cells), followed over the last quarter and fitted by a line
    j0 = max(1, int(0.75 * len(res.time)))
    t_track, z_track = [], []
    z_now = None
    for j in range(j0 - 1, len(res.time)):
        fronts = _fronts(res.c[j], thr, dx, periodic)
        if not len(fronts):
            continue
        if z_now is None:
            z_now = float(fronts[0])
        else:
            dz = (fronts - z_now % L + 0.5 * L) % L - 0.5 * L if periodic else fronts - z_now
            z_now += float(dz[int(np.argmin(np.abs(dz)))])
        t_track.append(res.time[j])
        z_track.append(z_now)
    speed = float(np.polyfit(t_track, z_track, 1)[0]) if len(t_track) >= 3 else float("nan")
    return WaveState(n_waves=n, dense_length_D=float(lengths.mean()), dense_fraction=float(lengths.sum() / L),
                     wavelength_D=L / n if periodic and n else float("nan"),
                     front_speed=speed, threshold_c=thr,
                     c_min=lo, c_max=hi)


def segment_counts(res: SimulationResult, *, threshold: float | None = None) -> np.ndarray:
    """Number of dense segments (``c`` above ``threshold``, default halfway between min and max) at each output;
    none while the final range is under :data:`MIN_WAVE_RANGE_C`, and not an open pipe's fed inlet cells alone
    (:data:`INLET_CELLS`), as :func:`~grainplug.simulation.waves.wave_state` counts them."""
    c = res.c
    lo, hi = float(c[-1].min()), float(c[-1].max())
    if hi - lo < MIN_WAVE_RANGE_C:
        return np.zeros(len(c), int)
    thr = 0.5 * (lo + hi) if threshold is None else threshold
    dense = c > thr
    if res.params.boundary == "periodic":
        starts = dense & ~np.roll(dense, 1, axis=1)
    else:
        starts = dense & ~np.concatenate([np.zeros((len(c), 1), bool), dense[:, :-1]], axis=1)
        starts[:, 0] &= dense[:, : INLET_CELLS + 1].all(axis=1)  # the fed cells alone are no segment
    return starts.sum(axis=1)
