"""Read or write a hopper log by its file's suffix: one table of readers and one of writers."""

from __future__ import annotations

import importlib
from collections.abc import Callable
from pathlib import Path

from hopper.logs.schema import Log, LogError

# Suffix -> the module of hopper.logs that reads it (its `read` returns a validated Log, gaps marked).
# A new format is one module with read (and write) and one line in each table. Modules are imported
# when a file of theirs is read or written: rerun's and pyarrow's imports took most of a second of
# every `hopper-sim` start, `--help` included.
READERS: dict[str, str] = {
    ".csv": "csv_log",
    ".mcap": "mcap_log",
    ".npz": "npz",
    ".rrd": "rrd_log",  # our own recordings (hopper.telemetry)
}
# Suffix -> the module whose `write` writes a Log there (a .rrd is a recording, not a log: read only).
WRITERS: dict[str, str] = {
    ".csv": "csv_log",
    ".mcap": "mcap_log",
    ".npz": "npz",
}


def _function(table: dict[str, str], suffix: str, name: str) -> Callable:
    return getattr(importlib.import_module(f"hopper.logs.{table[suffix]}"), name)


def _suffix(path: Path, table: dict[str, str], what: str) -> str:
    suffix = path.suffix.lower()
    if suffix not in table:
        raise LogError(f"{path}: cannot {what} a log as '{suffix or 'no suffix'}'; known: {', '.join(table)}")
    return suffix


def read_log(path: str | Path) -> Log:
    """The log at `path`, read by its suffix's reader; LogError (what and where) for a bad file."""
    path = Path(path)
    reader = _function(READERS, _suffix(path, READERS, "read"), "read")
    if not path.is_file():
        raise LogError(f"{path}: no such file")
    return reader(path)


def writer(path: str | Path) -> Callable[[Log, str | Path], Path]:
    """The writer of `path`'s suffix; LogError naming the known ones (checked before any work)."""
    path = Path(path)
    return _function(WRITERS, _suffix(path, WRITERS, "write"), "write")


def write_log(log: Log, path: str | Path) -> Path:
    """Write `log` at `path` in its suffix's format; returns the path."""
    return writer(path)(log, path)
