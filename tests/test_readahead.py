"""The read-ahead asks the kernel for what the reader will need, and no more.

:class:`grainplug._system.ReadAhead` is driven here directly, with the kernel calls
(``sendfile`` to ``/dev/null`` through ``read_to_cache``, ``posix_fadvise``)
recorded; the movie that owns one stops and joins it when closed.
"""

from __future__ import annotations

import os
import sys
import threading
import time

import numpy as np
import pytest

from grainplug import _system
from grainplug._system import ReadAhead
from grainplug.band import Band
from grainplug.readers import open_movie
from grainplug.synthetic import SynthConfig, synthesize

KIB = 1024


def _wait(cond, timeout=5.0):
    t0 = time.monotonic()
    while not cond():
        if time.monotonic() - t0 > timeout:
            return False
        time.sleep(0.002)
    return True


def _new_readahead_threads():
    """A function listing the read-ahead threads started since it was made, still alive."""
    before = set(threading.enumerate())
    return lambda: [t for t in threading.enumerate()
                    if t.name == "grainplug-readahead" and t.is_alive() and t not in before]


@pytest.fixture
def recorded(monkeypatch):
    """Every range the read-ahead asks for, ``(start, end)``, whichever call it uses."""
    calls: list[tuple[int, int]] = []
    lock = threading.Lock()

    def record(off, n):
        with lock:
            calls.append((off, off + n))

    monkeypatch.setattr(os, "posix_fadvise", lambda fd, off, n, advice: record(off, n), raising=False)
    monkeypatch.setattr(_system, "read_to_cache", lambda fd, null, off, n: record(off, n))
    return calls


def test_window_follows_advance(tmp_path, monkeypatch, recorded):
    """The file is asked for chunk by chunk, contiguously, up to ``limit`` bytes beyond the
    position the reader reports, never further; to its end once the reader gets there."""
    path = tmp_path / "movie.raw"
    size = 1_000_000
    path.write_bytes(b"\0" * size)
    monkeypatch.setattr(_system, "readahead_chunk_bytes", lambda p: 16 * KIB)
    limit = 200_000
    ours = _new_readahead_threads()
    ra = ReadAhead(path, limit)
    try:
        assert _wait(lambda: ra.requested_to >= limit)
        time.sleep(0.05)
        assert ra.requested_to == limit  # and not a byte further while the reader stays put
        for position in (150_000, 420_000, 700_000):
            ra.advance(position)
            assert _wait(lambda p=position: ra.requested_to >= p + limit)
            time.sleep(0.02)
            assert ra.requested_to == position + limit
        ra.advance(100_000)  # going back asks for nothing more
        time.sleep(0.02)
        assert ra.requested_to == 900_000
        ra.advance(size - 1000)
        assert _wait(lambda: ra.requested_to == size)
        ra.join(5.0)  # nothing left to ask for: the thread ends by itself
        assert ours() == []
    finally:
        ra.close()
        ra.join()
    assert len(recorded) > 50
    assert all(b - a <= 16 * KIB for a, b in recorded)
    assert recorded[0][0] == 0 and recorded[-1][1] == size
    assert all(recorded[i + 1][0] == recorded[i][1] for i in range(len(recorded) - 1))  # once, in order


def test_restrict_only_when_it_skips_enough(tmp_path, recorded):
    path = tmp_path / "f.bin"
    path.write_bytes(b"\0" * 100)
    ra = ReadAhead(path, 10)
    try:
        mib = 1 << 20
        frames = [k * 4 * mib for k in range(10)]
        assert ReadAhead.MIN_SKIP_BYTES == mib
        assert not ra.restrict(frames, 0, 3 * mib + 1)  # skips less than 1 MiB
        assert not ra.restrict(frames, 0, 2 * mib + 1)  # skips less than it keeps
        assert not ra.restrict(frames[:1], 0, 10)  # one frame: no stride to skip in
        assert not ra.restrict(frames, 5, 5)  # nothing to keep
        assert not ra.restricted
        assert ra.restrict(frames, mib, 2 * mib)  # skips 3 MiB, keeps 1
        assert ra.restricted
    finally:
        ra.close()
        ra.join()


def test_restricted_readahead_asks_for_every_band_once(tmp_path, monkeypatch, recorded):
    """Under a restriction the read-ahead asks, in file order, for exactly the band
    of every frame (page-aligned), within its window, and for nothing else."""
    frame, n = 64 * KIB, 40
    path = tmp_path / "frames.raw"
    path.write_bytes(b"\0" * (512 + frame * n))
    offsets = [512 + k * frame for k in range(n)]
    monkeypatch.setattr(_system, "readahead_chunk_bytes", lambda p: 8192)
    monkeypatch.setattr(ReadAhead, "MIN_SKIP_BYTES", 0)
    ours = _new_readahead_threads()
    ra = ReadAhead(path, 0)  # no window yet: nothing is asked for until the reader advances
    try:
        assert ra.restrict(offsets, 10_000, 20_000)
        time.sleep(0.02)
        assert recorded == []
        ra.advance(offsets[5])
        assert _wait(lambda: len(recorded) >= 5)
        time.sleep(0.02)
        assert recorded == [(off + 8192, off + 20_480) for off in offsets[:5]]  # within the window
        ra.advance(path.stat().st_size)
        ra.join(5.0)
        assert ours() == []
    finally:
        ra.close()
        ra.join()
    assert recorded == [(off + 8192, off + 20_480) for off in offsets]


@pytest.mark.skipif(not (hasattr(os, "sendfile") and sys.platform.startswith("linux")),
                    reason="sendfile to /dev/null is used on Linux only")
def test_whole_files_are_read_through_the_kernel_and_fall_back(tmp_path, monkeypatch):
    """A whole-file read-ahead reads with sendfile to /dev/null (pages cached, nothing
    copied out), chunk after chunk to the end; where that fails it asks with
    POSIX_FADV_WILLNEED instead, from where it stopped."""
    path = tmp_path / "movie.raw"
    path.write_bytes(np.random.default_rng(3).bytes(300_000))
    monkeypatch.setattr(_system, "readahead_chunk_bytes", lambda p: 64 * KIB)
    read: list[tuple[int, int]] = []
    real = _system.read_to_cache

    def spy(fd, null, off, n):
        real(fd, null, off, n)  # the real call, on a real file
        read.append((off, n))

    monkeypatch.setattr(_system, "read_to_cache", spy)
    ra = ReadAhead(path, 1e12)
    assert _wait(lambda: ra.requested_to == ra.size)
    ra.close()
    ra.join()
    assert [off for off, _ in read] == list(range(0, 300_000, 64 * KIB))

    asked: list[int] = []
    monkeypatch.setattr(os, "posix_fadvise", lambda fd, off, n, adv: asked.append(off), raising=False)

    def fails_once_started(fd, null, off, n):
        if off >= 128 * KIB:
            raise OSError("no sendfile here")

    monkeypatch.setattr(_system, "read_to_cache", fails_once_started)
    ra = ReadAhead(path, 1e12)
    assert _wait(lambda: ra.requested_to == ra.size)
    ra.close()
    ra.join()
    assert asked == list(range(128 * KIB, 300_000, 64 * KIB))


@pytest.mark.parametrize("closing", ["with block", "close()"])
def test_closing_the_movie_stops_and_joins_its_readahead(tmp_path, monkeypatch, closing):
    movie = synthesize(SynthConfig(n_frames=40), tmp_path, fmt="tiff").movie
    calls: list[int] = []

    def slow_disk(off):  # 5 ms a chunk: the file cannot be read before the movie is closed
        time.sleep(0.005)
        calls.append(off)

    monkeypatch.setattr(os, "posix_fadvise", lambda fd, off, n, adv: slow_disk(off), raising=False)
    monkeypatch.setattr(_system, "read_to_cache", lambda fd, null, off, n: slow_disk(off))
    monkeypatch.setattr(_system, "readahead_chunk_bytes", lambda p: 16 * KIB)
    n_chunks = -(-movie.stat().st_size // (16 * KIB))
    assert n_chunks > 200
    ours = _new_readahead_threads()
    m = open_movie(movie)
    try:
        m.prefetch()
        assert _wait(lambda: len(calls) >= 2)
        assert len(ours()) == 1
        m.prefetch()  # a second call starts no second thread
        assert len(ours()) == 1
    finally:
        if closing == "with block":
            with m:
                pass
        else:
            m.close()
    alive = ours()
    if alive:  # do not leave it running for the tests that follow
        with m:
            pass
    assert alive == [], f"the read-ahead thread outlived {closing}"  # stopped and joined on closing
    assert len(calls) < n_chunks  # stopped, not run to the end
    n_closed = len(calls)
    time.sleep(0.05)
    assert len(calls) == n_closed


def test_band_read_under_a_restricted_readahead_is_unchanged(tmp_path, monkeypatch):
    """Landscape frames, a band across a few rows (a horizontal tube): the read-ahead is
    restricted to those rows, and the profiles are those of the frames all the same."""
    cfg = SynthConfig(n_frames=24, seed=5, flow_direction="right", width_px=64, height_px=400)
    movie = synthesize(cfg, tmp_path, fmt="tiff").movie
    monkeypatch.setattr(ReadAhead, "MIN_SKIP_BYTES", 0)  # the test's frames are small
    taken: list[bool] = []
    original = ReadAhead.restrict

    def spy(self, *args):
        taken.append(original(self, *args))
        return taken[-1]

    monkeypatch.setattr(ReadAhead, "restrict", spy)
    with open_movie(movie) as m:
        h, w = m.info.height, m.info.width
        assert w > 4 * h
        rows = np.repeat(np.arange(28, 36)[None, :], w, axis=0)
        cols = np.repeat(np.arange(w)[:, None], 8, axis=1)
        band = Band(rows, cols, np.full(rows.shape, 1 / 8, np.float32), (h, w))
        want = np.stack([band.profile(f) for f in m.frames()])
        m.prefetch()
        got = m.read_band(band, threads=2)
    assert taken == [True]
    np.testing.assert_allclose(got, want, rtol=1e-5)


def test_quieting_stderr_from_two_threads_gives_it_back():
    """Two threads enter and leave out of order (first in, first out): file descriptor 2 is silenced while
    either is inside, and is the original one again afterwards (not /dev/null)."""
    import os
    import threading

    from grainplug._system import quiet_stderr

    before = os.fstat(2)
    a_in, b_in, a_out = threading.Event(), threading.Event(), threading.Event()
    seen = {}

    def a() -> None:
        with quiet_stderr():
            a_in.set()
            b_in.wait(5)
        a_out.set()

    def b() -> None:
        a_in.wait(5)
        with quiet_stderr():
            b_in.set()
            a_out.wait(5)
            seen["inside"] = os.fstat(2)

    threads = [threading.Thread(target=a), threading.Thread(target=b)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(10)
    after = os.fstat(2)
    null = os.stat(os.devnull)
    assert (seen["inside"].st_dev, seen["inside"].st_ino) == (null.st_dev, null.st_ino)  # still quiet
    assert (after.st_dev, after.st_ino) == (before.st_dev, before.st_ino)
