"""Reading recordings back in tests: rerun's own verifier and reader."""

from __future__ import annotations

import os
import subprocess
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pyarrow as pa
import rerun_cli
from rerun.chunk import RrdReader

# The CLI binary itself: `python -m rerun_cli` drops its exit status (it always exits 0).
RERUN_BINARY = os.path.join(os.path.dirname(rerun_cli.__file__), "rerun")


def verify(*paths: Path) -> str:
    """`rerun rrd verify` on each file; fails the test unless it exits 0 and says so."""
    assert paths, "nothing to verify"
    done = subprocess.run(
        [RERUN_BINARY, "rrd", "verify", *map(str, paths)], capture_output=True, text=True, timeout=120
    )
    out = done.stdout + done.stderr
    assert done.returncode == 0 and f"{len(paths)} file" in out and "verified without error" in out, out
    return out


def chunks(path: Path) -> Iterator:
    """The recording's chunks as rerun's reader gives them."""
    yield from RrdReader(path).stream()


def signal_times(path: Path, tolerate_torn_tail: bool = False) -> np.ndarray:
    """sim_time (s) of every `signals` row, in file order. A file cut mid-message (a killed writer)
    raises at its torn end: with `tolerate_torn_tail` the rows before it are returned."""
    out: list[np.ndarray] = []
    try:
        for chunk in chunks(path):
            if chunk.entity_path == "/signals" and not chunk.is_static:
                table = pa.Table.from_batches([chunk.to_record_batch()])
                out.append(table.column("sim_time").cast(pa.int64()).to_numpy() / 1e9)
    except RuntimeError:
        if not tolerate_torn_tail:
            raise
    return np.concatenate(out) if out else np.zeros(0)
