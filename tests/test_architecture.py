"""The layers hold: import-linter's contracts of pyproject.toml (one-way layers, no cycle in any package) are kept.

A failure names the import that breaks a contract; docs/architecture.md draws the layers. Imports made only
for type checking do not count; imports inside functions do.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_import_contracts_are_kept():
    # a process of its own: import-linter builds its graph from the installed package's files and prints a report
    r = subprocess.run([sys.executable, "-c", "import sys; from importlinter.cli import lint_imports; "
                        "sys.exit(lint_imports(config_filename='pyproject.toml', no_cache=True, no_logo=True))"],
                       capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "2 kept, 0 broken" in r.stdout, r.stdout


def test_a_science_module_never_opens_a_file():
    """calibration/, diagram/, plugs/ and measures/ take arrays and frozen dataclasses: none of them names a file
    function (the calibration's files are read and written by grainplug.calibration_files)."""
    words = ("open(", ".read_text(", ".write_text(", ".read_bytes(", "imread", "imwrite", "savefig", "np.load(",
             "np.save")
    src = ROOT / "src" / "grainplug"
    found = [f"{p.relative_to(src)}: {w}" for pkg in ("calibration", "diagram", "plugs", "measures")
             for p in sorted((src / pkg).glob("*.py")) for w in words if w in p.read_text(encoding="utf-8")]
    assert not found, found
