"""What the machine offers (standard library only: imported before numpy by the CLI)."""

from __future__ import annotations

import collections
import os
import threading

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

    Requests go out in chunks of the disk's read-ahead size (one call reads no
    more), at most ``DEPTH`` at a time, up to ``limit`` bytes beyond the position
    given to :meth:`advance`; the calls release the GIL, so the reads overlap
    whatever the program does. :meth:`pause` lets the program's own small reads
    (file headers, an index, sampled frames) have the disk first. One instance per
    file at a time (:meth:`for_path`), so the command line can start it before its
    imports and the reader adopt it. Only a hint: nothing is read into the
    program, and without ``posix_fadvise`` it does nothing.
    """

    #: read-ahead chunks queued at the disk at once
    DEPTH = 8

    _registry: dict[str, ReadAhead] = {}  # noqa: RUF012 - shared on purpose
    _registry_lock = threading.Lock()

    def __init__(self, path: str | os.PathLike, limit: float, *, start: int = 0) -> None:
        self.path = os.path.realpath(os.fspath(path))
        self.size = os.path.getsize(self.path)
        self.limit = float(limit)
        self._to = int(start)  # requested so far
        self._target = int(min(self.size, start + self.limit))
        self._closed = False
        self._paused = False
        self._cond = threading.Condition()
        self._chunk = readahead_chunk_bytes(self.path)
        self._thread = None
        if hasattr(os, "posix_fadvise") and self.size > 0:
            with ReadAhead._registry_lock:
                ReadAhead._registry[self.path] = self
            self._thread = threading.Thread(target=self._run, name="grainplug-readahead", daemon=True)
            self._thread.start()

    @classmethod
    def for_path(cls, path: str | os.PathLike) -> ReadAhead | None:
        """The running read-ahead of ``path``, if any."""
        with cls._registry_lock:
            ra = cls._registry.get(os.path.realpath(os.fspath(path)))
        return ra if ra is not None and not ra._closed else None

    def advance(self, position: int) -> None:
        """The reader is at byte ``position``: keep ``limit`` bytes beyond it requested."""
        with self._cond:
            target = int(min(self.size, position + self.limit))
            if target > self._target:
                self._target = target
                self._cond.notify()

    def pause(self) -> None:
        """Ask for nothing more until :meth:`resume` (requests already queued complete)."""
        with self._cond:
            self._paused = True

    def resume(self) -> None:
        with self._cond:
            self._paused = False
            self._cond.notify()

    @property
    def requested_to(self) -> int:
        """Bytes requested from the start of the file (or the given start) so far."""
        return self._to

    def close(self) -> None:
        """Stop asking (requests already made complete on their own)."""
        with self._cond:
            self._closed = True
            self._cond.notify()
        with ReadAhead._registry_lock:
            if ReadAhead._registry.get(self.path) is self:
                del ReadAhead._registry[self.path]

    def _run(self) -> None:
        try:
            fd = os.open(self.path, os.O_RDONLY)
        except OSError:
            return
        inflight: collections.deque[int] = collections.deque()
        try:
            while True:
                with self._cond:
                    while not self._closed and self._to < self.size and (self._paused or self._to >= self._target):
                        self._cond.wait()
                    if self._closed or self._to >= self.size:
                        return
                    lo = self._to
                    hi = min(self._target, lo + self._chunk)
                try:
                    os.posix_fadvise(fd, lo, hi - lo, os.POSIX_FADV_WILLNEED)
                    inflight.append(hi)
                    if len(inflight) > self.DEPTH:
                        # wait for the oldest request (its last byte): only DEPTH chunks queue
                        # at the disk, so a pause takes effect and other reads are not stuck
                        # behind the whole file
                        os.pread(fd, 1, inflight.popleft() - 1)
                except OSError:
                    return
                with self._cond:
                    self._to = hi
        finally:
            os.close(fd)
