"""``make demo``: the main job on the bundled sample movie.

Run as ``python -m grainplug.demo [OUT_DIR]`` (default ``out/demo``): prints what
``grainplug info`` finds, runs ``grainplug analyze`` into ``OUT_DIR/sample`` and
compares the result with the sample's known truth.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from .cli import main as cli_main

SAMPLE_DIR = Path(__file__).resolve().parent / "data" / "sample"
SAMPLE = SAMPLE_DIR / "plugflow_sample.mp4"
SAMPLE_TRUTH = SAMPLE_DIR / "plugflow_sample_truth.json"


def main(argv: list[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    out = Path(args[0] if args else "out/demo")
    print(f"== grainplug info {SAMPLE.name}")
    code = cli_main(["info", str(SAMPLE)])
    if code:
        return code
    dest = out / "sample"
    print(f"\n== grainplug analyze {SAMPLE.name} --out {dest} --overwrite")
    code = cli_main(["analyze", str(SAMPLE), "--out", str(dest), "--overwrite"])
    if code:
        return code
    truth = json.loads(SAMPLE_TRUTH.read_text())
    got = json.loads((dest / "summary.json").read_text())
    print("\n== against the sample's known truth (synthetic movie)")
    for key, unit in (("celerity_m_s", "m/s"), ("plug_length_mm", "mm"), ("bubble_length_mm", "mm")):
        t, g = truth[key], got[key]
        print(f"{key:18s} truth {t:9.4f} {unit:4s} measured {g:9.4f} {unit:4s} ({100 * (g / t - 1):+.2f}%)")
    print(f"{'regime':18s} truth {truth['regime']:>14s} measured {got['regime']:>14s}")
    print(f"\nopen {dest / 'report.html'} for the figures and tables")
    return 0


if __name__ == "__main__":
    sys.exit(main())
