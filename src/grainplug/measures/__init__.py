"""Measures from the tracked plugs: celerity, oscillation, regime, lengths."""

from .lengths import Lengths, measure_lengths
from .motion import Motion, measure_motion

__all__ = ["Lengths", "Motion", "measure_lengths", "measure_motion"]
