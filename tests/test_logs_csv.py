"""CSV logs: the header check, units converted to SI, and every bad file refused with what and where."""

from __future__ import annotations

import math
from pathlib import Path

import bad_logs
import numpy as np
import pytest

from hopper.logs import csv_log
from hopper.logs.schema import COLUMNS, Log
from hopper.logs.synthetic import synthetic_log


@pytest.fixture
def log() -> Log:
    return synthetic_log(0.2, seed=3, optional=False)  # the 14 required columns


def lines_of(log: Log, tmp_path: Path) -> list[str]:
    """The CSV writer's lines for `log` (header first), to edit into a bad file."""
    return csv_log.write(log, tmp_path / "good.csv").read_text().splitlines()


def written(tmp_path: Path, lines: list[str], name: str = "bad.csv") -> Path:
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


def refused(path: Path) -> str:
    return bad_logs.refused(csv_log.read, path)


def test_round_trip_is_exact(tmp_path: Path) -> None:
    log = synthetic_log(0.3, rate_hz=500.0, seed=1)  # with the optional columns
    back = csv_log.read(csv_log.write(log, tmp_path / "log.csv"))
    assert back.source == str(tmp_path / "log.csv") and back.gaps == ()
    np.testing.assert_array_equal(back.time, log.time)
    assert list(back.signals) == list(log.signals)
    for name, values in log.signals.items():
        np.testing.assert_array_equal(back.signals[name], values, err_msg=name)


def test_header_names_every_column_with_its_si_unit(log: Log, tmp_path: Path) -> None:
    header = lines_of(log, tmp_path)[0].split(",")
    assert header == [f"{n} [{COLUMNS[n].unit}]" for n in ("time", *log.signals)]


def test_deg_deg_per_s_rpm_and_ms_are_converted_to_si(log: Log, tmp_path: Path) -> None:
    units = {"time": ("ms", 1e3), "gyro_pitch": ("deg/s", 180 / math.pi), "wheel_speed": ("rpm", 60 / (2 * math.pi))}
    units |= {"hip_L": ("deg", 180 / math.pi), "wheel_torque_cmd": ("Nm", 1.0)}
    names = ["time", *log.signals]
    columns = [log.time, *log.signals.values()]
    header = [f"{n} [{units[n][0] if n in units else COLUMNS[n].unit}]" for n in names]
    scaled = [c * (units[n][1] if n in units else 1.0) for n, c in zip(names, columns, strict=True)]
    rows = [",".join(repr(float(v)) for v in row) for row in zip(*scaled, strict=True)]
    back = csv_log.read(written(tmp_path, [",".join(header), *rows]))
    np.testing.assert_allclose(back.time, log.time, rtol=1e-12, atol=1e-15)
    for name in ("gyro_pitch", "wheel_speed", "hip_L", "wheel_torque_cmd", "knee_R"):
        np.testing.assert_allclose(back.signals[name], log.signals[name], rtol=1e-12, atol=1e-15, err_msg=name)


def test_a_unit_not_allowed_is_refused_naming_the_column_and_the_allowed_units(log: Log, tmp_path: Path) -> None:
    lines = lines_of(log, tmp_path)
    lines[0] = lines[0].replace("gyro_pitch [rad/s]", "gyro_pitch [m/s]")
    assert "column gyro_pitch has unit 'm/s'; allowed: rad/s, deg/s, rpm" in refused(written(tmp_path, lines))
    lines[0] = lines[0].replace("gyro_pitch [m/s]", "gyro_pitch")
    assert "column gyro_pitch has no unit; allowed: rad/s, deg/s, rpm" in refused(written(tmp_path, lines))


def test_missing_unknown_and_repeated_columns_are_refused(log: Log, tmp_path: Path) -> None:
    lines = lines_of(log, tmp_path)
    k = lines[0].split(",").index("wheel_speed [rad/s]")
    cut = [",".join(c for i, c in enumerate(line.split(",")) if i != k) for line in lines]
    assert "missing column(s) wheel_speed;" in refused(written(tmp_path, cut))
    extra = [lines[0] + ",banana [m]", *(line + ",1.0" for line in lines[1:])]
    assert "unknown column(s) banana;" in refused(written(tmp_path, extra))
    misspelt = [lines[0].replace("gyro_pitch [", "gyro_pich ["), *lines[1:]]
    assert "missing column(s) gyro_pitch, unknown column(s) gyro_pich;" in refused(written(tmp_path, misspelt))
    twice = [lines[0] + ",hip_L [rad]", *(line + ",1.0" for line in lines[1:])]
    assert "column(s) hip_L appear more than once" in refused(written(tmp_path, twice))


def test_a_header_cell_that_is_not_name_unit_is_refused(log: Log, tmp_path: Path) -> None:
    lines = lines_of(log, tmp_path)
    lines[0] = lines[0].replace("knee_L [rad]", "knee L (rad)")
    assert "header column 10 'knee L (rad)' is not 'name [unit]'" in refused(written(tmp_path, lines))


def test_time_going_backwards_is_refused_at_its_line(log: Log, tmp_path: Path) -> None:
    lines = lines_of(log, tmp_path)
    lines[51], lines[52] = lines[52], lines[51]  # samples 50 and 51, lines 52 and 53
    message = refused(written(tmp_path, lines))
    assert "time goes backwards or repeats at sample 51" in message and message.endswith("(line 53)"), message


def test_blank_lines_are_skipped_and_lines_still_counted_right(log: Log, tmp_path: Path) -> None:
    lines = lines_of(log, tmp_path)
    cells = lines[41].split(",")
    cells[6] = "inf"  # sample 40, gyro_pitch
    spaced = [*lines[:11], "", "", *lines[11:41], ",".join(cells), *lines[42:], ""]  # two blank lines before it
    message = refused(written(tmp_path, spaced))
    assert "column gyro_pitch is not finite at sample 40" in message and message.endswith("(line 44)"), message
    assert len(csv_log.read(written(tmp_path, [*lines[:11], "", *lines[11:]], "blank.csv")).time) == 200


def test_a_gap_is_read_and_marked(log: Log, tmp_path: Path) -> None:
    lines = lines_of(log, tmp_path)
    del lines[101:151]  # samples 100..149
    back = csv_log.read(written(tmp_path, lines))
    assert len(back.time) == len(log.time) - 50
    assert back.gaps == ((float(log.time[99]), float(log.time[150])),)


def test_nan_and_empty_cells_are_refused_naming_column_and_line(log: Log, tmp_path: Path) -> None:
    lines = lines_of(log, tmp_path)
    k = lines[0].split(",").index("foot_R_force [N]")
    cells = lines[31].split(",")
    cells[k] = "nan"
    nan = [*lines[:31], ",".join(cells), *lines[32:]]
    message = refused(written(tmp_path, nan))
    assert "column foot_R_force is not finite at sample 30 (t = 0.030000 s)" in message, message
    assert message.endswith("(line 32)"), message
    cells[k] = ""
    empty = [*lines[:31], ",".join(cells), *lines[32:]]
    assert refused(written(tmp_path, empty)).endswith("column foot_R_force is empty at line 32")


def test_a_short_row_and_a_cell_that_is_not_a_number_are_refused_at_their_line(log: Log, tmp_path: Path) -> None:
    lines = lines_of(log, tmp_path)
    short = [*lines[:10], lines[10].rsplit(",", 2)[0], *lines[11:]]
    assert refused(written(tmp_path, short)).endswith("line 11 has 12 values, the header 14")
    cells = lines[20].split(",")
    cells[3] = "abc"
    word = [*lines[:20], ",".join(cells), *lines[21:]]
    assert refused(written(tmp_path, word)).endswith("line 21, column knee_L_torque_cmd: 'abc' is not a number")


def test_empty_header_only_and_files_that_are_no_csv_are_refused(log: Log, tmp_path: Path) -> None:
    empty = tmp_path / "empty.csv"
    empty.write_bytes(b"")
    assert "empty file" in refused(empty)
    header = written(tmp_path, lines_of(log, tmp_path)[:1], "header.csv")
    assert "needs at least 2 samples, got 0" in refused(header)
    binary = tmp_path / "image.csv"
    binary.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\x00\x00")
    assert "not a CSV file (its first line is not text)" in refused(binary)
    prose = written(tmp_path, ["Dear robot team,", "here are the numbers: 1, 2, 3"], "letter.csv")
    assert "not a hopper CSV (line 1 is not a header" in refused(prose)
