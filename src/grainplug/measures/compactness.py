"""The grains' compactness along the tube, from the light they let through (Beer–Lambert).

Notes
-----
In back light, a chord of length ``L`` through grains of compactness ``c`` passes a share
``exp(-kappa c L)`` of the light that the empty tube passes, ``kappa`` a property of the grains (their
size, their glass, the light's colour). With two references taken with the same camera and lamp,

- the tube **empty**, ``E(s)`` along it (the ``background`` picture), and
- the tube **packed** with still grains at a known compactness ``c_p`` (0.60 by default: glass beads
  poured and settled), ``P(s)``,

the diagram's level ``D(s, t)`` gives ``c(s, t)`` without knowing ``kappa``: at each position the packed
reference fixes ``kappa D`` (the bore's optical depth at compactness 1), and the diagram's level is then
read as the compactness that makes that light.

*Chord-averaged.* The diagram averages the light over the band's core (the middle of the bore), where
the chords differ in length; the compactness read, ``c = c_p ln(D/E) / ln(P/E)``, is the mean over those
chords. Averaging the light before its logarithm would bias it if the chords differed much: a model of
the core's chords (``D sqrt(1 - x^2)``, ``|x| <= 0.7``) read through the averaged light differs from the
plain logarithm by less than 0.001 in compactness for ``P/E`` from 0.08 to 0.5 (tests/compactness_render.py),
so the plain logarithm is used.

What it assumes, and where it fails: the light is absorbed or scattered out of the camera's view in
proportion to the grains crossed (Beer–Lambert), which holds for beads much smaller than the bore seen
in back light; it does not hold in front light (the light comes back from the grains: nothing is
measured), and a lamp whose level changed between the references and the movie shifts every value (the
pipeline scales the references to the movie's lamp by the background beside the tube).

The plugs' and the bubbles' compactness (:func:`phase_compactness`) are means over their insides, the
edges' blur left out: one value per plug track and per bubble (the pair of tracks bounding it), then the
mean over them with a 95 % interval: Student's over them, and the light model's own error
(:data:`LIGHT_MODEL_HALF_WIDTH`) in quadrature. The interval is that of the measurement at the ``c_p``
given: every compactness scales with ``c_p``, whose own uncertainty (0.60-0.64 for settled glass beads)
is the user's to add.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..band import Band
from ..diagram import Diagram
from ..diagram.extract import Probes
from ..errors import ParameterError
from ..plugs import Runs, Tracks
from ..warning_codes import coded

#: the compactness of grains poured into a tube and left to settle (glass beads: random loose to close packing)
PACKED_COMPACTNESS = 0.60
#: the light model's own error (95 % half-width) added to the intervals in quadrature: Beer–Lambert read through
#: light averaged over grains of varying compactness is biased by up to this much on independent renders
#: (tests/compactness_render.py, textures of +-15-30 %; docs/accuracy.md) — a type B term, not a fit
LIGHT_MODEL_HALF_WIDTH = 0.01
#: the packed reference must let through at most this share of the empty one's light (below it, the
#: contrast between grains and air is too weak to read a compactness)
MAX_PACKED_SHARE = 0.9

@dataclass(frozen=True)
class PhaseCompactness:
    """The plugs' and the bubbles' compactness.

    Attributes
    ----------
    plug, bubble : float or None
        Means over the plug tracks and over the bubbles measured (None when none was).
    plug_ci95, bubble_ci95 : tuple of float or None
        Student's 95 % intervals over them (None with fewer than two).
    n_plugs, n_bubbles : int
        How many plug tracks and bubbles were measured.
    per_track : dict
        Each plug track's mean compactness.
    """

    plug: float | None
    plug_ci95: tuple[float, float] | None
    n_plugs: int
    bubble: float | None
    bubble_ci95: tuple[float, float] | None
    n_bubbles: int
    per_track: dict[int, float] = field(default_factory=dict)


@dataclass(frozen=True)
class References:
    """The empty and packed references, put in the diagram's units.

    Attributes
    ----------
    empty_level : float
        The empty tube's light in the flat-fielded diagram's units (the same at every position: the
        flat field divided the empty tube's profile out).
    packed_share : ndarray
        The packed tube's light over the empty tube's, along the tube (the diagram's positions as read).
    lamp_ratio_empty, lamp_ratio_packed : float or None
        The movie's lamp over each reference's, from the background beside the tube (None: not seen, and
        taken as equal).
    """

    empty_level: float
    packed_share: np.ndarray = field(repr=False)
    lamp_ratio_empty: float | None = None
    lamp_ratio_packed: float | None = None


def _lamp(beside: np.ndarray) -> float | None:
    b = np.asarray(beside, np.float64)
    b = b[np.isfinite(b)]
    level = float(np.median(b)) if b.size else float("nan")
    return level if level > 0 else None


def references(empty_core: np.ndarray, packed_core: np.ndarray, *, empty_beside: np.ndarray,
               packed_beside: np.ndarray, movie_beside: np.ndarray) -> References:
    """The references in the units of a diagram flat-fielded by the empty one (see module notes).

    Parameters
    ----------
    empty_core, packed_core : ndarray, (n_positions,)
        The band's core level along the tube in each reference.
    empty_beside, packed_beside, movie_beside : ndarray
        The background beside the tube in each reference and over the movie (its lamp's level): each reference
        is scaled to the movie's lamp; where one is not seen, the lamps are taken as equal.
    """
    e = np.asarray(empty_core, np.float64)
    p = np.asarray(packed_core, np.float64)
    movie = _lamp(movie_beside)
    le, lp = _lamp(empty_beside), _lamp(packed_beside)
    re = movie / le if movie and le else None
    rp = movie / lp if movie and lp else None
    scale_e, scale_p = (re, rp) if re and rp else (1.0, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        share = np.where(e > 0, p * scale_p / (e * scale_e), np.nan)
    lit = e[e > 0]
    median_e = float(np.median(lit)) if lit.size else float("nan")
    return References(median_e * scale_e, share, re, rp)


def compactness_field(values: np.ndarray, empty: np.ndarray, packed: np.ndarray, *,
                      packed_compactness: float = PACKED_COMPACTNESS) -> np.ndarray:
    """The compactness ``c(t, s)`` of a diagram's contents (see module notes).

    Parameters
    ----------
    values : ndarray, (n_frames, n_positions)
        The diagram's light (the band's mean level, the lamp's changes divided out).
    empty, packed : ndarray, (n_positions,)
        The same band's level in the references: the tube empty, and packed at ``packed_compactness``.
    packed_compactness : float
        The packed reference's compactness.

    Returns
    -------
    ndarray, float32
        Compactness; positions where the references are not lit, or not darker packed than empty, are NaN.

    Raises
    ------
    ValueError
        When the packed reference is not darker than the empty one along most of the tube (swapped, or the
        same picture twice).
    """
    if not 0.0 < packed_compactness < 1.0:
        raise ValueError(f"the packed compactness must be between 0 and 1, got {packed_compactness:g}")
    e = np.asarray(empty, np.float64)
    p = np.asarray(packed, np.float64)
    lit = (e > 0) & (p > 0)
    share = np.where(lit, p / np.where(e > 0, e, 1.0), np.nan)
    usable = lit & (share < MAX_PACKED_SHARE)
    if not usable.mean() > 0.5:
        typical = float(np.nanmedian(share)) if np.isfinite(share).any() else float("nan")
        raise ValueError(f"the packed reference lets through {typical:.0%} of the empty one's light along the "
                         f"tube (it must be darker, below {MAX_PACKED_SHARE:.0%}): are the two swapped, or the same?")
    depth = np.where(usable, np.log(np.where(usable, share, 0.5)), np.nan)  # ln(P/E) < 0
    t = np.asarray(values, np.float64) / np.where(e > 0, e, 1.0)[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        c = packed_compactness * np.log(np.where(t > 0, t, np.nan)) / depth[None, :]
    return c.astype(np.float32)


def _student(values: np.ndarray) -> tuple[float | None, tuple[float, float] | None]:
    """The mean and its 95 % interval: Student's over the values, and the light model's error."""
    from .._filters import t_quantile_975
    if values.size == 0:
        return None, None
    m = float(np.mean(values))
    if values.size < 2:
        return m, None
    half = t_quantile_975(values.size - 1) * float(np.std(values, ddof=1)) / np.sqrt(values.size)
    half = float(np.hypot(half, LIGHT_MODEL_HALF_WIDTH))
    return m, (m - half, m + half)


def phase_compactness(field: np.ndarray, runs: Runs, tracks: Tracks, *, margin_samples: int = 2,
                      min_frames: int = 3) -> PhaseCompactness:
    """The plugs' and the bubbles' mean compactness (see module notes).

    Parameters
    ----------
    field : ndarray, (n_frames, n_positions)
        :func:`compactness_field`'s output, positions increasing downstream as the runs'.
    runs, tracks : Runs, Tracks
        The plugs found in each frame and their tracks.
    margin_samples : int
        Samples left out inside each edge (its blur).
    min_frames : int
        Frames a plug track or a bubble must be measured in.
    """
    n_pos = field.shape[1]
    csum = np.concatenate([np.zeros((field.shape[0], 1)), np.nancumsum(field, axis=1, dtype=np.float64)], axis=1)
    ccount = np.concatenate([np.zeros((field.shape[0], 1)),
                             np.cumsum(np.isfinite(field), axis=1, dtype=np.int64)], axis=1)

    def inside(frame: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        lo = np.clip(lo + margin_samples, 0, n_pos)
        hi = np.clip(hi - margin_samples, 0, n_pos)
        ok = hi > lo
        s = np.where(ok, csum[frame, hi] - csum[frame, np.minimum(lo, hi)], 0.0)
        k = np.where(ok, ccount[frame, hi] - ccount[frame, np.minimum(lo, hi)], 0)
        return np.where(k > 0, s / np.maximum(k, 1), np.nan)

    whole = np.isfinite(runs.top_mm) & np.isfinite(runs.bottom_mm)
    plug_mean = inside(runs.frame, runs.start, runs.stop)
    per_track: dict[int, float] = {}
    for tid in range(len(tracks)):
        if tracks.composite(tid):
            continue
        v = plug_mean[whole & (tracks.run_track == tid)]
        v = v[np.isfinite(v)]
        if v.size >= min_frames:
            per_track[tid] = float(np.mean(v))
    plug, plug_ci = _student(np.asarray(list(per_track.values()), float))
    # bubbles: between one plug's downstream edge and the next one's upstream edge in the same frame
    u = np.nonzero(runs.frame[1:] == runs.frame[:-1])[0]
    d = u + 1
    ok = np.isfinite(runs.bottom_mm[u]) & np.isfinite(runs.top_mm[d])
    u, d = u[ok], d[ok]
    bubbles: list[float] = []
    if u.size:
        gap = inside(runs.frame[u], runs.stop[u], runs.start[d])
        pair = tracks.run_track[u].astype(np.int64) * (len(tracks) + 1) + tracks.run_track[d]
        for key in np.unique(pair):
            v = gap[(pair == key) & np.isfinite(gap)]
            if v.size >= min_frames:
                bubbles.append(float(np.mean(v)))
    bubble, bubble_ci = _student(np.asarray(bubbles, float))
    return PhaseCompactness(plug, plug_ci, len(per_track), bubble, bubble_ci, len(bubbles), per_track)


@dataclass(frozen=True)
class ReferenceReads:
    """The references' band read like the movie's (:func:`reference_reads`): core and beside of each."""

    empty_core: np.ndarray = field(repr=False)
    packed_core: np.ndarray = field(repr=False)
    empty_beside: np.ndarray = field(repr=False)
    packed_beside: np.ndarray = field(repr=False)
    packed_compactness: float = PACKED_COMPACTNESS


def reference_reads(band: Band, probes: Probes, empty: np.ndarray, packed: np.ndarray, *,
                    packed_compactness: float = PACKED_COMPACTNESS) -> ReferenceReads:
    """The empty and packed pictures read through the movie's band (``band``, ``probes``: what
    :func:`grainplug.diagram.extract.probes_along_tube` gives), checked before the movie is read.

    Raises
    ------
    ParameterError
        When the packed picture is not darker than the empty one along the tube.
    """
    def read(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        core, _, beside, _ = probes.split(band.profile(np.asarray(image, np.float32))[None, :])
        return np.asarray(core[0], np.float64), np.asarray(beside[0] if beside.size else beside.ravel(), np.float64)

    e_core, e_beside = read(empty)
    p_core, p_beside = read(packed)
    with np.errstate(divide="ignore", invalid="ignore"):
        share = np.where(e_core > 0, p_core / e_core, np.nan)
    if not np.mean(share < MAX_PACKED_SHARE) > 0.5:
        typical = float(np.nanmedian(share)) if np.isfinite(share).any() else float("nan")
        raise ParameterError(f"the packed picture lets through {typical:.0%} of the empty tube's light along the "
                             f"tube (it must be darker, below {MAX_PACKED_SHARE:.0%}): give the tube packed with "
                             "grains as packed= and the empty tube as background= — are the two swapped, or the "
                             "same?", param="packed")
    return ReferenceReads(e_core, p_core, e_beside, p_beside, packed_compactness)


@dataclass(frozen=True)
class GrainContents:
    """What the analysis says of the grains' compactness: the phases' figures, the field, and why not."""

    phases: PhaseCompactness | None = None
    field: np.ndarray | None = None
    note: str = ""
    warnings: tuple[str, ...] = ()


#: what the summary says when no references were given
NO_REFERENCES = ("not measured: give the tube empty (background=, --background) and packed with still grains "
                 "(packed=, --packed) to read it from the light")


def grain_contents(diagram: Diagram, reads: ReferenceReads | None, movie_beside: np.ndarray | None,
                   runs: Runs, tracks: Tracks, *, given: bool, back_lit: bool | None, backwards: bool,
                   resample_at: np.ndarray | None = None) -> GrainContents:
    """The compactness of the diagram's contents and of its plugs and bubbles, or why it is not measured.

    Parameters
    ----------
    diagram : Diagram
        The analysis' diagram (flat-fielded by the empty reference, the lamp's changes divided out, turned to the
        flow's direction).
    reads : ReferenceReads or None
        The references read through the band (None: not given, or not read in front light).
    movie_beside : ndarray or None
        The background beside the tube over the movie (its lamp's level).
    runs, tracks : Runs, Tracks
        The plugs found and their tracks.
    given : bool
        Whether references were given.
    back_lit : bool or None
        Whether the tube is seen in back light (in front light the light does not cross the grains).
    backwards : bool
        The diagram was turned (positions run against the read's).
    resample_at : ndarray, optional
        The fractional samples the diagram was resampled at (a lens's distortion), or None.
    """
    if not given:
        return GrainContents(note=NO_REFERENCES)
    if reads is None or not back_lit:
        why = ("not measured: the tube is seen in front light, where the light comes back from the grains instead "
               "of crossing them")
        return GrainContents(note=why, warnings=(coded(
            "compactness.unmeasured", f"the compactness was {why} — film in back light (a lamp behind the tube) to "
            "read it"),))
    refs = references(reads.empty_core, reads.packed_core, empty_beside=reads.empty_beside,
                      packed_beside=reads.packed_beside,
                      movie_beside=np.zeros(0) if movie_beside is None else movie_beside)
    share = refs.packed_share
    if resample_at is not None:
        share = np.interp(resample_at, np.arange(share.size), share)
    if backwards:
        share = share[::-1]
    empty = np.full(share.shape, refs.empty_level)
    c = compactness_field(diagram.values, empty, share * refs.empty_level,
                          packed_compactness=reads.packed_compactness)
    phases = phase_compactness(c, runs, tracks)
    warnings: tuple[str, ...] = ()
    if refs.lamp_ratio_empty is None or refs.lamp_ratio_packed is None:
        warnings = (coded("compactness.lamp_unknown",
            "the compactness takes the lamp as bright in the movie as in the empty and packed pictures: the "
            "background beside the tube was not seen in all three to compare them — keep the lamp and the "
            "exposure unchanged between them"),)
    return GrainContents(phases, c, "", warnings)
