"""Throughput and peak memory of the camera-file readers, per format, against decoding alone.

    .venv/bin/python benchmarks/camera_formats.py [--frames 520] [--dir /tmp/grainplug-camera-bench]

Renders once (cached in --dir) a 1024 x 1280 grey movie of plug flow with 12-bit values and
writes the same frames as: a 16-bit TIFF stack, a 12-bit packed Photron .mraw, a 16-bit .mraw,
a 16-bit and a packed 10-bit (P10, values / 4) Phantom .cine, and a 16-bit NorPix .seq (the
file writers of tests/camera_writers.py). With the default 520 frames the 12-bit .mraw is 1 GB.
Then, each in a fresh process, with the file in the page cache (warm; run twice):

- decode: every frame handed out by ``Movie.frames()`` (unpacked, flipped), nothing else;
- band: ``Movie.read_band`` over the tube's band, the one streaming call of the analysis;
- analyze: ``grainplug.analyze`` end to end (no figures);

and the peak memory (max RSS) of each process. Prints a Markdown table. Not a test: timings
depend on the machine.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

FORMATS = ("tiff", "mraw12", "mraw16", "cine16", "cine-p10", "seq16")


def render(n_frames: int) -> np.ndarray:
    from grainplug.synthetic import SynthConfig
    from grainplug.synthetic.render import Renderer

    cfg = SynthConfig(width_px=1024, height_px=1280, n_frames=n_frames, fps=250.0, mm_per_px=0.185,
                      tube_offset_px=-140.0, noise_sigma=3.0, celerity_m_s=-0.05, seed=6, rgb=False, bit_depth=16)
    return np.stack(list(Renderer(cfg).frames())) >> 4  # 12-bit values


def write_all(folder: Path, n_frames: int) -> dict[str, Path]:
    import tifffile
    from camera_writers import write_cine, write_mraw, write_seq

    folder.mkdir(parents=True, exist_ok=True)
    paths = {"tiff": folder / "m.tif", "mraw12": folder / "m12.cih", "mraw16": folder / "m16.cih",
             "cine16": folder / "m16.cine", "cine-p10": folder / "m10.cine", "seq16": folder / "m16.seq"}
    stamp = folder / f"written-{n_frames}"
    if stamp.exists():
        return paths
    frames = render(n_frames)
    tifffile.imwrite(paths["tiff"], frames, contiguous=True, metadata={"fps": 250.0})
    write_mraw(folder / "m12", frames, bits=12, fps=250.0)
    write_mraw(folder / "m16", frames, bits=16, fps=250.0)
    write_cine(paths["cine16"], frames, fps=250.0, real_bpp=12)
    write_cine(paths["cine-p10"], frames >> 2, fps=250.0, layout="p10", real_bpp=10)
    write_seq(paths["seq16"], frames, stamps_s=1.7e9 + np.arange(n_frames) / 250.0, suggested_fps=250.0)
    stamp.touch()
    return paths


CHILD = r"""
import json, sys, time
import numpy as np
import grainplug as gp
from grainplug.band import Band
path, what = sys.argv[1], sys.argv[2]
t0 = time.perf_counter()
if what == "decode":
    with gp.open_movie(path) as m:
        n = 0
        for f in m.frames():
            n += 1
elif what == "band":
    with gp.open_movie(path) as m:
        h, w = m.info.height, m.info.width
        cols = np.arange(w // 2 - 140 - 24, w // 2 - 140 + 24)  # the tube's bore in these movies
        band = Band(np.arange(h)[:, None].repeat(len(cols), 1), np.tile(cols, (h, 1)),
                    np.full((h, len(cols)), 1 / len(cols), np.float32), (h, w))
        m.read_band(band)
        n = m.info.n_frames
else:
    res = gp.analyze(path)
    n = res.info.n_frames
dt = time.perf_counter() - t0
# VmHWM: this process's own peak (ru_maxrss would carry the parent's peak over exec)
hwm = next(int(line.split()[1]) for line in open("/proc/self/status") if line.startswith("VmHWM:"))
print(json.dumps({"s": dt, "frames": n, "rss_mb": hwm / 1024}))
"""


def measure(path: Path, what: str) -> dict[str, float]:
    out = subprocess.run([sys.executable, "-c", CHILD, str(path), what], check=True, capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=520)
    ap.add_argument("--dir", type=Path, default=Path("/tmp/grainplug-camera-bench"))
    ap.add_argument("--formats", default=",".join(FORMATS))
    args = ap.parse_args()
    paths = write_all(args.dir, args.frames)
    rows = []
    for fmt in args.formats.split(","):
        path = paths[fmt]
        data = path.with_suffix(".mraw") if path.suffix == ".cih" else path
        size_mb = data.stat().st_size / 1e6
        for _ in range(2):  # the first run brings the file into the page cache
            got = {what: measure(path, what) for what in ("decode", "band", "analyze")}
        row = {"format": fmt, "file_mb": round(size_mb), **{
            f"{what}_fps": round(r["frames"] / r["s"]) for what, r in got.items()},
            **{f"{what}_rss_mb": round(r["rss_mb"]) for what, r in got.items()}}
        rows.append(row)
        print(json.dumps(row), flush=True)
    print(f"\n{args.frames} frames of 1024 x 1280, warm page cache, {time.strftime('%Y-%m-%d')}\n")
    print("| format | file MB | decode fps | read_band fps | analyze fps | peak RSS decode / band / analyze MB |")
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    for r in rows:
        print(f"| {r['format']} | {r['file_mb']} | {r['decode_fps']} | {r['band_fps']} | {r['analyze_fps']} | "
              f"{r['decode_rss_mb']} / {r['band_rss_mb']} / {r['analyze_rss_mb']} |")


if __name__ == "__main__":
    main()
