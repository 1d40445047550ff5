"""A hopper log as a NumPy .npz archive: one float64 array per column, their units beside them.

The archive holds `time`, every signal of hopper.logs.schema under its column name, and `units`
(the JSON object column -> unit as written), so that a file whose units are not the schema's is
refused rather than read as if they were; and `world` (JSON, hopper.logs.world) when the log knows
where it was recorded. Gaps are found again from the time column on reading.
"""

from __future__ import annotations

import json
import zipfile
import zlib
from pathlib import Path

import numpy as np

from hopper.logs.schema import COLUMNS, TIME, Log, LogError, find_gaps
from hopper.logs.world import from_meta

FORMAT = "hopper-log-npz-1"  # the archive's `format` entry
ZIP_MAGIC = b"PK\x03\x04"  # a zip file's first local header: what np.savez writes first


def write(log: Log, path: str | Path) -> Path:
    """Write `log` to `path` (compressed .npz; the name is kept as given). Returns the path."""
    path = Path(path)
    units = {TIME.name: TIME.unit} | {name: COLUMNS[name].unit for name in log.signals}
    arrays = {"time": log.time, **log.signals}
    if log.world is not None:
        arrays["world"] = np.array(json.dumps(log.world.to_meta()))
    with open(path, "wb") as out:  # a file object: numpy would append .npz to a bare name
        np.savez_compressed(out, format=np.array(FORMAT), units=np.array(json.dumps(units)), **arrays)
    return path


def read(path: str | Path) -> Log:
    """The log in `path`; LogError (one line: what and where) for a file that is not one, is empty,
    or is cut short or damaged (numpy reads the archive's entries lazily: each is read here, inside
    the one try)."""
    path = Path(path)
    try:
        with open(path, "rb") as head:
            magic = head.read(4)
    except FileNotFoundError:
        raise LogError(f"{path}: no such file") from None
    except OSError as exc:
        raise LogError(f"{path}: cannot read it ({exc.strerror or exc})") from None
    if not magic:
        raise LogError(f"{path}: empty file (not a .npz log)")
    if magic != ZIP_MAGIC:  # numpy would try it as .npy or a pickle and say so, which misleads
        raise LogError(f"{path}: not a .npz archive (a .npz is a zip file; this one does not start as one)")
    try:
        return _read(path)
    except LogError:  # a ValueError too: what _read found, said already
        raise
    except (OSError, EOFError, ValueError, zipfile.BadZipFile, zlib.error) as exc:
        raise LogError(f"{path}: not a .npz archive, or one cut short or damaged ({exc})") from None


def _read(path: Path) -> Log:
    """The log in the zip archive `path`: numpy's errors of a damaged archive are left to read."""
    with np.load(path, allow_pickle=False) as archive:
        names = set(archive.files)
        if "format" not in names or str(archive["format"]) != FORMAT:
            raise LogError(f"{path}: not a hopper log (its 'format' entry is not {FORMAT!r})")
        units = json.loads(str(archive["units"])) if "units" in names else {}
        for name, unit in units.items():
            expected = COLUMNS[name].unit if name in COLUMNS else TIME.unit if name == TIME.name else None
            if expected is not None and unit != expected:
                raise LogError(f"{path}: column {name} is in {unit!r}, the schema's unit is {expected!r}")
        if "time" not in names:
            raise LogError(f"{path}: no time column")
        time = np.asarray(archive["time"], dtype=np.float64)
        world = None
        if "world" in names:
            try:
                world = from_meta(json.loads(str(archive["world"])))
            except (ValueError, AttributeError) as exc:
                raise LogError(f"{path}: {exc}") from None
        columns = sorted(names - {"format", "units", "time", "world"})
        signals = {n: np.asarray(archive[n], dtype=np.float64) for n in columns}
    return Log(time, signals, str(path), find_gaps(time), world)
