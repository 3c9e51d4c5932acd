"""Frames are streamed: the analysis' memory does not grow with the movie's length."""

from __future__ import annotations

import tracemalloc

import pytest

from grainplug import AnalysisParams, analyze
from grainplug.synthetic import SynthConfig, synthesize


def _peak_bytes(movie) -> int:
    tracemalloc.start()
    try:
        analyze(movie, AnalysisParams(mm_per_px=0.185))
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("fmt", ["tiff", "avi"])
def test_peak_memory_independent_of_length(tmp_path, fmt):
    short = synthesize(SynthConfig(n_frames=100, seed=3), tmp_path / "short", fmt=fmt)
    long = synthesize(SynthConfig(n_frames=800, seed=3), tmp_path / "long", fmt=fmt)
    frame_bytes = 640 * 128 * 3
    a, b = _peak_bytes(short.movie), _peak_bytes(long.movie)
    # 700 more frames would be 172 MB held; what may grow is the diagram and the edge tables
    # (a few kB per frame)
    assert b - a < 25 * frame_bytes, (a, b)
    # and far from holding the movie: the tube is found on 32 sampled frames
    assert b < 200 * frame_bytes < 800 * frame_bytes
