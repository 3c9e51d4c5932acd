"""The spatiotemporal diagram: the band it is made from, normalised from its own data."""

from .extract import Diagram, band_along_tube, display_stride
from .normalize import Normalized, normalize

__all__ = ["Diagram", "Normalized", "band_along_tube", "display_stride", "normalize"]
