"""hopper-sim log check / export: the schema check printed, a refused log in one line with exit 2."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hopper.app.sim_cli import main

from hopper.config import SimConfig
from hopper.logs import csv_log, mcap_log
from hopper.logs.io import read_log
from hopper.logs.schema import Log
from hopper.logs.synthetic import synthetic_log
from hopper.sim import Simulation
from hopper.telemetry import Telemetry


def refused(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and err.count("\n") == 1 and err.startswith("hopper-sim: error: "), err
    return err


def test_check_prints_samples_duration_rate_gaps_and_columns(tmp_path: Path, capsys) -> None:
    log = synthetic_log(2.0, seed=5, optional=False)
    keep = (log.time < 0.5) | (log.time >= 0.75)
    gapped = Log(log.time[keep], {k: v[keep] for k, v in log.signals.items()}, "test")
    path = csv_log.write(gapped, tmp_path / "gapped.csv")
    assert main(["log", "check", str(path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == f"{path}: a hopper log (read with its gaps marked)"
    assert "  samples: 1,750 over 1.999 s (0.000 to 1.999 s)" in out
    assert "  rate: 1000.0 Hz (median period 1.000 ms)" in out
    assert "  gaps: 1 marked, 0.251 s without samples: 0.499-0.750 s" in out
    assert "  commands: all of 5" in out and "  measurements: all of 8" in out
    assert "  state: none of 6; missing (optional): x, z, vx, vz, pitch, pitch_rate" in out
    assert out[-1] == "  replay starts from: what the sensors give"


def test_check_refuses_a_bad_log_in_one_line_with_exit_2(tmp_path: Path, capsys) -> None:
    path = csv_log.write(synthetic_log(0.1), tmp_path / "log.csv")
    lines = path.read_text().splitlines()
    lines[0] = lines[0].replace("wheel_speed [rad/s]", "wheel_speed [km/h]")
    path.write_text("\n".join(lines) + "\n")
    err = refused(["log", "check", str(path)], capsys)
    assert "column wheel_speed has unit 'km/h'; allowed: rad/s, deg/s, rpm" in err
    assert "cannot read a log as '.txt'" in refused(["log", "check", str(tmp_path / "log.txt")], capsys)
    assert "no such file" in refused(["log", "check", str(tmp_path / "absent.mcap")], capsys)
    (tmp_path / "empty.npz").write_bytes(b"")
    assert "empty.npz: empty file" in refused(["log", "check", str(tmp_path / "empty.npz")], capsys)
    assert "empty.npz: empty file" in refused(["log", "export", str(tmp_path / "empty.npz"), str(path)], capsys)


def test_export_our_rrd_to_mcap_and_csv(tmp_path: Path, capsys) -> None:
    rrd = tmp_path / "run.rrd"
    sim = Simulation(SimConfig(terrain="flat"))
    with Telemetry(sim, path=rrd):
        for _ in range(300):
            sim.step()
    assert main(["log", "export", str(rrd), str(tmp_path / "run.mcap")]) == 0
    assert capsys.readouterr().out == f"{rrd} -> {tmp_path / 'run.mcap'}: 300 samples, 20 columns, 0.0 MB\n"
    assert main(["log", "export", str(tmp_path / "run.mcap"), str(tmp_path / "run.csv")]) == 0
    original, csv = read_log(rrd), read_log(tmp_path / "run.csv")
    assert mcap_log.read(tmp_path / "run.mcap").source.endswith(f"(written from {original.source})")
    np.testing.assert_array_equal(csv.time, original.time)
    assert all(np.array_equal(csv.signals[k], v) for k, v in original.signals.items())


def test_export_refuses_what_it_cannot_write_before_reading(tmp_path: Path, capsys) -> None:
    path = mcap_log.write(synthetic_log(0.1), tmp_path / "log.mcap")
    assert "cannot write a log as '.rrd'; known: .csv, .mcap, .npz" in refused(
        ["log", "export", str(path), str(tmp_path / "out.rrd")], capsys
    )
    assert "is the input" in refused(["log", "export", str(path), str(path)], capsys)
    assert "folder" in refused(["log", "export", str(path), str(tmp_path / "no" / "out.csv")], capsys)
    assert not (tmp_path / "out.rrd").exists()


@pytest.mark.parametrize(
    ("column", "row", "value", "says"),
    [
        ("wheel_torque_cmd", 40, "1e300", "column wheel_torque_cmd is 1e+300 N m at sample 40 (t = 0.040000 s), "
         "beyond 2950 N m (100x the wheel motor's stall torque): is its unit right? (line 42)"),
        ("wheel_speed", 7, "1e308", "column wheel_speed is 1e+308 rad/s at sample 7 (t = 0.007000 s), beyond 4189 "
         "rad/s (100x the wheel's no-load speed)"),
        ("foot_L_force", 90, "-3e7", "column foot_L_force is -3e+07 N at sample 90"),
    ],
)  # fmt: skip
def test_check_refuses_a_finite_value_no_robot_gives(
    column: str, row: int, value: str, says: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A torque command of 1e300 passed `log check`; a wheel speed of 1e308 then replayed to 'RMS inf'."""
    path = csv_log.write(synthetic_log(0.1), tmp_path / "log.csv")
    lines = path.read_text().splitlines()
    k = lines[0].split(",").index(next(h for h in lines[0].split(",") if h.startswith(f"{column} [")))
    cells = lines[row + 1].split(",")
    cells[k] = value
    lines[row + 1] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    assert says in refused(["log", "check", str(path)], capsys)


def test_check_refuses_a_time_column_in_another_unit_than_it_says(tmp_path: Path, capsys) -> None:
    """Seconds labelled ms passed at 'rate: 1000000.0 Hz'; replay then said 'the log has 0 hop(s)'."""
    path = csv_log.write(synthetic_log(0.1), tmp_path / "log.csv")
    text = path.read_text().replace("time [s]", "time [ms]", 1)
    path.write_text(text)
    err = refused(["log", "check", str(path)], capsys)
    assert "its sample rate is 1e+06 Hz (median period 1e-06 s), outside 10 Hz..100000 Hz" in err, err
    assert "is its time in the unit it says?" in err
    header, *rows = csv_log.write(synthetic_log(0.1), tmp_path / "slow.csv").read_text().splitlines()
    slow = [",".join([repr(200.0 * float(r.split(",")[0])), *r.split(",")[1:]]) for r in rows]  # 5 Hz
    (tmp_path / "slow.csv").write_text("\n".join([header, *slow]) + "\n")
    assert "its sample rate is 5 Hz" in refused(["log", "check", str(tmp_path / "slow.csv")], capsys)
