"""The one thing the science asks of a movie: a band of pixels along the tube.

:class:`Band` is the contract between the analysis and the readers. The analysis
(:func:`grainplug.diagram.band_along_tube`) says which pixels of a frame to
average at each position along the tube; a reader
(:meth:`grainplug.readers.Movie.read_band`) returns, for every frame, those
weighted means, reading the pixels the fastest way its format allows. Neither
side knows how the other works: no byte offset, file or callback crosses here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Band:
    """Pixels to average at each position along the tube, in frame coordinates.

    Attributes
    ----------
    rows, cols : ndarray of int, shape (n_positions, n_across)
        Pixel row and column of every sample (within the frame).
    weights : ndarray of float32, shape (n_positions, n_across)
        Weight of every sample; each row sums to 1.
    frame_shape : tuple of int
        ``(height, width)`` of the frames the band was made for.

    Notes
    -----
    The profile of frame :math:`I` at position :math:`i` is
    :math:`p_i = \\sum_j w_{ij}\\, \\bar I(r_{ij}, c_{ij})`, where :math:`\\bar I` is the
    mean over the colour channels (equal weights, so channel order does not matter).
    A reader of YUV-coded video uses the luma plane for :math:`\\bar I` instead (see
    :meth:`grainplug.readers.Movie.read_band`).
    """

    rows: np.ndarray
    cols: np.ndarray
    weights: np.ndarray
    frame_shape: tuple[int, int]

    def __post_init__(self) -> None:
        if not (self.rows.shape == self.cols.shape == self.weights.shape) or self.rows.ndim != 2:
            raise ValueError("rows, cols and weights must be 2-D arrays of one shape")
        h, w = self.frame_shape
        if self.rows.size and (self.rows.min() < 0 or self.rows.max() >= h or self.cols.min() < 0
                               or self.cols.max() >= w):
            raise ValueError(f"the band leaves the {h} x {w} frame")

    @property
    def n_positions(self) -> int:
        """Number of positions along the tube (length of one profile)."""
        return self.rows.shape[0]

    def profile(self, frame: np.ndarray) -> np.ndarray:
        """The band's profile of one frame, computed plainly (the reference).

        Readers compute the same numbers faster (:mod:`grainplug.readers.band`);
        tests hold them to this.
        """
        vals = np.asarray(frame)[self.rows, self.cols].astype(np.float64)
        if vals.ndim == 3:
            vals = vals[..., :3].mean(axis=2) if vals.shape[2] >= 3 else vals.mean(axis=2)
        return (vals * self.weights).sum(axis=1).astype(np.float32)
