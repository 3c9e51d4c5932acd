"""Writing an analysis: the figure worker draws what in-process drawing draws, and survives failure."""

from __future__ import annotations

import pytest

import grainplug as gp
from grainplug.outputs import draw_figures, write_outputs
from grainplug.plotting.worker import FigureWorker
from grainplug.synthetic import SynthConfig, synthesize


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    movie = synthesize(SynthConfig(n_frames=90, seed=5, regime="oscillating"), tmp_path_factory.mktemp("m"),
                       fmt="tiff")
    return gp.analyze(movie.movie)


def _pngs(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.glob("*.png"))}


def test_worker_draws_the_same_figures_as_in_process(result, tmp_path):
    here, there = tmp_path / "here", tmp_path / "there"
    here.mkdir()
    draw_figures(result, here)
    with FigureWorker() as fw:
        assert fw.running
        write_outputs(result, there, report=False, figure_worker=fw)
    assert not fw.running  # stopped and reaped when the block ends
    assert set(_pngs(here)) == {"diagram.png", "frame.png", "spectrum.png"}
    assert _pngs(there) == _pngs(here)


@pytest.mark.parametrize("when", ["before the job", "during the job"])
def test_a_dead_worker_falls_back_to_drawing_here(result, tmp_path, caplog, when):
    with FigureWorker() as fw:
        if when == "before the job":
            fw._proc.kill()
            fw._proc.wait()
            wait = fw.submit(result, tmp_path)
        else:
            wait = fw.submit(result, tmp_path)
            fw._proc.kill()
        paths = wait()
    assert {p.name for p in paths} == {"diagram.png", "frame.png", "spectrum.png"}
    assert all(p.stat().st_size > 10_000 for p in paths)
    if when == "during the job":
        assert "drawing in this process" in caplog.text
