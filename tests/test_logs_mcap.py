"""MCAP logs: the SignalBlock schema, units converted to SI, and every bad file refused with what and where."""

from __future__ import annotations

import math
from pathlib import Path

import bad_logs
import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import Writer

from hopper.logs import csv_log, mcap_log
from hopper.logs.schema import COLUMNS, Log
from hopper.logs.synthetic import synthetic_log


@pytest.fixture
def log() -> Log:
    return synthetic_log(3.5, seed=4, optional=False)  # 3,500 samples: 4 messages


def blocks_of(log: Log) -> list[tuple[list[str], list[str], np.ndarray]]:
    """The writer's messages for `log`, as (names, units, values) to edit into a bad file."""
    names = ["time", *log.signals]
    values = np.stack([log.time, *log.signals.values()])
    step = mcap_log.BLOCK_SAMPLES
    return [(names, [COLUMNS[n].unit for n in names], values[:, i : i + step]) for i in range(0, values.shape[1], step)]


def written(path: Path, blocks, topic: str = mcap_log.TOPIC, schema: str = mcap_log.SCHEMA_NAME) -> Path:
    """An MCAP file of `blocks` (names, units, values, or raw bytes) on `topic`, as mcap_log.write would."""
    with path.open("wb") as f:
        writer = Writer(f)
        writer.start()
        schema_id = writer.register_schema(schema, "ros2msg", mcap_log.SCHEMA_TEXT.encode())
        channel = writer.register_channel(topic, "cdr", schema_id)
        for i, block in enumerate(blocks):
            data = block if isinstance(block, bytes) else mcap_log.encode(*block)
            writer.add_message(channel, log_time=i, data=data, publish_time=i)
        writer.finish()
    return path


def refused(path: Path) -> str:
    return bad_logs.refused(mcap_log.read, path)


def test_round_trip_is_exact_and_one_message_per_block(tmp_path: Path) -> None:
    log = synthetic_log(2.5, seed=1)  # with the optional columns
    path = mcap_log.write(log, tmp_path / "log.mcap")
    back = mcap_log.read(path)
    np.testing.assert_array_equal(back.time, log.time)
    assert list(back.signals) == list(log.signals) and back.gaps == ()
    for name, values in log.signals.items():
        np.testing.assert_array_equal(back.signals[name], values, err_msg=name)
    with path.open("rb") as f:
        summary = make_reader(f).get_summary()
    (schema,) = summary.schemas.values()
    (channel,) = summary.channels.values()
    assert (schema.name, schema.encoding, schema.data.decode()) == (
        mcap_log.SCHEMA_NAME,
        "ros2msg",
        mcap_log.SCHEMA_TEXT,
    )
    assert (channel.topic, channel.message_encoding) == ("/hopper/signals", "cdr")
    assert summary.statistics.message_count == 3


def test_the_cdr_layout_is_the_documented_one() -> None:
    """Decoded by hand, byte by byte as a ROS 2 reader would: counts, NUL-ended strings, 8-aligned doubles."""
    data = mcap_log.encode(["time", "x"], ["s", "m"], np.array([[0.0, 0.001], [1.5, -2.0]]))
    assert data[:4] == b"\x00\x01\x00\x00"
    assert data[4:8] == (2).to_bytes(4, "little") and data[8:17] == b"\x05\x00\x00\x00time\x00"
    assert data[20:26] == b"\x02\x00\x00\x00x\x00"  # 17 -> 20: aligned to 4
    values = np.frombuffer(data[-32:], "<f8")
    np.testing.assert_array_equal(values, [0.0, 0.001, 1.5, -2.0])
    assert (len(data) - 32 - 4) % 8 == 0


def test_deg_rpm_and_ms_are_converted_to_si(log: Log, tmp_path: Path) -> None:
    blocks = []
    for names, units, values in blocks_of(log):
        units, values = list(units), values.copy()
        for name, unit, scale in (
            ("time", "ms", 1e3),
            ("hip_R", "deg", 180 / math.pi),
            ("wheel_speed", "rpm", 30 / math.pi),
        ):
            units[names.index(name)] = unit
            values[names.index(name)] *= scale
        blocks.append((names, units, values))
    back = mcap_log.read(written(tmp_path / "units.mcap", blocks))
    np.testing.assert_allclose(back.time, log.time, rtol=1e-12, atol=1e-15)
    for name in ("hip_R", "wheel_speed", "gyro_pitch"):
        np.testing.assert_allclose(back.signals[name], log.signals[name], rtol=1e-12, err_msg=name)


def test_a_unit_not_allowed_and_a_missing_column_are_refused(log: Log, tmp_path: Path) -> None:
    blocks = blocks_of(log)
    names, units, values = blocks[0]
    bad_units = [*units[:-1], "kg"]
    message = refused(written(tmp_path / "unit.mcap", [(names, bad_units, values)]))
    assert "column foot_R_force has unit 'kg'; allowed: N" in message
    k = names.index("gyro_pitch")
    cut = (
        [n for i, n in enumerate(names) if i != k],
        [u for i, u in enumerate(units) if i != k],
        np.delete(values, k, 0),
    )
    assert "missing column(s) gyro_pitch;" in refused(written(tmp_path / "missing.mcap", [cut]))


def test_columns_that_change_between_messages_are_refused(log: Log, tmp_path: Path) -> None:
    blocks = blocks_of(log)
    names, units, values = blocks[1]
    blocks[1] = ([*names, "accel_x"], [*units, "m/s^2"], np.vstack([values, values[:1]]))
    assert "message 1 has columns" in refused(written(tmp_path / "changed.mcap", blocks))


def test_time_going_backwards_is_refused_at_its_message(log: Log, tmp_path: Path) -> None:
    blocks = blocks_of(log)
    blocks[1], blocks[2] = blocks[2], blocks[1]  # in file order: 0, 2, 1, 3
    message = refused(written(tmp_path / "back.mcap", blocks))
    assert "time goes backwards or repeats at sample 2000" in message, message
    assert message.endswith("(/hopper/signals message 2, its sample 0)"), message


def test_a_gap_is_read_and_marked(log: Log, tmp_path: Path) -> None:
    blocks = blocks_of(log)
    del blocks[2]  # samples 2000..2999: a second missing
    back = mcap_log.read(written(tmp_path / "gap.mcap", blocks))
    assert len(back.time) == 2500 and back.gaps == ((float(log.time[1999]), float(log.time[3000])),)


def test_nan_is_refused_naming_column_message_and_time(log: Log, tmp_path: Path) -> None:
    blocks = blocks_of(log)
    names, units, values = blocks[3]
    values = values.copy()
    values[names.index("wheel_speed"), 7] = np.nan
    blocks[3] = (names, units, values)
    message = refused(written(tmp_path / "nan.mcap", blocks))
    assert "column wheel_speed is not finite at sample 3007 (t = 3.007000 s)" in message, message
    assert message.endswith("(/hopper/signals message 3, its sample 7)"), message


def test_files_that_are_no_hopper_mcap_are_refused(log: Log, tmp_path: Path) -> None:
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    assert "empty file" in refused(empty)
    text = csv_log.write(log, tmp_path / "log.csv").rename(tmp_path / "text.mcap")
    assert "not an MCAP file" in refused(text)
    whole = mcap_log.write(log, tmp_path / "whole.mcap").read_bytes()
    torn = tmp_path / "torn.mcap"
    torn.write_bytes(whole[: len(whole) // 2])
    assert "not an MCAP file, or one cut short or damaged" in refused(torn)
    other = written(tmp_path / "other.mcap", blocks_of(log), topic="/imu")
    assert "no /hopper/signals channel (its channels: /imu)" in refused(other)
    foreign = written(tmp_path / "foreign.mcap", blocks_of(log), schema="sensor_msgs/msg/Imu")
    assert "/hopper/signals carries sensor_msgs/msg/Imu in cdr, expected hopper_msgs/msg/SignalBlock" in refused(
        foreign
    )
    garbled = written(tmp_path / "garbled.mcap", [mcap_log.encode(*blocks_of(log)[0])[:100]])
    assert "message 0 is not a hopper_msgs/msg/SignalBlock: " in refused(garbled)
    assert "has no messages" in refused(written(tmp_path / "none.mcap", []))
