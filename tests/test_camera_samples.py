"""Real camera files (../shared/camera-samples, read by path, never copied): the facts of its README.

Only what grainplug already reads right is checked here; the rest of issue 15 (cine
decimation and packing, NorPix .seq, bit depths) lands with its readers.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from grainplug.errors import MovieError
from grainplug.readers import open_movie

SAMPLES = Path(__file__).resolve().parent.parent.parent / "shared" / "camera-samples"

pytestmark = [
    pytest.mark.skipif(not SAMPLES.is_dir(), reason=f"the real camera samples are not at {SAMPLES}"),
]


@pytest.mark.parametrize(("name", "width", "height", "frames", "fps", "note"), [
    # skipFrame / Save Step: the saved frames are record rate / step apart (the README's facts)
    ("pyMRAW/beam.cihx", 1024, 80, 4, 20.0, "record rate 50000 fps / save step 2500"),
    ("pyidi/data_showcase.cih", 640, 40, 75, 150.0, "record rate 15000 fps / save step 100"),
    ("pyMRAW/ball_12bit.cihx", 384, 384, 15, 30000.0, "record rate 30000 fps"),
])
def test_photron_saved_frame_rate(name, width, height, frames, fps, note):
    pytest.importorskip("pyMRAW")
    with open_movie(SAMPLES / name) as movie:
        info = movie.info
        assert (info.width, info.height, info.n_frames) == (width, height, frames)
        assert info.fps == pytest.approx(fps) and info.fps_source == "file" and info.fps_note == note
        assert movie.timestamps_s()[1] == pytest.approx(1 / fps)


def test_photron_frame_rate_given_by_the_user_wins():
    pytest.importorskip("pyMRAW")
    with open_movie(SAMPLES / "pyMRAW" / "beam.cihx", fps=1000.0) as movie:
        assert movie.info.fps == 1000.0 and movie.info.fps_source == "user" and not movie.info.fps_note


def test_photron_header_without_its_data_is_one_clear_error():
    pytest.importorskip("pyMRAW")
    with pytest.raises(MovieError, match=r"sample_60k_16bit\.mraw is not beside it — copy"):
        open_movie(SAMPLES / "pyMRAW" / "sample_60k_16bit.cih")  # the sample is a header only
