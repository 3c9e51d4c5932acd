"""Shared fixtures: seeded synthetic movies, headless matplotlib."""

from __future__ import annotations

import os

os.environ.setdefault("MPLBACKEND", "Agg")

import numpy as np
import pytest


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


def grey(frame: np.ndarray) -> np.ndarray:
    """Mean over colour channels, as float."""
    f = frame.astype(float)
    return f.mean(axis=2) if f.ndim == 3 else f
