"""Do the 95 % intervals hold the truth when the scale comes from the tube? (issue 33, item 5)

A sweep on the independent renderers of ``tests/``: the optical one (``tests/tube_optics.py``: rays traced
through the glass with Fresnel reflections) over bores of 10-60 px, low and high noise, back light (lamps of
15, 25 and 50 deg) and front light, lossless TIFF, H.264 and MJPEG, a few seeds; and the plain-band renderer of
``tests/test_other_renderer.py`` (no walls at all) over bores of 10-30 px. Every movie is analysed with the
scale from the tube, the outer diameter unknown and given (the plain-band renderer has no outer diameter).

For each analysis: the scale's error, the claimed ``scale_rel_sd``, ``z = error / rel_sd``, and whether the
95 % intervals of the celerity and of the plug length hold the truth (a miss by less than 0.5 % of the truth is
not counted: the renderers' own truth is no closer). Then the coverage (the share of ``|z| <= 1.96`` and of the
intervals that hold the truth) over the whole sweep and per group, and the median width of the intervals.

    PYTHONPATH=src .venv/bin/python benchmarks/intervals.py [--seeds 3] [--jobs 2] [--json FILE] [--quick]
        [--markdown]

``--quick`` runs a few cases only (a 12 px bore, a front-lit H.264 one...). Exit status 1 when the coverage of
either interval is below 95 %.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

log = logging.getLogger("intervals")
TESTS = Path(__file__).resolve().parents[1] / "tests"

#: a miss by less than this share of the truth is not counted
SLACK = 0.005

BORES = (10, 12, 15, 20, 30, 45, 60)
LIGHTS = (("back", 15.0), ("back", 25.0), ("back", 50.0), ("front", 0.0))
#: (codec, noise) taken in turn, so that every bore and light meets each of them over the seeds
CAMERAS = (("tif", 0.01), ("h264", 0.01), ("tif", 0.03), ("mjpeg", 0.03), ("h264", 0.03), ("mjpeg", 0.01))
OTHER_BORES = (10, 12, 15, 20, 30)


def optics_cases(seeds: int) -> list[dict[str, object]]:
    """The optical renderer's sweep: one dict per movie."""
    out = []
    for i, bore in enumerate(BORES):
        for j, (kind, beta) in enumerate(LIGHTS):
            for seed in range(seeds):
                fmt, noise = CAMERAS[(i + j * 2 + seed * 3) % len(CAMERAS)]
                out.append({"renderer": "optics", "bore": bore, "light": kind, "beta": beta, "fmt": fmt,
                            "noise": noise, "seed": seed})
    return out


def other_cases(seeds: int) -> list[dict[str, object]]:
    """The plain-band renderer's: dark and bright plugs."""
    return [{"renderer": "band", "bore": bore, "light": "back" if dark else "front", "beta": 0.0, "fmt": "tif",
             "noise": 0.0, "seed": seed, "dark": dark}
            for bore in OTHER_BORES for dark in (True, False) for seed in range(max(1, seeds - 1))]


QUICK = [
    {"renderer": "optics", "bore": 12, "light": "back", "beta": 25.0, "fmt": "tif", "noise": 0.01, "seed": 0},
    {"renderer": "optics", "bore": 13, "light": "back", "beta": 25.0, "fmt": "tif", "noise": 0.03, "seed": 0},
    {"renderer": "optics", "bore": 20, "light": "front", "beta": 0.0, "fmt": "h264", "noise": 0.01, "seed": 0},
    {"renderer": "optics", "bore": 30, "light": "back", "beta": 15.0, "fmt": "mjpeg", "noise": 0.03, "seed": 0},
    {"renderer": "band", "bore": 12, "light": "back", "beta": 0.0, "fmt": "tif", "noise": 0.0, "seed": 0,
     "dark": True},
]


def render(case: dict[str, object], folder: Path) -> tuple[Path, dict[str, float], list[float | None]]:
    """Render one case; return the movie, its truth and the outer diameters (mm) to analyse it with."""
    if str(TESTS) not in sys.path:
        sys.path.insert(0, str(TESTS))
    bore = float(case["bore"])  # type: ignore[arg-type]
    rng = np.random.default_rng(1000 + int(case["seed"]))  # type: ignore[call-overload]
    if case["renderer"] == "optics":
        from tube_optics import SUFFIX, Lighting, render_movie

        fmt = str(case["fmt"])
        path = folder / f"m{SUFFIX[fmt]}"
        light = Lighting("back", float(case["beta"])) if case["light"] == "back" else Lighting("front")  # type: ignore[arg-type]
        mpp = 3.0 / bore
        t = render_movie(path, rng=rng, fmt=fmt, mm_per_px=mpp, width_px=max(60, int(round(3.4 * bore))),
                         height_px=max(600, int(20 * bore)), n_frames=300, noise=float(case["noise"]), lighting=light)  # type: ignore[arg-type]
        truth = {"mm_per_px": mpp, "celerity_m_s": t.celerity_m_s, "plug_length_mm": t.plug_length_mm,
                 "fps": t.fps, "tube_diameter_mm": 3.0}
        return path, truth, [None, 5.5]
    from test_other_renderer import render as band

    path = folder / "m.tif"
    mpp = 0.15 if bore >= 15 else 0.27
    c, length, _ = band(path, rng=rng, tube_px=bore, mm_per_px=mpp, n_frames=150, h=500 if bore < 15 else 720,
                        dark_plugs=bool(case["dark"]), celerity_m_s=-0.045 if case["dark"] else 0.03)
    truth = {"mm_per_px": mpp, "celerity_m_s": c, "plug_length_mm": length, "fps": 250.0,
             "tube_diameter_mm": bore * mpp}
    return path, truth, [None]


def holds(ci: list[float] | None, truth: float) -> bool | None:
    """Whether the interval holds the truth (to ``SLACK``); None without an interval."""
    if not ci or ci[0] is None or ci[1] is None:
        return None
    lo, hi = sorted(ci)
    pad = SLACK * abs(truth)
    return lo - pad <= truth <= hi + pad


def run(case: dict[str, object]) -> list[dict[str, object]]:
    """Render and analyse one case (both outer diameters); one row per analysis."""
    import warnings

    from grainplug import AnalysisParams, analyze
    from grainplug.errors import GrainplugError

    rows = []
    with tempfile.TemporaryDirectory(dir=None) as tmp:
        path, truth, ods = render(case, Path(tmp))
        for od in ods:
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    res = analyze(path, AnalysisParams(fps=truth["fps"], tube_diameter_mm=truth["tube_diameter_mm"],
                                                       tube_outer_diameter_mm=od))
            except GrainplugError as exc:  # refused, said why: not an interval that misses
                log.warning("%s, outer diameter %s: refused (%s)", case, od, exc)
                rows.append({**case, "od": od, "error": str(exc)})
                continue
            s = res.summary
            err = res.mm_per_px / truth["mm_per_px"] - 1
            sd = float(res.scale_rel_sd)
            c, cci = s["celerity_m_s"], s["celerity_ci95_m_s"]
            ln, lci = s["plug_length_mm"], s["plug_length_ci95_mm"]

            def width(ci: list[float] | None, v: float | None) -> float | None:
                return None if not ci or not v or ci[0] is None else abs(ci[1] - ci[0]) / 2 / abs(v)

            b = res.bore
            rows.append({**case, "od": od, "method": b.method if b else "none",
                         "bore_px": b.diameter_px if b else None, "agreement": b.agreement if b else None,
                         "estimates_px": dict(b.estimates_px) if b else {},
                         "visible_px": res.tube.inner_diameter_px, "contrast": res.tube.contrast,
                         "scale_error": err, "scale_rel_sd": sd, "z": err / sd if sd > 0 else math.inf,
                         "celerity_error": None if c is None else c / truth["celerity_m_s"] - 1,
                         "celerity_holds": None if c is None else holds(cci, truth["celerity_m_s"]),
                         "celerity_half_width": width(cci, c),
                         "length_error": None if ln is None else ln / truth["plug_length_mm"] - 1,
                         "length_holds": None if ln is None else holds(lci, truth["plug_length_mm"]),
                         "length_half_width": width(lci, ln),
                         "warnings": [w.split(":")[0] for w in res.warnings]})
    return rows


def coverage(rows: list[dict[str, object]], key: str) -> tuple[int, int]:
    vals = [r[key] for r in rows if r[key] is not None]
    return sum(bool(v) for v in vals), len(vals)


def pct(a: int, n: int) -> str:
    return f"{a}/{n} ({100 * a / n:.0f} %)" if n else "—"


def report(rows: list[dict[str, object]], *, markdown: bool) -> bool:
    """Print the table and the coverage; True when both intervals hold the truth in >= 95 % of the analyses."""
    def f(x: object, fmt: str) -> str:
        return "—" if x is None else format(x, fmt)

    hdr = (f"{'renderer':8s} {'bore':>4s} {'light':9s} {'codec':5s} {'noise':>5s} {'seed':>4s} {'OD':>4s} "
           f"{'method':16s} {'err %':>6s} {'sd %':>5s} {'z':>6s} {'c err%':>6s} {'c±%':>5s} {'c':>2s} "
           f"{'L err%':>6s} {'L±%':>5s} {'L':>2s}")
    print(hdr)
    print("-" * len(hdr))
    for r in rows:
        light = f"{r['light']} {r['beta']:.0f}" if r["light"] == "back" and r["beta"] else str(r["light"])
        def mark(v: object) -> str:
            return "—" if v is None else ("ok" if v else "NO")
        print(f"{r['renderer']:8s} {r['bore']:4d} {light:9s} {r['fmt']:5s} {r['noise']:5.2f} {r['seed']:4d} "
              f"{f(r['od'], 'g'):>4s} {r['method']:16s} {100 * r['scale_error']:+6.2f} {100 * r['scale_rel_sd']:5.2f} "
              f"{r['z']:+6.2f} {f(r['celerity_error'] and 100 * r['celerity_error'], '+6.2f'):>6s} "
              f"{f(r['celerity_half_width'] and 100 * r['celerity_half_width'], '5.2f'):>5s} "
              f"{mark(r['celerity_holds']):>2s} {f(r['length_error'] and 100 * r['length_error'], '+6.2f'):>6s} "
              f"{f(r['length_half_width'] and 100 * r['length_half_width'], '5.2f'):>5s} {mark(r['length_holds']):>2s}")
    z_ok = sum(abs(float(r["z"])) <= 1.96 for r in rows)  # type: ignore[arg-type]
    c_ok, c_n = coverage(rows, "celerity_holds")
    l_ok, l_n = coverage(rows, "length_holds")
    print(f"\n{len(rows)} analyses with the scale from the tube")
    print(f"|z| <= 1.96: {pct(z_ok, len(rows))}; celerity's interval holds the truth: {pct(c_ok, c_n)}; "
          f"plug length's: {pct(l_ok, l_n)}")
    cw = [r["celerity_half_width"] for r in rows if r["celerity_half_width"] is not None]
    lw = [r["length_half_width"] for r in rows if r["length_half_width"] is not None]
    sds = [r["scale_rel_sd"] for r in rows]
    print(f"median half-width of the 95 % intervals: celerity {100 * np.median(cw):.2f} %, plug length "
          f"{100 * np.median(lw):.2f} %; median scale_rel_sd {100 * np.median(sds):.2f} %")
    groups: dict[str, list[dict[str, object]]] = {}
    for r in rows:
        for g in (f"renderer {r['renderer']}", f"method {r['method']}", f"light {r['light']}", f"codec {r['fmt']}",
                  f"bore {'<= 15' if int(r['bore']) <= 15 else '> 15'} px", f"seed {r['seed']}"):  # type: ignore[call-overload]
            groups.setdefault(g, []).append(r)
    print(f"\n{'group':26s} {'n':>3s} {'|z|<=1.96':>10s} {'celerity':>9s} {'length':>9s} {'med sd %':>8s}")
    for g in sorted(groups):
        rs = groups[g]
        zk = sum(abs(float(r["z"])) <= 1.96 for r in rs)  # type: ignore[arg-type]
        ck, cn = coverage(rs, "celerity_holds")
        lk, ln = coverage(rs, "length_holds")
        print(f"{g:26s} {len(rs):3d} {zk:4d}/{len(rs):<5d} {ck:3d}/{cn:<5d} {lk:3d}/{ln:<5d} "
              f"{100 * np.median([r['scale_rel_sd'] for r in rs]):8.2f}")
    if markdown:
        print("\n| analyses | \\|z\\| <= 1.96 | celerity's interval holds | length's interval holds | "
              "median celerity ± | median length ± | median scale sd |")
        print("| --- | --- | --- | --- | --- | --- | --- |")
        print(f"| {len(rows)} | {pct(z_ok, len(rows))} | {pct(c_ok, c_n)} | {pct(l_ok, l_n)} | "
              f"{100 * np.median(cw):.2f} % | {100 * np.median(lw):.2f} % | {100 * np.median(sds):.2f} % |")
    return c_n > 0 and c_ok >= 0.95 * c_n and (l_n == 0 or l_ok >= 0.95 * l_n)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--json", default=None, help="write every analysis's figures here")
    ap.add_argument("--quick", action="store_true", help="a handful of cases only")
    ap.add_argument("--markdown", action="store_true", help="also print the coverage as a Markdown table")
    ap.add_argument("--renderer", choices=("optics", "band", "both"), default="both")
    args = ap.parse_args()
    cases = QUICK if args.quick else (
        (optics_cases(args.seeds) if args.renderer != "band" else [])
        + (other_cases(args.seeds) if args.renderer != "optics" else []))
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs) as pool:
            rows = [r for rs in pool.map(run, cases) for r in rs]
    else:
        rows = [r for c in cases for r in run(c)]
    refused = [r for r in rows if "error" in r]
    good = report([r for r in rows if "error" not in r], markdown=args.markdown)
    for r in refused:
        print(f"refused: {r['renderer']} bore {r['bore']} {r['light']} {r['fmt']} seed {r['seed']} OD {r['od']}: "
              f"{r['error']}")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1, default=float))
    return 0 if good else 1


if __name__ == "__main__":
    sys.exit(main())
