"""Synthetic plug-flow movies with known ground truth.

:func:`synthesize` renders a movie from a :class:`SynthConfig`, writes it in
any format grainplug reads and writes the truth beside it (``truth.json`` and
``truth_edges.csv``). Same seed, same bytes. These movies are the ground truth
of every image-analysis test.
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._version import __version__
from ..errors import ParameterError
from ..jsonio import write_json
from .kinematics import REGIMES, displacement_mm
from .render import FLOW_DIRECTIONS, Renderer, SynthConfig
from .writers import FORMATS, MovieWriter, movie_path, require_writer

#: frames a plug must be wholly in view, apart from its neighbours, to count in the
#: truth's mean length
MIN_FULL_FRAMES = 5


@dataclass(frozen=True)
class SynthResult:
    """What :func:`synthesize` wrote."""

    movie: Path
    truth_json: Path
    truth_edges_csv: Path
    truth: dict


def flow_axis_angle_deg(config: SynthConfig) -> float:
    """Angle of the flow direction in the written image, degrees from +x towards +y (y down)."""
    a = np.radians(config.tilt_deg)
    ex, ey = np.sin(a), np.cos(a)  # canonical view, flow downward
    d = config.flow_direction
    if d == "up":
        ex, ey = ex, -ey
    elif d == "right":
        ex, ey = ey, ex
    elif d == "left":
        ex, ey = -ey, ex
    return float(np.degrees(np.arctan2(ey, ex)))


def compute_truth(renderer: Renderer) -> tuple[dict, list[tuple]]:
    """Summary truth and per-frame plug edges of a rendered movie."""
    cfg = renderer.cfg
    view = cfg.view_length_mm
    rows: list[tuple] = []
    full_count = np.zeros(len(renderer.train), dtype=int)
    n_gap = max(len(renderer.train) - 1, 0)
    gap_samples: list[list[float]] = [[] for _ in range(n_gap)]
    if cfg.regime != "none":
        for k in range(cfg.n_frames):
            tops, bots = renderer.plug_edges_mm(k)
            vis = np.nonzero((bots > 0) & (tops < view))[0]
            for i in vis:
                rows.append((k, k / cfg.fps, int(i), float(tops[i]), float(bots[i])))
            # whole in view and apart from its neighbours (a plug merged with another is
            # not seen as itself)
            apart = np.ones(len(tops), bool)
            apart[1:] &= tops[1:] > bots[:-1]
            apart[:-1] &= bots[:-1] < tops[1:]
            full_count += (tops >= 0) & (bots <= view) & apart
            if n_gap:
                whole = (bots[:-1] >= 0) & (tops[1:] <= view) & (tops[1:] > bots[:-1])
                for g in np.nonzero(whole)[0]:
                    gap_samples[g].append(float(tops[g + 1] - bots[g]))
    lengths = renderer.train.length_mm
    full = full_count >= MIN_FULL_FRAMES
    # a bubble's length is the median of its actual length over the frames it is wholly in
    # view (merging plugs change it); plugs keep their length
    gaps = np.asarray([np.median(g) for g in gap_samples if len(g) >= MIN_FULL_FRAMES])
    has_plugs = cfg.regime != "none"
    oscillating = cfg.regime in ("oscillating", "stick-slip")
    times = np.arange(cfg.n_frames) / cfg.fps
    disp = renderer.displacement_mm(times)
    detrended = disp - cfg.celerity_m_s * 1000 * times
    truth = {
        "grainplug_version": __version__,
        "config": cfg.as_dict(),
        "has_plugs": has_plugs,
        "regime": ("oscillating" if oscillating else "propagative") if has_plugs else "none",
        "motion": cfg.regime,
        "celerity_m_s": cfg.celerity_m_s if has_plugs else None,
        "plug_length_mm": float(np.mean(lengths[full])) if has_plugs and full.any() else None,
        "plug_lengths_mm": [float(x) for x in lengths[full]] if has_plugs else [],
        "bubble_length_mm": float(np.mean(gaps)) if has_plugs and gaps.size else None,
        "oscillation_frequency_hz": cfg.frequency_hz if has_plugs and oscillating else None,
        "oscillation_amplitude_mm": float(np.ptp(detrended) / 2) if has_plugs and oscillating else None,
        "n_plugs_seen": int(np.count_nonzero(full_count > 0)) if has_plugs else 0,
        "mm_per_px": cfg.mm_per_px,
        "tube_diameter_mm": cfg.tube_diameter_mm,
        "tube_diameter_px": cfg.tube_diameter_mm / cfg.mm_per_px,
        "tube_axis_angle_deg": flow_axis_angle_deg(cfg),
        "view_length_mm": view,
        "fps": cfg.fps,
        "n_frames": cfg.n_frames,
        "conventions": "positions in mm along the tube from the top (upstream end) of the view, "
                       "increasing with the flow; celerity positive downstream",
    }
    return truth, rows


def synthesize(config: SynthConfig, out_dir: str | Path, *, fmt: str = "tiff",
               stem: str = "movie") -> SynthResult:
    """Render ``config`` into ``out_dir`` as a movie of format ``fmt``, with its truth.

    Parameters
    ----------
    config : SynthConfig
        What to render.
    out_dir : str or Path
        Folder that receives the movie, ``truth.json`` and ``truth_edges.csv``.
    fmt : str
        One of :data:`FORMATS` (``tiff``, ``png``, ``avi``, ``ffv1``, ``h264`` ...).
    stem : str
        Name of the movie file (or folder, for image formats) without its extension.

    Returns
    -------
    SynthResult
        Paths written and the truth dictionary.
    """
    if fmt not in FORMATS:
        raise ParameterError(f"unknown format {fmt!r}: use one of {', '.join(FORMATS)}", param="fmt")
    require_writer(fmt)  # before anything is written
    from .._atomic import OutputPlaceError, check_output_place

    out = check_output_place(out_dir, replace=False)  # a file, a loop of links: refused before anything is written
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputPlaceError(f"cannot create {out}: {exc.strerror or exc} — choose another output folder") from None
    renderer = Renderer(config)
    path = movie_path(out, fmt, stem)
    meta = {"software": f"grainplug {__version__} synthetic", "seed": config.seed}
    tmp = path.with_name(path.name + ".part" + (path.suffix if path.suffix else ""))
    try:
        with MovieWriter(tmp, fmt, fps=config.fps, metadata=meta, n_frames=config.n_frames) as writer:
            for frame in renderer.frames():
                writer.write(frame)
    except BaseException:
        if created and not any(out.iterdir()):  # a writer's refusal leaves no empty folder behind
            out.rmdir()
        raise
    _move_into_place(tmp, path, fmt)
    truth, rows = compute_truth(renderer)
    truth["movie"] = path.name
    truth["format"] = fmt
    tjson = out / f"{stem}_truth.json" if stem != "movie" else out / "truth.json"
    write_json(tjson, truth)
    tcsv = tjson.with_name(tjson.stem.replace("truth", "truth_edges") + ".csv")
    with open(tcsv.with_suffix(".csv.part"), "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["frame", "time_s", "plug_id", "top_mm", "bottom_mm"])
        for r in rows:
            w.writerow([r[0], f"{r[1]:.6f}", r[2], f"{r[3]:.4f}", f"{r[4]:.4f}"])
    os.replace(tcsv.with_suffix(".csv.part"), tcsv)
    return SynthResult(path, tjson, tcsv, truth)


def _move_into_place(tmp: Path, final: Path, fmt: str) -> None:
    """Rename a finished movie (and its sidecar) from its temporary name."""
    import shutil

    if final.exists():
        shutil.rmtree(final) if final.is_dir() else final.unlink()
    os.replace(tmp, final)
    if fmt == "mraw":
        os.replace(tmp.with_suffix(".cih"), final.with_suffix(".cih"))


__all__ = ["FLOW_DIRECTIONS", "FORMATS", "REGIMES", "MovieWriter", "Renderer", "SynthConfig",
           "SynthResult", "compute_truth", "displacement_mm", "synthesize"]
