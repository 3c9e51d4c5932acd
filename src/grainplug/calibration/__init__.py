"""Calibration: where the tube is and how many mm a pixel spans."""

from .tube import TubeGeometry, find_tube, mean_and_variation, to_grey

__all__ = ["TubeGeometry", "find_tube", "mean_and_variation", "to_grey"]
