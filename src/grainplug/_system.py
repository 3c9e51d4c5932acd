"""What the machine offers (standard library only: imported before numpy by the CLI)."""

from __future__ import annotations

import os


def free_memory_bytes() -> float:
    """Memory the system can give without swapping (MemAvailable), or 1 GiB when unknown."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return float(2**30)
