"""Recording paths: check that a .rrd file can be written, name new session files."""

from __future__ import annotations

import datetime
from pathlib import Path


def check_writable(path: str | Path) -> Path:
    """The absolute .rrd path, or ValueError with a one-line reason why it cannot be written."""
    p = Path(path).expanduser().absolute()
    if p.suffix != ".rrd":
        raise ValueError(f"recording path {str(path)!r} must end in .rrd")
    if p.is_dir():
        raise ValueError(f"recording path {str(p)!r} is a directory")
    if not p.parent.is_dir():
        raise ValueError(f"cannot write recording {str(p)!r}: directory {str(p.parent)!r} does not exist")
    existed = p.exists()
    try:  # really open it: permission bits say little for root, read-only mounts or ACLs
        with open(p, "ab"):
            pass
    except OSError as exc:
        raise ValueError(f"cannot write recording {str(p)!r}: {exc.strerror or exc}") from None
    if not existed:
        p.unlink(missing_ok=True)
    return p


def session_path(folder: str | Path, prefix: str = "hopper") -> Path:
    """A new path `folder/prefix-YYYYmmdd-HHMMSS.rrd` (never an existing file). The folder is made if
    missing, in a folder that exists: ValueError in one line if it cannot be (a missing parent is
    refused, never made, as the dashboard's start-up check does)."""
    directory = Path(folder).expanduser()
    try:
        directory.mkdir(exist_ok=True)
    except OSError as exc:
        raise ValueError(f"cannot make sessions folder {str(directory)!r}: {exc.strerror or exc}") from None
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    path, n = directory / f"{prefix}-{stamp}.rrd", 2
    while path.exists():
        path, n = directory / f"{prefix}-{stamp}-{n}.rrd", n + 1
    return path


def part_path(base: str | Path, index: int) -> Path:
    """The `index`-th part (from 1) of a recording rolled over into numbered files: a.rrd -> a-001.rrd."""
    if index < 1:
        raise ValueError(f"part index must be at least 1, got {index}")
    p = Path(base)
    return p.with_name(f"{p.stem}-{index:03d}{p.suffix}")
