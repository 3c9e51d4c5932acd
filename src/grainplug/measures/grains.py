"""Grains falling through the bubbles: their speed, and from its sign the flow direction.

Notes
-----
Between plugs, grains fall freely (the paper measures about 0.8 m/s against 0.9 m/s for free
fall over a bubble). In the diagram they are small specks in the bubbles that move far between
frames, in the direction of the flow, much faster than the plugs. Their displacement is the peak
of the cross-correlation of the bubble specks of frames a lag apart, summed over the record
(computed with FFTs). The lag is the fewest frames over which the slowest speed looked for,
``min_speed_m_s``, moves the grains at least two samples: one frame at the usual 250-500 fps,
several at thousands of frames per second, where grains move less than two pixels per frame and
could not be told from the plug edges. Plug edges are kept out by eroding the bubbles and by
looking only at speeds above ``min_speed_m_s``.

The peak is accepted when it stands above the correlation's spread over all shifts (robust
z-score of at least ``min_score``) and clearly above the best peak of the opposite sign.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: frame pairs correlated at once
PAIRS_PER_BLOCK = 64

#: the fewest samples the slowest grains looked for move over the lag (fewer is a plug edge's motion)
MIN_SHIFT_SAMPLES = 2


@dataclass(frozen=True)
class GrainMotion:
    """Speed of the grains falling through the bubbles.

    Attributes
    ----------
    speed_m_s : float or None
        Signed speed along increasing positions (positive: the assumed flow direction);
        None when no clear motion was found.
    score : float
        Robust z-score of the correlation peak.
    opposite_ratio : float
        Peak height over the best peak of the other sign.
    lag_frames : int
        Frames between the correlated pairs.
    seen : str
        What was and was not seen, in words (why there is no speed, when there is none).
    """

    speed_m_s: float | None
    score: float
    opposite_ratio: float
    lag_frames: int = 1
    seen: str = ""


def falling_grains(z: np.ndarray, *, mm_per_sample: float, fps: float, min_speed_m_s: float = 0.25,
                   max_speed_m_s: float = 4.0, min_score: float = 8.0, max_pairs: int = 600,
                   unseen: np.ndarray | None = None) -> GrainMotion:
    """Speed of the specks moving through the bubbles of the contrast diagram ``z``.

    The cross-correlation of frames ``lag`` apart is summed over every such pair, or over
    ``max_pairs`` pairs spread over a record longer than ``2 max_pairs`` frames
    (enough for a clear peak; a long record adds time and memory, not information).
    The lag is the fewest frames over which ``min_speed_m_s`` moves at least
    :data:`MIN_SHIFT_SAMPLES` samples (one frame at 250-500 fps and 0.1-0.2 mm per sample).
    A pair with a frame of ``unseen`` (indices of frames bridged by interpolation:
    :func:`grainplug.diagram.frames.repair_frames`) is left out: an interpolated frame holds
    the specks of both its neighbours, half-bright, and its pairs correlate at shifts no grain made.
    """
    from .._filters import minimum_filter1d, uniform_filter1d
    n_t, n_s = z.shape
    step_mm = 1000.0 / fps  # mm per frame at 1 m/s
    lag = max(1, int(np.ceil(MIN_SHIFT_SAMPLES * mm_per_sample / (min_speed_m_s * step_mm) - 1e-9)))
    apart = "consecutive frames" if lag == 1 else f"frames {lag} apart"
    if n_s < 16:
        return GrainMotion(None, 0.0, 0.0, lag, "the view along the tube is too short to follow grains")
    if n_t < lag + 2:
        return GrainMotion(None, 0.0, 0.0, lag, f"the record is too short to follow grains over {apart}")
    seen = np.ones(n_t, bool)
    if unseen is not None and len(unseen):
        seen[np.asarray(unseen, int)] = False
    both = np.flatnonzero(seen[:-lag] & seen[lag:])  # pairs of frames both seen
    if len(both) <= 2 * max_pairs:  # every pair
        firsts = both
    else:  # pairs spread over the record
        firsts = both[np.unique(np.linspace(0, len(both) - 1, max_pairs).round().astype(int))]
    if len(firsts) < 2:
        return GrainMotion(None, 0.0, 0.0, lag, f"fewer than two pairs of {apart} were both seen")
    n_fft = 1 << int(np.ceil(np.log2(2 * n_s)))
    acc = np.zeros(n_fft // 2 + 1, complex)
    n_bubble = n_seen = 0
    for lo in range(0, len(firsts), PAIRS_PER_BLOCK):  # in blocks: memory bounded by the block
        first = firsts[lo: lo + PAIRS_PER_BLOCK]
        rows = np.union1d(first, first + lag)
        zz = z[rows]
        # erosion along the tube by 7 samples (binary_erosion's, border 0, as a running minimum)
        bubble = minimum_filter1d((zz < 0.35).view(np.uint8), 7, axis=1).view(bool)
        n_bubble += int(bubble.sum())
        n_seen += bubble.size
        x = np.where(bubble, zz, 0.0).astype(np.float32)
        # specks: what stands out of the bubble's own level along the tube
        x -= np.where(bubble, uniform_filter1d(x, 15, axis=1), 0.0)
        x = np.where(bubble, x, 0.0)
        spec = np.fft.rfft(x, n_fft, axis=1)
        acc += (np.conj(spec[np.searchsorted(rows, first)]) * spec[np.searchsorted(rows, first + lag)]).sum(axis=0)
    if n_bubble < 0.05 * n_seen:
        return GrainMotion(None, 0.0, 0.0, lag, "no bubbles to see grains fall through (air in under 5 % of the "
                                                "tube's length over the record)")
    cross = np.fft.irfft(acc, n_fft)
    shifts = np.fft.fftfreq(n_fft, 1.0 / n_fft).astype(int)  # shift d: row k at s -> row k+lag at s+d
    lo = max(MIN_SHIFT_SAMPLES, int(np.ceil(min_speed_m_s * lag * step_mm / mm_per_sample)))
    hi = min(n_s // 2, int(max_speed_m_s * lag * step_mm / mm_per_sample))
    if hi <= lo:
        return GrainMotion(None, 0.0, 0.0, lag, "the view along the tube is too short for grains falling at "
                                                f"{min_speed_m_s:g}-{max_speed_m_s:g} m/s over {apart}")
    sel = (np.abs(shifts) >= lo) & (np.abs(shifts) <= hi)
    c, d = cross[sel], shifts[sel]
    med = float(np.median(c))
    spread = 1.4826 * float(np.median(np.abs(c - med))) + 1e-12
    pos, neg = d > 0, d < 0
    best_pos = float(c[pos].max()) if pos.any() else -np.inf
    best_neg = float(c[neg].max()) if neg.any() else -np.inf
    sign_pos = best_pos >= best_neg
    best, other = (best_pos, best_neg) if sign_pos else (best_neg, best_pos)
    score = (best - med) / spread
    ratio = (best - med) / max(other - med, 1e-12)
    if score < min_score or ratio < 1.5:
        why = (f"the specks in the bubbles ({100.0 * n_bubble / n_seen:.0f} % of the tube) show no clear motion "
               f"between {apart} (peak {score:.1f} robust sd above the rest, needed {min_score:g}"
               + (")" if score < min_score else f"; {ratio:.2f}x the other way's, needed 1.5)"))
        return GrainMotion(None, float(score), float(ratio), lag, why)
    k = int(np.argmax(np.where(pos if sign_pos else neg, c, -np.inf)))
    # parabolic refinement of the peak
    i = np.nonzero(shifts == d[k])[0][0]
    a, b0, cc = cross[i - 1], cross[i], cross[(i + 1) % n_fft]
    den = a - 2 * b0 + cc
    off = 0.5 * (a - cc) / den if den != 0 else 0.0
    shift = d[k] + float(np.clip(off, -0.5, 0.5))
    speed = float(shift * mm_per_sample * fps / 1000.0 / lag)
    return GrainMotion(speed, float(score), float(ratio), lag, f"grains falling at {abs(speed):.2f} m/s "
                                                                 f"between {apart}")
