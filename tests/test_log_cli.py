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
