"""Accuracy of `grainplug analyze` over the synthetic hard cases.

Renders every case of ``grainplug.synthetic.cases`` (several seeds), analyses it
with the scale given and with the scale measured from the tube, and prints the
truth, the measurement and the error of celerity, plug length, frequency and
regime, with the targets of the analyze issue.

    .venv/bin/python benchmarks/accuracy.py [--seeds 3] [--cases name,...] [--json FILE]

With ``--optics``, instead: the scale from the tube (issue 16) on movies rendered by the
independent optical renderer ``tests/tube_optics.py`` (rays traced through the glass with
Fresnel reflections; back-lit 15-70 deg and front-lit; 15 px to 90 % of the frame; tilts,
offsets, vignetting, flicker, 12-bit, H.264 crf 28, MJPEG; other glass and walls), each with
the outer diameter unknown and given. A case passes when the bore is within 2 %, the celerity
within 3 % and the plug length within 5 % of the truth, or when a warning says the scale is
doubtful; "SILENT" marks a case off by more without a warning (the issue's "never").

    .venv/bin/python benchmarks/accuracy.py --optics [--markdown]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

from grainplug import AnalysisParams, analyze
from grainplug.synthetic import synthesize
from grainplug.synthetic.cases import (
    CASES,
    CELERITY_TOL_SCALE_FROM_TUBE,
    CELERITY_TOL_SCALE_GIVEN,
    FREQUENCY_TOL_HZ,
    LENGTH_TOL_SCALE_FROM_TUBE,
    LENGTH_TOL_SCALE_GIVEN,
    MIN_PERIODS_FOR_FREQUENCY,
)


def rel(a, b):
    return None if a is None or b is None else a / b - 1


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--cases", default="")
    ap.add_argument("--json", default=None)
    ap.add_argument("--optics", action="store_true", help="the tube-model matrix on the optical renderer")
    ap.add_argument("--markdown", action="store_true", help="with --optics: also print a Markdown table")
    args = ap.parse_args()
    if args.optics:
        return optics(markdown=args.markdown, names=set(filter(None, args.cases.split(","))))
    names = set(filter(None, args.cases.split(",")))
    rows = []
    failures = 0
    hdr = (f"{'case':22s} {'seed':>4s} {'scale':5s} {'c truth':>8s} {'c meas':>8s} {'err%':>6s} "
           f"{'L truth':>7s} {'L meas':>7s} {'err%':>6s} {'f truth':>7s} {'f meas':>7s} "
           f"{'regime':>11s} {'ok':>3s} {'s':>5s}")
    print(hdr)
    print("-" * len(hdr))
    with tempfile.TemporaryDirectory() as tmp:
        for case in CASES:
            if names and case.name not in names:
                continue
            for seed in range(args.seeds):
                cfg = case.synth_config(seed)
                res = synthesize(cfg, Path(tmp) / f"{case.name}_{seed}", fmt=case.fmt)
                truth = res.truth
                for scale in ("given", "tube"):
                    t0 = time.perf_counter()
                    out = analyze(res.movie, AnalysisParams(
                        mm_per_px=cfg.mm_per_px if scale == "given" else None,
                        flow_direction=cfg.flow_direction))
                    dt = time.perf_counter() - t0
                    s = out.summary
                    ec = rel(s["celerity_m_s"], truth["celerity_m_s"])
                    el = rel(s["plug_length_mm"], truth["plug_length_mm"])
                    ft, fm = truth["oscillation_frequency_hz"], s["oscillation_frequency_hz"]
                    periods = (ft or 0) * cfg.n_frames / cfg.fps
                    tol_c = CELERITY_TOL_SCALE_GIVEN if scale == "given" else CELERITY_TOL_SCALE_FROM_TUBE
                    tol_l = LENGTH_TOL_SCALE_GIVEN if scale == "given" else LENGTH_TOL_SCALE_FROM_TUBE
                    ok = s["regime"] == truth["regime"]
                    if truth["has_plugs"]:
                        ok &= ec is not None and abs(ec) <= tol_c
                        ok &= el is not None and abs(el) <= tol_l
                        if ft and periods >= MIN_PERIODS_FOR_FREQUENCY:
                            ok &= fm is not None and abs(fm - ft) <= FREQUENCY_TOL_HZ
                    else:
                        ok &= s["celerity_m_s"] is None
                    failures += not ok

                    def f(x, nd=4):
                        return "—" if x is None else f"{x:.{nd}f}"

                    print(f"{case.name:22s} {seed:4d} {scale:5s} {f(truth['celerity_m_s'])!s:>8s} "
                          f"{f(s['celerity_m_s'])!s:>8s} {f(ec and 100 * ec, 2)!s:>6s} "
                          f"{f(truth['plug_length_mm'], 2)!s:>7s} {f(s['plug_length_mm'], 2)!s:>7s} "
                          f"{f(el and 100 * el, 2)!s:>6s} {f(ft, 2)!s:>7s} {f(fm, 2)!s:>7s} "
                          f"{s['regime']:>11s} {'yes' if ok else 'NO':>3s} {dt:5.1f}", flush=True)
                    rows.append({"case": case.name, "seed": seed, "scale": scale, "truth": {
                        k: truth[k] for k in ("celerity_m_s", "plug_length_mm", "oscillation_frequency_hz",
                                              "regime")}, "measured": {
                        k: s[k] for k in ("celerity_m_s", "plug_length_mm", "oscillation_frequency_hz",
                                          "regime", "tube_diameter_px")}, "ok": bool(ok), "seconds": dt})
    print(f"\n{len(rows) - failures}/{len(rows)} within targets: celerity {CELERITY_TOL_SCALE_GIVEN:.0%} "
          f"(scale given) / {CELERITY_TOL_SCALE_FROM_TUBE:.0%} (scale from tube); plug length "
          f"{LENGTH_TOL_SCALE_GIVEN:.0%} / {LENGTH_TOL_SCALE_FROM_TUBE:.0%}; frequency "
          f"{FREQUENCY_TOL_HZ} Hz with >= {MIN_PERIODS_FOR_FREQUENCY} periods; regime exact")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 1 if failures else 0


SCALE_WORDS = ("the scale", "the tube's bore", "the tube model", "the tube is only", "the tube fills")


def optics(*, markdown: bool, names: set[str]) -> int:
    """The tube model's accuracy on the optical renderer's matrix (see the module's docstring)."""
    import numpy as np

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from tube_optics import CASES as OPTICS
    from tube_optics import SUFFIX, render_movie

    rows, silent = [], 0
    with tempfile.TemporaryDirectory() as tmp:
        for name, kw in OPTICS.items():
            if names and name not in names:
                continue
            fmt = str(kw.get("fmt", "tif"))
            path = Path(tmp) / f"m{SUFFIX[fmt]}"
            truth = render_movie(path, rng=np.random.default_rng(1), **kw)
            for od in (None, float(kw.get("outer_diameter_mm", 5.5))):
                res = analyze(path, AnalysisParams(fps=truth.fps, tube_outer_diameter_mm=od))
                bore = res.bore.diameter_px / truth.bore_px - 1
                c = rel(res.celerity_m_s, truth.celerity_m_s)
                ln = rel(res.plug_length_mm, truth.plug_length_mm)
                warned = any(any(w.startswith(k) or k in w for k in SCALE_WORDS) for w in res.warnings)
                good = abs(bore) <= 0.02 and c is not None and abs(c) <= 0.03 and ln is not None and abs(ln) <= 0.05
                verdict = "ok" if good else ("flagged" if warned else "SILENT")
                silent += verdict == "SILENT"
                rows.append((name, "given" if od else "unknown", bore, c, ln, res.bore.method, warned, verdict,
                             truth.visible_fraction))
                print(f"{name:32s} OD {rows[-1][1]:7s} bore {100 * bore:+6.2f} % ({res.bore.method:14s}) "
                      f"celerity {100 * (c or float('nan')):+6.2f} % length {100 * (ln or float('nan')):+6.2f} % "
                      f"warned {'yes' if warned else 'no ':3s} {verdict}", flush=True)
    if markdown:
        print("\n| case | outer diameter | bore | celerity | plug length | from | warning | verdict |")
        print("| --- | --- | --- | --- | --- | --- | --- | --- |")
        for name, od, bore, c, ln, method, warned, verdict, _ in rows:
            print(f"| {name} | {od} | {100 * bore:+.1f} % | {100 * (c or float('nan')):+.1f} % | "
                  f"{100 * (ln or float('nan')):+.1f} % | {method} | {'yes' if warned else 'no'} | {verdict} |")
    print(f"\n{sum(r[7] == 'ok' for r in rows)} within the targets, {sum(r[7] == 'flagged' for r in rows)} "
          f"outside them with a warning, {silent} outside them silently (of {len(rows)})")
    return 1 if silent else 0


if __name__ == "__main__":
    sys.exit(main())
