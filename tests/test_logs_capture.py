"""hopper.logs.capture and hopper.logs.npz: a simulated robot logged as a real one, written and read back."""

from __future__ import annotations

import json
import math
from pathlib import Path

import bad_logs
import numpy as np
import pytest

from hopper.config import SensingParams, SimConfig
from hopper.logs import npz
from hopper.logs.capture import capture
from hopper.logs.schema import STATE, LogError

BIAS = 0.5  # deg/s, the IMU's fixed turn-on bias in the realistic captures


@pytest.fixture(scope="module")
def realistic():
    """Two hops of a mismatched robot, realistic sensing with a known gyro bias."""
    config = SimConfig(
        terrain="flat",
        sensing="realistic",
        seed=3,
        mismatch=(("torso_mass", 1.2), ("motor_torque", 0.9)),
        sensor=SensingParams(gyro_turn_on_bias=0.0, gyro_bias_fixed=BIAS),
    )
    return capture(config, 2)


def test_capture_logs_every_tick_with_state(realistic) -> None:
    log = realistic.log
    assert realistic.hops == 2 and not realistic.fell
    assert log.has_state() and all(c.name in log.signals for c in STATE)
    assert np.allclose(np.diff(log.time), 0.001)
    assert log.gaps == ()
    on = (log.signals["foot_L_force"] > 0) | (log.signals["foot_R_force"] > 0)
    assert on[:100].any() and not on.all()  # it stood, then flew


def test_the_gyro_column_is_the_imus_biased_noisy_sample(realistic) -> None:
    s = realistic.log.signals
    error = s["gyro_pitch"] - s["pitch_rate"]  # the truth: the error is bias + white noise
    per_sample = math.radians(SensingParams().gyro_noise_density) / math.sqrt(0.001)
    assert math.degrees(error.mean()) == pytest.approx(BIAS, abs=5 * math.degrees(per_sample) / math.sqrt(error.size))
    assert error.std() == pytest.approx(per_sample, rel=0.05)


def test_ideal_sensing_logs_the_true_rate() -> None:
    log = capture(SimConfig(terrain="flat"), 1).log
    s = log.signals
    assert np.abs(s["gyro_pitch"] - s["pitch_rate"]).max() < 1e-12


def test_npz_round_trip(tmp_path: Path, realistic) -> None:
    log = realistic.log
    back = npz.read(npz.write(log, tmp_path / "run.log"))  # any name: nothing is appended
    assert back.source == str(tmp_path / "run.log")
    assert np.array_equal(back.time, log.time)
    assert back.signals.keys() == log.signals.keys()
    assert all(np.array_equal(back.signals[k], v) for k, v in log.signals.items())


def _rewrite(path: Path, **changes: object) -> None:
    with np.load(path) as archive:
        arrays = {k: archive[k] for k in archive.files}
    arrays.update(changes)
    arrays = {k: v for k, v in arrays.items() if v is not None}
    with open(path, "wb") as out:
        np.savez(out, **arrays)


def test_npz_refuses_what_is_not_a_log(tmp_path: Path, realistic) -> None:
    with pytest.raises(LogError, match="no such file"):
        npz.read(tmp_path / "missing.npz")
    (tmp_path / "text.npz").write_text("time,pitch\n")
    with pytest.raises(LogError, match="not a .npz archive"):
        npz.read(tmp_path / "text.npz")
    other = tmp_path / "other.npz"
    np.savez(other, a=np.zeros(3))
    with pytest.raises(LogError, match="not a hopper log"):
        npz.read(other)
    path = npz.write(realistic.log, tmp_path / "bad.npz")
    units = json.loads(str(np.load(path)["units"])) | {"wheel_speed": "rpm"}
    _rewrite(path, units=np.array(json.dumps(units)))
    with pytest.raises(LogError, match="column wheel_speed is in 'rpm'"):
        npz.read(path)
    path = npz.write(realistic.log, tmp_path / "missing_col.npz")
    _rewrite(path, wheel_speed=None)
    with pytest.raises(LogError, match="missing column.*wheel_speed"):
        npz.read(path)
    path = npz.write(realistic.log, tmp_path / "nan.npz")
    pitch = realistic.log.signals["gyro_pitch"].copy()
    pitch[7] = np.nan
    _rewrite(path, gyro_pitch=pitch)
    with pytest.raises(LogError, match="gyro_pitch is not finite at sample 7"):
        npz.read(path)


def test_npz_refuses_an_empty_cut_short_or_damaged_file_in_one_line(tmp_path: Path, realistic) -> None:
    whole = npz.write(realistic.log, tmp_path / "whole.npz").read_bytes()
    empty = tmp_path / "empty.npz"
    empty.write_bytes(b"")
    assert "empty file" in bad_logs.refused(npz.read, empty)
    for name, data in (("head.npz", whole[:100]), ("half.npz", whole[: len(whole) // 2])):
        (tmp_path / name).write_bytes(data)
        assert "cut short or damaged" in bad_logs.refused(npz.read, tmp_path / name)
    damaged = bytearray(whole)
    damaged[len(whole) // 3 : len(whole) // 3 + 64] = b"x" * 64  # inside an entry: its CRC fails when read
    (tmp_path / "damaged.npz").write_bytes(damaged)
    assert "cut short or damaged" in bad_logs.refused(npz.read, tmp_path / "damaged.npz")
    with open(tmp_path / "array.npz", "wb") as out:  # a .npy under a .npz name
        np.save(out, np.zeros(3))
    assert "not a .npz archive" in bad_logs.refused(npz.read, tmp_path / "array.npz")
