"""Accuracy of `grainplug analyze` over the synthetic hard cases.

Renders every case of ``grainplug.synthetic.cases`` (several seeds), analyses it
with the scale given and with the scale measured from the tube, and prints the
truth, the measurement and the error of celerity, plug length, frequency and
regime, with the targets of the analyze issue.

    .venv/bin/python benchmarks/accuracy.py [--seeds 3] [--cases name,...] [--json FILE]
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
    args = ap.parse_args()
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


if __name__ == "__main__":
    sys.exit(main())
