"""`grainplug analyze` on movies with a real lab's nuisances, from an independent renderer.

Renders every case of ``tests/lab_nuisances.py`` (camera shake, lamp ripple, passing shadows,
clamps, labels, front and back light, noise, H.264; propagative, oscillating, stick-slip and static
trains), caches the movies and their truth under ``CACHE`` (reused while the case is unchanged),
analyses each with ``grainplug.analyze`` and prints a Markdown table of truth, measurement, errors,
the celerity interval, the warning codes and a verdict against the targets:

* celerity within 3 % (scale given) / 6 % (scale from the tube);
* plug length within 5 % / 8 %;
* oscillation frequency within 0.3 Hz;
* regime exact;
* the celerity's 95 % interval holds the truth (a miss by under 0.5 % of the truth is not counted).

The bubble length is shown, not judged. Usage::

    .venv/bin/python benchmarks/nuisances.py CACHE [--cases REGEX] [--out DIR] [--jobs 1] [--seed N]

``--out DIR`` writes ``nuisances.md`` (the table) and ``nuisances.json`` (every figure) there.
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import json
import re
import subprocess
import sys
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

from lab_nuisances import CASES, FREQUENCY_TOL_HZ, Case, judge, render_movie, truth_record  # noqa: E402


def cached_movie(case: Case, cache: Path) -> tuple[Path, dict[str, object]]:
    """The case's movie and truth, rendered into ``cache`` unless a movie of the same scene is there."""
    key = hashlib.sha256(f"{case.scene!r} {case.seed}".encode()).hexdigest()[:10]
    movie = cache / f"{key}_{case.movie_name()}"
    meta = movie.with_suffix(".json")
    if movie.exists() and meta.exists():
        return movie, json.loads(meta.read_text())
    truth = render_movie(movie, case.scene, np.random.default_rng(case.seed))
    record = truth_record(truth)
    meta.write_text(json.dumps(record, indent=1))
    return movie, record


def run_case(name: str, cache: str, seed: int | None = None) -> dict[str, object]:
    """Render (or reuse) and analyse one case (with another seed: another draw of its noise, grains, plug lengths
    and shake phases); every figure of the row."""
    import dataclasses

    import grainplug as gp

    case = CASES[name] if seed is None else dataclasses.replace(CASES[name], seed=seed)
    t0 = time.perf_counter()
    movie, truth = cached_movie(case, Path(cache))
    t1 = time.perf_counter()
    try:
        res = gp.analyze(movie, **case.analysis_kwargs())
        s = res.summary
        error = None
    except Exception as exc:  # a crash is a result of the bench, not its end
        s, error = {}, f"{type(exc).__name__}: {exc}"
    t2 = time.perf_counter()
    keep = ("celerity_m_s", "celerity_ci95_m_s", "plug_length_mm", "bubble_length_mm", "oscillation_frequency_hz",
            "oscillation_amplitude_mm", "regime", "mm_per_px", "scale_source", "warning_codes", "warnings")
    measured = {k: s.get(k) for k in keep}
    measured["warnings"] = [str(w) for w in (measured["warnings"] or [])]
    row = {"case": name, "scale": case.scale, "fmt": case.scene.fmt, "truth": truth, "measured": measured,
           "error": error, "render_s": t1 - t0, "analyze_s": t2 - t1}
    row.update(judge(case, truth, s) if error is None else {"fails": ["crash"], "ok": False})
    return row


def _f(x: object, fmt: str) -> str:
    return "—" if x is None else format(x, fmt)


def _pct(x: object) -> str:
    return "—" if x is None else f"{100 * float(x):+.1f}"


def _codes(codes: list[str] | None) -> str:
    if not codes:
        return ""
    return ", ".join(f"{c}×{n}" if n > 1 else c for c, n in Counter(codes).items())


REG = {"propagative": "prop", "oscillating": "osc", "static": "static", None: "—"}


def markdown(rows: list[dict[str, object]], header: str) -> str:
    """The table, with a header line and the count meeting every target."""
    out = [header, "",
           "| case | scale | c truth (m/s) | c meas. | c err % | CI holds | plug truth (mm) | plug meas. | plug err % "
           "| bubble truth | bubble meas. | bubble err % | f truth (Hz) | f meas. | regime truth → meas. "
           "| warning codes | verdict |",
           "| --- " * 17 + "|"]
    for r in rows:
        t, m = r["truth"], r["measured"]
        ci = {True: "yes", False: "**no**", None: "—"}[r.get("ci_holds")]
        regime = f"{REG[t['regime']]} → {REG.get(m.get('regime'), m.get('regime'))}"
        if m.get("regime") != t["regime"]:
            regime = f"**{regime}**"
        verdict = "ok" if r["ok"] else "FAIL: " + ", ".join(r["fails"])
        out.append(
            f"| {r['case']} | {r['scale']} | {_f(t['celerity_m_s'], '.3f')} | {_f(m.get('celerity_m_s'), '.4f')} "
            f"| {_pct(r.get('celerity_err'))} | {ci} | {_f(t['plug_length_mm'], '.2f')} "
            f"| {_f(m.get('plug_length_mm'), '.2f')} | {_pct(r.get('plug_err'))} | {_f(t['bubble_length_mm'], '.2f')} "
            f"| {_f(m.get('bubble_length_mm'), '.2f')} | {_pct(r.get('bubble_err'))} | {_f(t['frequency_hz'], '.1f')} "
            f"| {_f(m.get('oscillation_frequency_hz'), '.2f')} | {regime} | {_codes(m.get('warning_codes'))} "
            f"| {verdict} |")
    n_ok = sum(r["ok"] for r in rows)
    out += ["", f"**{n_ok} of {len(rows)} cases meet all the targets** (celerity 3 % / 6 %, plug length "
            f"5 % / 8 % with the scale given / from the tube, frequency {FREQUENCY_TOL_HZ} Hz, regime exact, "
            f"the 95 % interval holding the celerity)."]
    return "\n".join(out)


def _commit() -> str:
    try:
        return subprocess.run(["git", "-C", str(HERE), "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cache", type=Path, help="folder where the movies and their truth are kept")
    ap.add_argument("--cases", default="", help="only the cases whose name matches this regular expression")
    ap.add_argument("--out", type=Path, default=None, help="write nuisances.md and nuisances.json here")
    ap.add_argument("--jobs", type=int, default=1, help="cases run at once (processes)")
    ap.add_argument("--seed", type=int, default=None,
                    help="render every case with this seed instead of its own (movies the methods were not "
                         "developed on)")
    args = ap.parse_args()
    pattern = re.compile(args.cases) if args.cases else None
    names = [n for n in CASES if pattern is None or pattern.search(n)]
    if not names:
        print(f"no case matches {args.cases!r}", file=sys.stderr)
        return 2
    args.cache.mkdir(parents=True, exist_ok=True)
    import grainplug

    t0 = time.perf_counter()
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs) as pool:
            rows = list(pool.map(run_case, names, [str(args.cache)] * len(names), [args.seed] * len(names)))
    else:
        rows = []
        for n in names:
            rows.append(run_case(n, str(args.cache), args.seed))
            r = rows[-1]
            print(f"{'ok  ' if r['ok'] else 'FAIL'} {n} ({r['render_s']:.1f} s + {r['analyze_s']:.1f} s) "
                  f"{', '.join(r['fails'])}", file=sys.stderr, flush=True)
    header = (f"Run on {datetime.date.today().isoformat()}, grainplug {grainplug.__version__} at commit "
              f"{_commit()}, {len(rows)} cases, {time.perf_counter() - t0:.0f} s"
              + (f", every case rendered with seed {args.seed}." if args.seed is not None else "."))
    table = markdown(rows, header)
    print(table)
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "nuisances.md").write_text(table + "\n")
        (args.out / "nuisances.json").write_text(json.dumps(rows, indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
