"""A .rrd file written by our own thread from a pipe: exact byte counts, and a full disk seen rather than hung on.

rerun's FileSink, given a path, writes from a Rust thread that logs a full disk (ENOSPC) and then
never completes a flush: `RecordingStream.flush()` times out and `disconnect()` blocks for good,
which would freeze the simulation loop and leave a file without its footer. So the FileSink writes
into a pipe (`/dev/fd/N`), and a Python thread copies what it encodes to the file with plain
`os.write` calls, where a full disk is an OSError we handle. Bytes leave the process as soon as
rerun encodes them, whole messages at a time: a `kill -9` loses only what rerun had not yet
encoded, and leaves a file that ends on a whole message.

A full disk leaves room for the footer thanks to a Reserve: space held back in a hidden file next
to the recording, released at the first ENOSPC so the rest of the batch in flight and the footer
(rerun's manifest of every chunk) still fit; the recording is then stopped (hopper.telemetry.recorder).
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import select
import struct
import threading
import time
from collections.abc import Callable
from pathlib import Path

import rerun as rr

log = logging.getLogger(__name__)

CHUNK_READ = 1 << 16  # bytes per read from the pipe
STREAM_MAGIC, STREAM_HEADER, MESSAGE_HEADER = b"RRF2", 12, 16  # rrd stream layout (rerun 0.41), see _complete
END_KIND, MAX_KIND, MAX_MESSAGE = 0, 16, 1 << 30  # beyond these the bytes are not framed as expected
# Errors that mean "no more room" rather than a broken file: a full disk, a quota, a file-size limit.
NO_ROOM = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)
MIN_RESERVE = 512 * 1024  # bytes: a batch in flight (~70 kB a second of simulation) and a small footer
FOOTER_BYTES_PER_CHUNK = 400  # bytes of manifest per chunk (measured ~370 with rerun 0.41), with margin


def reserve_path(path: Path) -> Path:
    """The hidden reserve file kept beside `path`."""
    return path.with_name(f".{path.name}.reserve")


class Reserve:
    """Disk space held in a preallocated hidden file, released when the disk is full.

    `size` bytes are really allocated (posix_fallocate), so a filesystem that fills up later still
    has them for us. grow() keeps the reserve ahead of the footer as a recording gets longer.
    """

    def __init__(self, path: Path, size: int = MIN_RESERVE) -> None:
        self.path = path
        self.size = 0
        self.released = False
        self._lock = threading.Lock()
        self.path.unlink(missing_ok=True)  # a reserve left by a killed process
        if not self.grow(size):
            raise OSError(errno.ENOSPC, f"no room for a {size / 1e6:.1f} MB reserve beside the recording")

    def grow(self, size: int) -> bool:
        """Hold at least `size` bytes; False if the filesystem cannot give them (it is full)."""
        with self._lock:
            if self.released:
                return False
            if size <= self.size:
                return True
            try:
                fd = os.open(self.path, os.O_WRONLY | os.O_CREAT, 0o600)
                try:
                    os.posix_fallocate(fd, 0, size)
                finally:
                    os.close(fd)
            except OSError as exc:
                if exc.errno in NO_ROOM:
                    return False
                raise
            self.size = size
            return True

    def release(self) -> bool:
        """Give the space back; True if it held any (the first call after a grow)."""
        with self._lock:
            held = not self.released and self.size > 0
            self.released = True
            self.size = 0
            self.path.unlink(missing_ok=True)
            return held

    def discard(self) -> None:
        """Remove the reserve file at the end of a recording."""
        with self._lock:
            self.released = True
            self.path.unlink(missing_ok=True)


class PipedFile:
    """One .rrd file: `sink` is the rerun FileSink to attach; a thread copies its bytes to `path`.

    `written` counts bytes on disk (in the page cache: they survive the process being killed).
    `lag_s()` is how long since the thread last found the pipe empty, i.e. had written everything
    rerun had encoded: near 0 while the disk keeps up, growing while the pipe stays full.
    `full` is set at the first "no room" error (after which the reserve's space is used);
    `error` when a write fails for good: the thread then drains the pipe and drops the bytes, so
    that rerun never blocks on a file it can no longer write.
    """

    def __init__(self, path: Path, reserve: Reserve, on_full: Callable[[str], None] | None = None) -> None:
        self.path = path
        self._on_full = on_full  # called once, on this file's thread, at the first "no room"
        self.written = 0
        self.busy_s = 0.0  # s this file's thread spent storing bytes: the disk's busy time
        self.full: str | None = None
        self.error: str | None = None
        self._reserve = reserve
        self._caught_up = time.monotonic()  # the last moment the pipe was found empty
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        self._read, self._write_end = os.pipe()
        self.sink = rr.FileSink(f"/dev/fd/{self._write_end}")  # opens its own descriptor of the pipe
        self._thread = threading.Thread(target=self._pump, name=f"rrd-writer {path.name}", daemon=True)
        self._thread.start()

    def attached(self) -> None:
        """Call once the sink is attached (it has opened the pipe): the pipe then ends with the sink."""
        if self._write_end >= 0:
            os.close(self._write_end)
            self._write_end = -1

    def join(self, timeout: float = 10.0) -> bool:
        """Wait for the thread to write the last bytes (after the sink is detached); True if it did."""
        self.attached()
        self._thread.join(timeout)
        return not self._thread.is_alive()

    def lag_s(self) -> float:
        """Seconds since the pipe was last found empty (about 0 while the disk keeps up)."""
        return time.monotonic() - self._caught_up

    def _pump(self) -> None:
        """Copy the pipe to the file, whole rrd messages at a time (framing below) until the sink closes it."""
        pending, framed, header_done = bytearray(), True, False
        try:
            while data := self._next():
                if self.error is not None:
                    continue  # drain: rerun must never block on a file we can no longer write
                if not framed:
                    self._timed_store(memoryview(data))
                    continue
                pending += data
                end, header_done, framed = _complete(pending, header_done)
                if end:
                    self._timed_store(memoryview(bytes(pending[:end])))
                    del pending[:end]
                if not framed and pending:
                    self._timed_store(memoryview(bytes(pending)))
                    pending.clear()
            if pending and self.error is None:
                self._store(memoryview(bytes(pending)))  # a torn end: only if the sink stopped mid-message
        finally:
            os.close(self._read)
            with contextlib.suppress(OSError):
                os.fsync(self._fd)  # a finished part is on disk, not only in the page cache
            os.close(self._fd)

    def _next(self) -> bytes:
        """The pipe's next bytes (b"" once the sink closed it); an empty pipe means caught up."""
        if not select.select([self._read], [], [], 0)[0]:
            self._caught_up = time.monotonic()  # everything rerun encoded so far is in the file
            data = os.read(self._read, CHUNK_READ)  # waits for rerun's next bytes: not behind meanwhile
            self._caught_up = time.monotonic()
            return data
        return os.read(self._read, CHUNK_READ)

    def _timed_store(self, data: memoryview) -> None:
        start = time.monotonic()
        self._store(data)
        self.busy_s += time.monotonic() - start

    def _store(self, data: memoryview) -> None:
        while data:
            try:
                n = os.write(self._fd, data)
            except OSError as exc:
                if exc.errno in NO_ROOM and self._reserve.release():
                    self.full = f"{os.strerror(exc.errno)} writing {self.path.name}"
                    log.warning("recording: %s; using the reserve to finish the file", self.full)
                    if self._on_full is not None:
                        self._on_full(self.full)  # stop sending now: the reserve is for the footer
                    continue
                self.error = f"{exc.strerror or exc} writing {self.path.name} after {self.written} bytes"
                log.error("recording: %s; the rest of this file is dropped", self.error)
                return
            self.written += n
            data = data[n:]


def _complete(buffer: bytearray, header_done: bool) -> tuple[int, bool, bool]:
    """How many leading bytes of `buffer` are whole rrd units; (end, header_done, still_framed).

    An .rrd stream is a 12-byte header (b"RRF2", version, options), then messages of a 16-byte
    header (kind, length: little-endian u64) and `length` bytes; kind 0 ends the stream and its
    payload, the footer, runs to the end. Writing whole messages in one write() each means a
    process killed between writes leaves a file that ends on a message: rerun's reader reads it
    as it is (it refuses a torn last message; `rerun rrd migrate` repairs such a file). Anything
    unexpected (another format) turns framing off: the bytes are then copied as they come.
    """
    end = 0
    if not header_done:
        if len(buffer) < STREAM_HEADER:
            return 0, False, True
        if buffer[:4] != STREAM_MAGIC:
            log.warning("recording: not the rrd stream layout this writer knows; copying it unframed")
            return 0, False, False
        end, header_done = STREAM_HEADER, True
    while len(buffer) - end >= MESSAGE_HEADER:
        kind, length = struct.unpack_from("<QQ", buffer, end)
        if kind == END_KIND or kind > MAX_KIND or length > MAX_MESSAGE:
            return end, header_done, False  # the footer (or something unknown): copy the rest as it comes
        if len(buffer) - end < MESSAGE_HEADER + length:
            break
        end += MESSAGE_HEADER + length
    return end, header_done, True
