"""Read or write a hopper log by its file's suffix: one table of readers and one of writers."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from hopper.logs import csv_log, mcap_log, npz, rrd_log
from hopper.logs.schema import Log, LogError

# Suffix -> the module function that reads it (each returns a validated Log, gaps marked).
# A new format is one module with read (and write) and one line in each table.
READERS: dict[str, Callable[[str | Path], Log]] = {
    ".csv": csv_log.read,
    ".mcap": mcap_log.read,
    ".npz": npz.read,
    ".rrd": rrd_log.read,  # our own recordings (hopper.telemetry)
}
# Suffix -> the function that writes a Log there (a .rrd is a recording, not a log: read only).
WRITERS: dict[str, Callable[[Log, str | Path], Path]] = {
    ".csv": csv_log.write,
    ".mcap": mcap_log.write,
    ".npz": npz.write,
}


def _suffix(path: Path, table: dict[str, Callable], what: str) -> str:
    suffix = path.suffix.lower()
    if suffix not in table:
        raise LogError(f"{path}: cannot {what} a log as '{suffix or 'no suffix'}'; known: {', '.join(table)}")
    return suffix


def read_log(path: str | Path) -> Log:
    """The log at `path`, read by its suffix's reader; LogError (what and where) for a bad file."""
    path = Path(path)
    reader = READERS[_suffix(path, READERS, "read")]
    if not path.is_file():
        raise LogError(f"{path}: no such file")
    return reader(path)


def writer(path: str | Path) -> Callable[[Log, str | Path], Path]:
    """The writer of `path`'s suffix; LogError naming the known ones (checked before any work)."""
    path = Path(path)
    return WRITERS[_suffix(path, WRITERS, "write")]


def write_log(log: Log, path: str | Path) -> Path:
    """Write `log` at `path` in its suffix's format; returns the path."""
    return writer(path)(log, path)
