"""``make demo``: the main job on the bundled sample movie.

Run as ``python -m grainplug.demo OUT_DIR``.
"""

from __future__ import annotations

import sys
from pathlib import Path

from .cli import main as cli_main

SAMPLE = Path(__file__).resolve().parent / "data" / "sample" / "plugflow_sample.mp4"


def main(argv: list[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    out = Path(args[0] if args else "out/demo")
    out.mkdir(parents=True, exist_ok=True)
    print(f"sample movie: {SAMPLE}")
    code = cli_main(["info", str(SAMPLE)])
    if code:
        return code
    return cli_main(["analyze", str(SAMPLE), "--out", str(out / "sample")])


if __name__ == "__main__":
    sys.exit(main())
