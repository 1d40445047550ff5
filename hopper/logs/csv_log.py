"""A hopper log as CSV: a header of `name [unit]` columns (README, "Logs in"), then one row a sample.

The names are the schema's (hopper.logs.schema); each unit is the column's SI unit or one that
`schema.UNITS` converts (deg, deg/s, rpm, ms, Nm), checked before the rows are read. The rows are
parsed by pyarrow.csv (multi-threaded, in blocks): a 1-hour log at 1 kHz, 3.6 M rows, is read
in seconds. A file the fast parser refuses (a short row, a cell that is not a number) is scanned
again with Python's csv module only to say which line and column.
"""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv

from hopper.logs.columns import Columns
from hopper.logs.schema import COLUMNS, Log, LogError, check_columns, located, to_si

HEADER_CELL = re.compile(r"\s*([A-Za-z_][A-Za-z0-9_]*)\s*(?:\[\s*([^\]]*?)\s*\])?\s*")
HEADER_LINES = 1  # the data's first line is line 2
BLOCK_BYTES = 1 << 20  # pyarrow's parse block (its default): larger ones cost memory (in flight at once), not time


def _header(path: Path) -> list[tuple[str, float]]:
    """Each column's (name, factor to SI), from the first line; LogError saying what is wrong."""
    try:
        with path.open("rb") as f:
            first = f.readline(1 << 16)
    except OSError as exc:
        raise LogError(f"{path}: cannot read it ({exc.strerror or exc})") from None
    if not first.strip():
        if path.stat().st_size == len(first):
            raise LogError(f"{path}: empty file (a hopper CSV starts with a header line: time [s],...)")
        raise LogError(f"{path}: line 1 is blank (a hopper CSV starts with its header line: time [s],...)")
    try:
        text = first.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = ""
    if not text or "\0" in text:
        raise LogError(f"{path}: not a CSV file (its first line is not text)")
    cells = next(csv.reader([text]))
    parsed = [HEADER_CELL.fullmatch(cell) for cell in cells]
    # A header names the schema's columns: a first line that names none of them is no header.
    if not any(m and m.group(1) in COLUMNS for m in parsed):
        raise LogError(f"{path}: not a hopper CSV (line 1 is not a header like 'time [s],gyro_pitch [rad/s],...')")
    columns: list[tuple[str, float]] = []
    for k, (cell, match) in enumerate(zip(cells, parsed, strict=True), start=1):
        if match is None:
            raise LogError(f"{path}: header column {k} '{cell.strip()}' is not 'name [unit]'")
        name, unit = match.group(1), match.group(2) or ""
        columns.append((name, to_si(name, unit, str(path)) if name in COLUMNS else 1.0))  # unknown: below
    names = [name for name, _ in columns]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise LogError(f"{path}: column(s) {', '.join(twice)} appear more than once in the header")
    check_columns(names, str(path))
    return columns


def _line_of(path: Path, sample: int) -> int:
    """The file's line number of sample `sample` (the parser skips blank lines; an error path only)."""
    with path.open("rb") as f:
        for _ in range(HEADER_LINES):
            f.readline()
        seen = -1
        for line, text in enumerate(f, start=HEADER_LINES + 1):
            seen += bool(text.rstrip(b"\r\n"))  # as pyarrow: a line of spaces is a (short) row
            if seen == sample:
                return line
    return sample + HEADER_LINES + 1


def _bad_row(path: Path, names: list[str], error: pa.ArrowInvalid) -> str:
    """Where the fast parser failed, found by a slow scan: 'line L: ...' (or the parser's own word)."""
    with path.open(newline="", encoding="utf-8", errors="replace") as f:
        rows = csv.reader(f)
        next(rows, None)
        for line, row in enumerate(rows, start=HEADER_LINES + 1):
            if not row:
                continue
            if len(row) != len(names):
                return f"line {line} has {len(row)} values, the header {len(names)}"
            for name, cell in zip(names, row, strict=True):
                try:
                    float(cell)
                except ValueError:
                    if cell.strip():
                        return f"line {line}, column {name}: '{cell[:40]}' is not a number"
    return f"cannot parse it ({error})"


def _rows_estimate(path: Path) -> int:
    """About how many rows the file has, from its size and the length of its first lines."""
    with path.open("rb") as f:
        head = f.read(1 << 20)
    lines = max(1, head.count(b"\n"))
    return int(1.05 * path.stat().st_size * lines / max(1, len(head))) + 16


def read(path: str | Path) -> Log:
    """The CSV log at `path`, in SI units, its gaps marked; LogError with what and where otherwise.

    Streamed in blocks into preallocated columns, so the peak memory is about one copy of the log.
    """
    path = Path(path)
    columns = _header(path)
    names = [name for name, _ in columns]
    data = Columns(names, _rows_estimate(path))
    try:
        batches = pacsv.open_csv(
            path,
            read_options=pacsv.ReadOptions(column_names=names, skip_rows=HEADER_LINES, block_size=BLOCK_BYTES),
            convert_options=pacsv.ConvertOptions(
                column_types=dict.fromkeys(names, pa.float64()),
                null_values=[""],  # an empty cell is missing; 'nan' parses as NaN, refused as not finite
                quoted_strings_can_be_null=False,
            ),
        )
        for batch in batches:
            for name, column in zip(names, batch.columns, strict=True):
                if column.null_count:
                    i = data.n + pc.index(column.is_null(), True).as_py()
                    raise LogError(f"{path}: column {name} is empty at line {_line_of(path, i)}", i)
            data.append({name: column.to_numpy() for name, column in zip(names, batch.columns, strict=True)})
    except pa.ArrowInvalid as exc:
        raise LogError(f"{path}: {_bad_row(path, names, exc)}") from None
    values: dict[str, np.ndarray] = {}
    for name, factor in columns:
        values[name] = data.take(name)
        if factor != 1.0:
            values[name] *= factor
    time = values.pop("time")
    return located(time, values, str(path), lambda i: f"line {_line_of(path, i)}")


def write(log: Log, path: str | Path) -> Path:
    """Write `log` as CSV in SI units with the header `name [unit]`; returns the path."""
    path = Path(path)
    names = ["time", *log.signals]
    table = pa.table([log.time, *log.signals.values()], names=names)
    with path.open("wb") as f:  # the header unquoted (pyarrow quotes its own), then the rows
        f.write((",".join(f"{n} [{COLUMNS[n].unit}]" for n in names) + "\n").encode())
        pacsv.write_csv(table, f, write_options=pacsv.WriteOptions(include_header=False, quoting_style="none"))
    return path
