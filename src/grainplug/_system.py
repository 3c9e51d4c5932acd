"""What the machine offers (standard library only: imported before numpy by the CLI)."""

from __future__ import annotations

import collections
import contextlib
import os
import sys
import threading
from collections.abc import Iterator, Sequence

#: share of the free memory that read-ahead may ask for beyond a reader's position
READAHEAD_MEMORY_SHARE = 0.5


def free_memory_bytes() -> float:
    """Memory the system can give without swapping (MemAvailable), or 1 GiB when unknown."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return float(2**30)


def read_to_cache(fd: int, null_fd: int, offset: int, count: int) -> None:
    """Read ``count`` bytes of ``fd`` from ``offset`` into the page cache, copying nothing out.

    ``sendfile`` to ``/dev/null``: the bytes go through the kernel's ordinary read path,
    whose read-ahead caches them in large folios, which later memory maps of the file
    map several times faster than the single pages ``POSIX_FADV_WILLNEED`` leaves
    (measured: a 600-frame stream in 0.05 s instead of 0.16-0.25 s). Raises
    ``OSError`` where the system cannot do it.
    """
    end = offset + count
    while offset < end:
        sent = os.sendfile(null_fd, fd, offset, end - offset)
        if sent <= 0:  # the file ends here
            return
        offset += sent


def readahead_chunk_bytes(path: str | os.PathLike) -> int:
    """The most the kernel reads for one read-ahead request on ``path``'s disk.

    Linux caps each ``POSIX_FADV_WILLNEED`` at the device's read-ahead size
    (``/sys/.../queue/read_ahead_kb``); asking for more in one call reads no more.
    """
    try:
        st = os.stat(path)
        dev = os.path.realpath(f"/sys/dev/block/{os.major(st.st_dev)}:{os.minor(st.st_dev)}")
        for queue in (os.path.join(dev, "queue"), os.path.join(os.path.dirname(dev), "queue")):
            f = os.path.join(queue, "read_ahead_kb")
            if os.path.exists(f):
                with open(f) as fh:
                    return max(128, int(fh.read().strip())) * 1024
    except (OSError, ValueError, AttributeError):
        pass
    return 2 << 20


class ReadAhead:
    """Asks the kernel to read a file ahead of its reader, from a background thread.

    The file is read in chunks of the disk's read-ahead size, up to ``limit``
    bytes beyond the position given to :meth:`advance`, by :func:`read_to_cache`
    (nothing copied out; large folios), or where that is not available by
    ``POSIX_FADV_WILLNEED`` requests (Linux caps each at the disk's read-ahead
    size, hence the chunks), at most ``DEPTH`` queued at a time. A restricted
    read-ahead (:meth:`restrict`) asks for its many small ranges with
    ``WILLNEED``, all queued at once. The calls release the GIL, so the reads
    overlap whatever the program does. It is owned by the movie that started it
    (:meth:`grainplug.readers.Movie.prefetch`) and stopped by :meth:`close` when that
    movie is closed. Only a hint: nothing is read into the program, and without
    ``posix_fadvise`` it does nothing.
    """

    #: read-ahead chunks queued at the disk at once (in bytes: DEPTH chunks)
    DEPTH = 8
    #: a frame's bytes left out of the read-ahead must be at least this many
    #: (and as many as it keeps) for :meth:`restrict` to take effect: skipping
    #: less would not save a disk's time
    MIN_SKIP_BYTES = 1 << 20
    PAGE = 4096

    def __init__(self, path: str | os.PathLike, limit: float, *, start: int = 0) -> None:
        self.path = os.path.realpath(os.fspath(path))
        self.size = os.path.getsize(self.path)
        self.limit = float(limit)
        self._to = int(start)  # requested so far
        self._target = int(min(self.size, start + self.limit))
        self._closed = False
        self._cond = threading.Condition()
        self._chunk = readahead_chunk_bytes(self.path)
        self._frames: Sequence[int] | None = None  # restricted: offsets of the frames ...
        self._span = (0, 0)  # ... and the bytes of each frame to ask for
        self._next_frame = 0
        self._thread = None
        if hasattr(os, "posix_fadvise") and self.size > 0:
            self._thread = threading.Thread(target=self._run, name="grainplug-readahead")
            self._thread.start()

    def advance(self, position: int) -> None:
        """The reader is at byte ``position``: keep ``limit`` bytes beyond it requested."""
        with self._cond:
            target = int(min(self.size, position + self.limit))
            if target > self._target:
                self._target = target
                self._cond.notify()

    def restrict(self, frame_offsets: Sequence[int], lo: int, hi: int) -> bool:
        """From now on ask only for bytes ``[lo, hi)`` of every frame.

        ``frame_offsets[k]`` is the file offset of frame ``k``'s first byte. Taken
        only where it skips at least :data:`MIN_SKIP_BYTES` of every frame and at
        least as much as it keeps (a horizontal tube crossing a wide frame, say);
        otherwise the whole file is still asked for. Returns whether it was taken.
        """
        n = len(frame_offsets)
        if n < 2 or not 0 <= lo < hi:
            return False
        stride = min(int(frame_offsets[k + 1]) - int(frame_offsets[k]) for k in range(n - 1))
        skipped = stride - (hi - lo)
        if skipped < max(self.MIN_SKIP_BYTES, hi - lo):
            return False
        with self._cond:
            self._frames = frame_offsets
            self._span = (lo // self.PAGE * self.PAGE, -(-hi // self.PAGE) * self.PAGE)
            self._next_frame = 0
            self._cond.notify()
        return True

    @property
    def restricted(self) -> bool:
        """Whether only part of each frame is asked for (:meth:`restrict`)."""
        return self._frames is not None

    @property
    def requested_to(self) -> int:
        """Bytes requested from the start of the file (or the given start) so far."""
        return self._to

    def close(self) -> None:
        """Stop asking (requests already made complete on their own)."""
        with self._cond:
            self._closed = True
            self._cond.notify()

    def join(self, timeout: float | None = None) -> None:
        """Wait for the background thread to end (after :meth:`close`)."""
        if self._thread is not None:
            self._thread.join(timeout)

    def _next_request(self) -> tuple[int, int] | None:
        """The next byte range to ask for, ``(lo, lo)`` when none is due yet, None when
        all is asked for (called under the lock)."""
        if self._frames is None:
            if self._to >= self.size:
                return None
            return self._to, min(self._target, self._to + self._chunk)
        a, b = self._span
        n = len(self._frames)
        while self._next_frame < n and int(self._frames[self._next_frame]) + b <= self._to:
            self._next_frame += 1  # asked for already, in full or in part
        if self._next_frame >= n:
            return None
        start = int(self._frames[self._next_frame])
        lo = max(self._to, start + a)
        return (lo, lo) if lo >= self._target else (lo, min(start + b, self.size))

    def _run(self) -> None:
        try:
            fd = os.open(self.path, os.O_RDONLY)
        except OSError:
            return
        inflight: collections.deque[tuple[int, int]] = collections.deque()
        queued = 0
        null_fd = -1
        if hasattr(os, "sendfile") and sys.platform.startswith("linux"):
            try:
                null_fd = os.open(os.devnull, os.O_WRONLY)
            except OSError:
                null_fd = -1
        try:
            while True:
                with self._cond:
                    while True:
                        if self._closed:
                            return
                        req = self._next_request()
                        if req is None:
                            return
                        if req[1] > req[0]:
                            break
                        self._cond.wait()
                    lo, hi = req
                    whole = self._frames is None
                if whole and null_fd >= 0:
                    try:
                        read_to_cache(fd, null_fd, lo, hi - lo)
                        with self._cond:
                            self._to = hi
                        continue
                    except OSError:  # not on this file system: ask the kernel to read instead
                        os.close(null_fd)
                        null_fd = -1
                try:
                    os.posix_fadvise(fd, lo, hi - lo, os.POSIX_FADV_WILLNEED)
                    inflight.append((hi, hi - lo))
                    queued += hi - lo
                    while queued > self.DEPTH * self._chunk:
                        # wait for the oldest request (its last byte): only DEPTH chunks' worth
                        # queue at the disk, so that a close takes effect and other reads are not
                        # stuck behind the whole file
                        end, nbytes = inflight.popleft()
                        os.pread(fd, 1, end - 1)
                        queued -= nbytes
                except OSError:
                    return
                with self._cond:
                    self._to = hi
        finally:
            os.close(fd)
            if null_fd >= 0:
                os.close(null_fd)


class _QuietStderr:
    """File descriptor 2 sent to nowhere while any thread is inside :meth:`__call__`'s block."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._depth = 0
        self._saved = -1

    @contextlib.contextmanager
    def __call__(self) -> Iterator[None]:
        with self._lock:
            if self._depth == 0:
                try:
                    self._saved = os.dup(2)
                    null = os.open(os.devnull, os.O_WRONLY)
                    try:
                        os.dup2(null, 2)
                    finally:
                        os.close(null)
                except OSError:  # no stderr to silence
                    self._saved = -1
            self._depth += 1
        try:
            yield
        finally:
            with self._lock:
                self._depth -= 1
                if self._depth == 0 and self._saved >= 0:
                    os.dup2(self._saved, 2)
                    os.close(self._saved)
                    self._saved = -1


#: what C libraries (FFmpeg, OpenCV) print on file descriptor 2 is sent to nowhere while the block runs. The
#: descriptor is the whole process's: the first thread in silences it, the last one out gives it back (keep
#: the block to the library call whose noise it hides: other threads' messages are lost meanwhile).
quiet_stderr = _QuietStderr()
