"""Speed and memory of `grainplug analyze` on full-size movies, against decoding alone
and against a straightforward per-frame port of the paper's algorithm.

    .venv/bin/python benchmarks/performance.py [--frames 600] [--dir /tmp/grainplug-bench]
        [--formats tiff,avi,ffv1,h264,tiff-h] [--long-frames 3000 --long-formats tiff,tiff-h]

For each format it renders (once, cached in --dir) a 1280x1024 RGB movie of plug
flow, then measures in one run on the same file:

- decode-only: every frame decoded to an array with the same library grainplug
  uses (tifffile / PyAV), nothing else;
- analyze: `grainplug analyze` end to end, timed from outside a fresh process
  (interpreter start, imports, tube detection, diagram, plugs, measures, files,
  figures, report; decode-only is timed inside its loop, without any start-up);
- baseline: `baseline_paper_port` below on a subset of frames (every whole frame
  converted to grey, binarised, labelled with scikit-image), from memory, timed right
  after each analysis so that each ratio compares timings seconds apart;
- peak memory (max RSS) of `analyze`, also on a long movie (--long-frames);
- from the disk, the share of the file the analysis read (``tiff-h``, a horizontal
  tube across landscape frames, needs only its band's rows);
- for H.264, the CPU time / wall time of decoding (decoding on all cores).

Each is measured "cold" (the movie evicted from the page cache: its bytes come from
the disk, while Python and its libraries stay in memory) and "warm" (the movie
already in memory). It prints the ratios and a Markdown table. Nothing here is a test: timings depend on the machine.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

from grainplug.readers import open_movie
from grainplug.synthetic import SynthConfig, synthesize

#: the analyses run as on a user's machine: Python's compiled bytecode cached (a shell with
#: PYTHONDONTWRITEBYTECODE set would have every module compiled again at each start, ~0.1 s)
USER_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def movie_config(n_frames: int, *, horizontal: bool = False) -> SynthConfig:
    # 1280 px along the tube (the paper's 237 mm field of view at 0.185 mm/px), 1024 across;
    # horizontal: the same view with the camera turned a quarter (1280 x 1024 landscape frames)
    return SynthConfig(width_px=1024, height_px=1280, n_frames=n_frames, fps=250.0, mm_per_px=0.185,
                       tube_offset_px=-140.0, noise_sigma=3.0, celerity_m_s=-0.05, seed=6,
                       flow_direction="right" if horizontal else "down")


def ensure_movie(folder: Path, fmt: str, n_frames: int) -> Path:
    """The benchmark's movie in format ``fmt`` (``tiff-h``: a TIFF stack of a horizontal tube)."""
    stem = f"movie_{n_frames}"
    target = folder / fmt
    done = target / f".{stem}.done"
    if done.exists():
        return Path(done.read_text())
    t0 = time.perf_counter()
    horizontal = fmt.endswith("-h")
    res = synthesize(movie_config(n_frames, horizontal=horizontal), target, fmt=fmt.removesuffix("-h"), stem=stem)
    done.write_text(str(res.movie))
    print(f"rendered {res.movie} ({res.movie.stat().st_size / 1e9:.2f} GB) in {time.perf_counter() - t0:.0f} s",
          file=sys.stderr)
    return res.movie


def decode_only(path: Path) -> tuple[int, float, float]:
    """Frames, wall seconds and CPU seconds of decoding every frame to an array."""
    c0 = time.process_time()
    t0 = time.perf_counter()
    n = 0
    if path.suffix.lower() in (".tif", ".tiff"):
        import tifffile

        with tifffile.TiffFile(str(path)) as tif:
            for page in tif.pages:
                page.asarray()
                n += 1
    else:
        import av

        with av.open(str(path)) as container:
            stream = container.streams.video[0]
            stream.thread_type = "AUTO"
            for frame in container.decode(stream):
                try:
                    frame.to_ndarray()  # the decoder's own layout where PyAV can hand it out
                except ValueError:
                    frame.to_ndarray(format="rgb24")  # e.g. FFV1's bgr0
                n += 1
    return n, time.perf_counter() - t0, time.process_time() - c0


def baseline_paper_port(path: Path, n_frames: int, *, mm_per_px: float = 0.185) -> tuple[int, float]:
    """The paper's algorithm, ported frame by frame with scikit-image (no cropping by hand,
    no tuning): grey conversion, Otsu threshold of the first frame, binarisation and
    connected-component labelling of every whole frame, plugs = dark regions taller than
    3 mm, their upper and lower positions stored."""
    from skimage.color import rgb2gray
    from skimage.filters import threshold_otsu
    from skimage.measure import label, regionprops

    t0 = time.perf_counter()
    positions = []
    threshold = None
    with open_movie(path) as movie:
        for k, frame in enumerate(movie.frames(0, n_frames)):
            grey = rgb2gray(frame) if frame.ndim == 3 else frame / frame.max()
            if threshold is None:
                threshold = threshold_otsu(grey)
            binary = grey < threshold
            for region in regionprops(label(binary)):
                top, _, bottom, _ = region.bbox
                if (bottom - top) * mm_per_px > 3.0:
                    positions.append((k, top * mm_per_px, bottom * mm_per_px))
    return n_frames, time.perf_counter() - t0


def evict(path: Path) -> bool:
    """Drop the movie's pages from the page cache, so that its reads come from the disk.

    Only this file's pages go (``POSIX_FADV_DONTNEED`` on clean pages; no root
    needed): Python and its libraries stay in memory, as on a machine where
    grainplug was used before and the movie is new.
    """
    if not hasattr(os, "posix_fadvise"):
        return False
    os.sync()
    fd = os.open(path, os.O_RDONLY)
    try:
        os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED)
    finally:
        os.close(fd)
    return True


def resident_bytes(path: Path) -> int | None:
    """Bytes of ``path`` in the page cache (util-linux ``fincore``), None when unknown."""
    try:
        out = subprocess.run(["fincore", "--bytes", "--noheadings", "--output", "RES", str(path)],
                             capture_output=True, text=True, check=True).stdout
        return int(out.split()[0])
    except (OSError, subprocess.CalledProcessError, ValueError, IndexError):
        return None


def run_analyze(path: Path, out: Path) -> tuple[float, int, dict]:
    """Wall seconds and peak RSS (bytes) of `grainplug analyze` in a fresh process (the
    analysis's peak plus the figure helper's, an upper bound of what they held together)."""
    code = (
        "import resource, sys, json\n"
        "from grainplug.cli import main\n"
        f"rc = main(['analyze', {str(path)!r}, '--out', {str(out)!r}, '--json', '--overwrite'])\n"
        "rss = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
        "       + resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss) * 1024  # + the figures' helper\n"
        "print(json.dumps({'rss': rss, 'rc': rc}), file=sys.stderr)\n"
    )
    t0 = time.perf_counter()  # the whole process: interpreter start, imports, analysis, files, figures
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False, env=USER_ENV)
    seconds = time.perf_counter() - t0
    info = json.loads(proc.stderr.strip().splitlines()[-1])
    if info["rc"] != 0:
        raise SystemExit(f"analyze failed: {proc.stderr}")
    return seconds, info["rss"], json.loads(proc.stdout)


def _baseline_now(path: Path, n_frames: int) -> float:
    """The baseline's speed (fps) now, from memory: its frames read once first (timed from
    the disk it once ran at 26 fps instead of ~47, flattering the ratios)."""
    baseline_paper_port(path, n_frames)
    n, seconds = baseline_paper_port(path, n_frames)
    return n / seconds


def measure(path: Path, label: str, out: Path, can_drop: bool, baseline_frames: int,
            repeat: int = 1) -> list[dict]:
    """Decode-only, analyze end to end and the baseline on one file, cold and warm.

    Each (decode, analyze, baseline) triple is taken ``repeat`` times in a row, the
    baseline right after the analysis, so that each ratio compares timings taken within
    seconds of each other (this machine's speed drifts by tens of percent within minutes);
    the row reports the median ratios and the range of the ratio to decoding.
    """
    rows = []
    for cache in (("cold", "warm") if can_drop else ("warm",)):
        runs = []
        for _ in range(repeat):
            if cache == "cold":
                evict(path)
                left = resident_bytes(path)
                if left:
                    print(f"warning: {left / 1e6:.0f} MB of {path.name} stayed in memory", file=sys.stderr)
            else:
                decode_only(path)  # both measures read from memory
                left = resident_bytes(path)
                if left is not None and left < 0.99 * path.stat().st_size:
                    print(f"warning: only {left / path.stat().st_size:.0%} of {path.name} stays in memory",
                          file=sys.stderr)
            n, dec_s, dec_cpu = decode_only(path)
            if cache == "cold":
                evict(path)
            an_s, rss, summary = run_analyze(path, out)
            if cache == "cold":  # what the analysis brought into memory is what it read
                got = resident_bytes(path)
                summary["read_fraction"] = None if got is None else got / path.stat().st_size
            fps_base = _baseline_now(path, baseline_frames)
            runs.append({"dec_s": dec_s, "dec_cpu": dec_cpu, "an_s": an_s, "rss": rss, "summary": summary,
                         "fps_base": fps_base, "over_decode": dec_s / an_s,
                         "over_baseline": n / an_s / fps_base})
        ratios = [r["over_decode"] for r in runs]
        mid = sorted(runs, key=lambda r: r["over_decode"])[len(runs) // 2]
        dec_s, dec_cpu, an_s, summary = mid["dec_s"], mid["dec_cpu"], mid["an_s"], mid["summary"]
        tm = summary["timings_s"]
        fps_dec, fps_an = n / dec_s, n / an_s
        by_base = sorted(r["over_baseline"] for r in runs)
        fps_base = sorted(r["fps_base"] for r in runs)[len(runs) // 2]
        rows.append({"movie": label, "cache": cache, "frames": n, "gb": path.stat().st_size / 1e9,
                     "repeats": repeat, "ratio_min": min(ratios), "ratio_max": max(ratios),
                     "decode_s": dec_s, "analyze_s": an_s,
                     "decode_fps": fps_dec, "analyze_fps": fps_an, "stream_fps": tm["stream_fps"],
                     "baseline_fps": fps_base, "baseline_fps_range": [min(r["fps_base"] for r in runs),
                                                                      max(r["fps_base"] for r in runs)],
                     "analyze_over_decode": fps_an / fps_dec,
                     "stream_over_decode": tm["stream_fps"] / fps_dec,
                     "analyze_over_baseline": by_base[len(by_base) // 2],
                     "baseline_ratio_min": by_base[0], "baseline_ratio_max": by_base[-1],
                     "stream_over_baseline": tm["stream_fps"] / mid["fps_base"],
                     "peak_rss_mb": max(r["rss"] for r in runs) / 1e6,
                     "decode_cpu_over_wall": dec_cpu / dec_s, "timings_s": tm,
                     "celerity_m_s": summary["celerity_m_s"],
                     "read_fraction": summary.get("read_fraction")})
        r = rows[-1]
        fixed = an_s - tm["stream_s"]
        spread = f" (range {r['ratio_min']:.2f}-{r['ratio_max']:.2f} over {repeat})" if repeat > 1 else ""
        bspread = f" (range {by_base[0]:.1f}-{by_base[-1]:.1f})" if repeat > 1 else ""
        print(f"{label} {cache}: {n} frames, {_size(r['gb'])} | decode-only {fps_dec:7.1f} fps "
              f"(cpu/wall {r['decode_cpu_over_wall']:.2f}) | analyze end to end {fps_an:6.1f} fps = "
              f"{r['analyze_over_decode']:.2f} x decode{spread}, {r['analyze_over_baseline']:.1f} x baseline{bspread} "
              f"| streaming pass {tm['stream_fps']:7.1f} fps = {r['stream_over_decode']:.2f} x decode, "
              f"{r['stream_over_baseline']:.0f} x baseline | rest of the run {fixed:.2f} s | baseline "
              f"{fps_base:.1f} fps | peak RSS {r['peak_rss_mb']:.0f} MB{_read(r)}", flush=True)
    return rows


def _size(gb: float) -> str:
    return f"{gb:.2f} GB" if gb >= 0.1 else f"{gb * 1000:.1f} MB"


def _read(r: dict, *, short: bool = False) -> str:
    f = r.get("read_fraction")
    if f is None:
        return ""
    return f"{f:.0%}" if short else f" | read from disk {f:.0%} of the file"


def _range(r: dict) -> str:
    return f" ({r['ratio_min']:.2f}-{r['ratio_max']:.2f})" if r.get("repeats", 1) > 1 else ""


def _brange(r: dict) -> str:
    return f" ({r['baseline_ratio_min']:.0f}-{r['baseline_ratio_max']:.0f})" if r.get("repeats", 1) > 1 else ""


def markdown(rows: list[dict]) -> str:
    """The table of docs/performance.md."""
    head = ("| movie | cache | decode only (fps) | analyze end to end (fps) | ratio (range) | streaming pass (fps) "
            "| ratio | vs baseline: end to end (range) / streaming | peak RSS | file read |\n" + "| --- " * 10 + "|\n")
    return head + "".join(
        f"| {r['movie']}, {r['frames']} fr., {_size(r['gb'])} | {r['cache']} | {r['decode_fps']:.0f} "
        f"| {r['analyze_fps']:.0f} | {r['analyze_over_decode']:.2f}{_range(r)} | {r['stream_fps']:.0f} "
        f"| {r['stream_over_decode']:.2f} | {r['analyze_over_baseline']:.1f}x{_brange(r)} "
        f"/ {r['stream_over_baseline']:.0f}x "
        f"| {r['peak_rss_mb']:.0f} MB | {_read(r, short=True)} |\n" for r in rows)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=600)
    ap.add_argument("--dir", type=Path, default=Path("/tmp/grainplug-bench"))
    ap.add_argument("--formats", default="tiff,avi")
    ap.add_argument("--baseline-frames", type=int, default=40)
    ap.add_argument("--long-frames", type=int, default=0,
                    help="also measure movies of this many frames (--long-formats)")
    ap.add_argument("--long-formats", default="tiff",
                    help="formats of the long movies (tiff-h: a horizontal tube, read band by band)")
    ap.add_argument("--repeat", type=int, default=3,
                    help="(decode, analyze) pairs per movie and cache state; medians are reported")
    ap.add_argument("--json", default=None, help="write the measurements to this file")
    args = ap.parse_args()
    args.dir.mkdir(parents=True, exist_ok=True)
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"{platform.platform()}")
    can_drop = hasattr(os, "posix_fadvise")
    if not can_drop:
        print("(no posix_fadvise: the movies cannot be evicted from memory, every measure is warm)")
    # the interpreter's own files in memory, as after any earlier use of grainplug
    subprocess.run([sys.executable, "-c", "import grainplug.cli.app, grainplug.pipeline, grainplug.outputs, "
                    "grainplug.plotting.worker, scipy.ndimage, av, tifffile, skimage.measure; "
                    "grainplug.plotting.worker._warm_up()"], check=True, env=USER_ENV)
    rows = []

    def only(path: Path) -> Path:
        """Evict the other movies of the folder: the measured one has the memory to itself."""
        for other in args.dir.glob("*/movie_*"):
            if other.is_file() and other != path and other.suffix in (".tif", ".avi", ".mkv", ".mp4"):
                evict(other)
        return path

    names = {"tiff": "TIFF", "avi": "raw AVI", "ffv1": "FFV1 MKV", "h264": "H.264 MP4",
             "tiff-h": "TIFF, horizontal tube", "avi-h": "raw AVI, horizontal tube"}
    for fmt in filter(None, args.formats.split(",")):
        path = only(ensure_movie(args.dir, fmt, args.frames))
        rows += measure(path, names.get(fmt, fmt), args.dir / f"out_{fmt}", can_drop, args.baseline_frames,
                        1 if fmt == "ffv1" else args.repeat)  # FFV1 decodes at ~25 fps: once is enough
    for fmt in filter(None, args.long_formats.split(",") if args.long_frames else []):
        # a run of realistic length ("thousands of frames"), rendered like the others
        path = only(ensure_movie(args.dir, fmt, args.long_frames))
        rows += measure(path, names.get(fmt, fmt), args.dir / f"out_long_{fmt}", can_drop, args.baseline_frames,
                        args.repeat)
    print()
    print(markdown(rows))
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
