"""Plugs in the diagram: segmentation into runs and tracking over frames."""

from .segment import Runs, find_runs, plug_mask
from .tracking import Tracks, link

__all__ = ["Runs", "Tracks", "find_runs", "link", "plug_mask"]
