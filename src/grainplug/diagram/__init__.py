"""The spatiotemporal diagram: built from the movie, normalised from its own data."""

from .extract import BandSampler, Diagram, build_diagram, build_diagram_blocks
from .normalize import Normalized, normalize

__all__ = ["BandSampler", "Diagram", "Normalized", "build_diagram", "build_diagram_blocks", "normalize"]
