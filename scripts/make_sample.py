"""Regenerate the bundled sample movie (src/grainplug/data/sample/).

    .venv/bin/python scripts/make_sample.py

A propagative flow of dark plugs climbing against the flow at -0.05 m/s, as in
the paper's Table 1, filmed at 250 fps and stored as H.264 (lossy, small).
Same seed, same bytes.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from grainplug.synthetic import SynthConfig, synthesize

SAMPLE_DIR = Path(__file__).resolve().parents[1] / "src" / "grainplug" / "data" / "sample"
CONFIG = SynthConfig(n_frames=400, fps=250.0, celerity_m_s=-0.05, noise_sigma=5.0, flicker=0.03,
                     gradient=0.15, falling_grains_per_mm=0.6, seed=2016)


def main() -> None:
    tmp = SAMPLE_DIR / "_build"
    res = synthesize(CONFIG, tmp, fmt="h264", stem="plugflow_sample")
    SAMPLE_DIR.mkdir(parents=True, exist_ok=True)
    for src in (res.movie, res.truth_json):
        shutil.move(str(src), SAMPLE_DIR / src.name)
    shutil.rmtree(tmp)
    print(f"wrote {SAMPLE_DIR / res.movie.name} ({(SAMPLE_DIR / res.movie.name).stat().st_size / 1e6:.2f} MB)")


if __name__ == "__main__":
    main()
