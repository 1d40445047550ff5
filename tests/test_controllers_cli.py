"""The README's example controller, in a file outside the package, through every command that flies."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from test_controllers import readme_example

pytestmark = pytest.mark.integration


def hopper_sim(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hopper.app.sim_cli", *args], capture_output=True, text=True, timeout=600, cwd=cwd
    )


@pytest.fixture(scope="module")
def example(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("user")
    (folder / "my_controller.py").write_text(readme_example())
    return folder


SPEC = "my_controller.py:LandLevel"  # relative, as the README has it: made absolute when parsed


def test_run_flies_it_and_reports_its_params_and_cost(example: Path) -> None:
    out = example / "run.json"
    result = hopper_sim("run", "--hops", "3", "--controller", SPEC, "--controller-param", "boost=2",
                        "--json", str(out), cwd=example)  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "controller " in result.stdout and "(LandLevel: kp 300 kd 25 boost 2;" in result.stdout
    doc = json.loads(out.read_text())
    assert doc["controller"]["params"] == {"kp": 300.0, "kd": 25.0, "boost": 2.0}
    assert doc["controller"]["calls"] > 1000 and doc["controller"]["fault"] is None
    assert doc["settings"]["controller"] == str(example / "my_controller.py") + ":LandLevel"
    assert doc["settings"]["controller_params"] == [["boost", 2.0]]
    assert len(doc["hops"]) == 3 and not doc["fell"]


def test_compare_stress_sweep_and_league_fly_it(example: Path) -> None:
    compare = hopper_sim("compare", "--seeds", "1", "--hops", "2", "--workers", "2", "--controller", SPEC,
                         "--json", str(example / "c.json"), cwd=example)  # fmt: skip
    assert compare.returncode == 0, compare.stderr
    runs = json.loads((example / "c.json").read_text())["runs"]
    assert {r["settings"]["controller"].rpartition("/")[2] for r in runs} == {SPEC}
    stress = hopper_sim("stress", "--quick", "--groups", "flight", "--workers", "2", "--controller", SPEC,
                        "--json", str(example / "s.json"), cwd=example)  # fmt: skip
    assert stress.returncode in (0, 1), stress.stderr  # a failed case is a result here
    cases = json.loads((example / "s.json").read_text())["cases"]
    assert len(cases) == 8 and all(c["settings"]["controller"].endswith(SPEC) for c in cases)
    assert all(c["fault"] == "" for c in cases)
    sweep = hopper_sim("sweep", "--out", str(example / "sweep"), "--seeds", "1", "--hops", "2", "--controller",
                       SPEC, "--param", "boost=0,3", "--workers", "2", cwd=example)  # fmt: skip
    assert sweep.returncode == 0, sweep.stderr
    assert "param_boost (x kp at the touchdown): 0: 0/1 fell" in sweep.stdout and "3: 0/1 fell" in sweep.stdout
    league = hopper_sim("league", "--quick", "--controllers", f"pid,{SPEC}", "--workers", "2",
                        "--json", str(example / "l.json"), cwd=example)  # fmt: skip
    assert league.returncode == 0, league.stderr
    rows = {r["controller"].rpartition("/")[2]: r for r in json.loads((example / "l.json").read_text())["rows"]}
    assert set(rows) == {"pid", SPEC} and rows[SPEC]["episodes"] == rows["pid"]["episodes"] > 10
    assert rows[SPEC]["compute_us"] > 0.0 == rows["pid"]["compute_us"]
    assert SPEC in league.stdout
    pid_line = next(line for line in league.stdout.splitlines() if line.startswith("pid "))
    assert pid_line.split()[-1] == "compiled", pid_line  # no Python call to time, not "0.00"
    assert all(r["energy_j"] > 0 for r in rows.values())  # electrical energy per hop, J
    report = hopper_sim("report", str(example / "l.json"), "--out", str(example / "report"), cwd=example)
    assert report.returncode == 0, report.stderr
    page = (example / "report" / "report.html").read_text()
    assert (example / "report" / "league.png").stat().st_size > 10_000 and SPEC in page and "energy (J/hop)" in page
    assert "<td>compiled (in the ~1 us kernel tick)</td>" in page  # the table said 0 us/call


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("run", "--controller", "missing.py:X"), "controller file"),
        (("compare", "--controller", "my_controller.py:Nope", "--seeds", "1"), "has no class 'Nope'"),
        (("stress", "--quick", "--controller", SPEC, "--controller-param", "boost=9"), "outside [0, 5]"),
        (("sweep", "--out", "never", "--controller", "lqr", "--param", "boost=1"), "lqr declares no such param"),
        (("sweep", "--out", "never", "--controller", "lqr", "--kp", "300,600"), "kp is the PID's gain, which"),
        (("league", "--controllers", "pid,nope"), "unknown controller 'nope'"),
        (("league", "--quick", "--controllers", f"pid,{SPEC},./{SPEC}"), "named more than once"),  # pooled rows
        (("league", "--quick", "--workers", "0"), "--workers must be at least 1, got 0"),  # ran on all cores
    ],
)
def test_a_bad_controller_stops_every_command_with_one_line_and_exit_2(example: Path, args, message: str) -> None:
    result = hopper_sim(*args, cwd=example)
    assert result.returncode == 2, result.stdout + result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hopper-sim: error: ") and message in lines[0], lines
    assert not (example / "never").exists()


def test_a_mixed_sweep_sweeps_the_gains_on_the_pid_alone_and_reports_it(example: Path) -> None:
    """pid,lqr over 2 kp values is 3 episodes, not 4: the LQR flies no kp, so it flies once, with the
    default gains its fallback PID would take (as `run --controller lqr`); the summary and the
    report's gain map count the PID's episodes only."""
    import pyarrow.dataset as ds

    from hopper.config import Gains

    out = example / "mixed"
    sweep = hopper_sim("sweep", "--out", str(out), "--controller", "pid,lqr", "--kp", "300,600", "--hops", "1",
                       "--terrain", "flat", cwd=example)  # fmt: skip
    assert sweep.returncode == 0, sweep.stderr
    rows = ds.dataset(out / "episodes").to_table(columns=["controller", "kp", "ki", "kd"]).to_pylist()
    default = Gains()
    lqr = {"controller": "lqr", "kp": default.kp, "ki": default.ki, "kd": default.kd}
    assert sorted(rows, key=str) == sorted([{**lqr, "controller": "pid", "kp": 300.0},
                                            {**lqr, "controller": "pid", "kp": 600.0}, lqr], key=str)  # fmt: skip
    assert "running 3 episodes" in sweep.stderr and "kp (N m/rad, pid episodes): 300: 0/1 fell" in sweep.stdout
    assert "controller: pid: 0/2 fell" in sweep.stdout and "lqr: 0/1 fell" in sweep.stdout
    report = hopper_sim("report", str(out), "--out", str(example / "mixed-report"), cwd=example)
    assert report.returncode == 0, report.stderr
    assert (example / "mixed-report" / "gain_map_wheel_on.png").stat().st_size > 10_000
    # A spec file's one gain other than the default, with no PID to fly it: refused, not dropped.
    (example / "lqr.toml").write_text('kp = 300\ncontroller = "lqr"\n')
    refused = hopper_sim("sweep", "lqr.toml", "--out", str(example / "never"), cwd=example)
    assert refused.returncode == 2 and refused.stderr.count("\n") == 1, refused.stderr
    assert "kp is the PID's gain, which controller lqr does not fly" in refused.stderr
    assert not (example / "never").exists()


def test_a_recording_holds_the_controller_and_its_params(example: Path) -> None:
    from hopper.report.rrd import read_run

    rrd = example / "flown.rrd"
    result = hopper_sim("run", "--hops", "2", "--controller", SPEC, "--controller-param", "kd=20", "--rrd", str(rrd),
                        cwd=example)  # fmt: skip
    assert result.returncode == 0, result.stderr
    settings = read_run(rrd).settings  # read back with rerun's own reader
    assert settings["controller"].endswith(SPEC)
    assert json.loads(settings["controller_params"]) == {"kp": 300.0, "kd": 20.0, "boost": 1.0}


def test_report_redraws_a_run_flown_by_another_controller(example: Path) -> None:
    out = example / "pid.json"
    assert hopper_sim("run", "--hops", "2", "--json", str(out), cwd=example).returncode == 0
    result = hopper_sim("report", str(out), "--out", str(example / "by-user"), "--controller", SPEC, cwd=example)
    assert result.returncode == 0, result.stderr
    assert f"re-flown by {SPEC}" in (example / "by-user" / "report.html").read_text()
    bad = hopper_sim("report", str(out), "--out", str(example / "never"), "--controller", "nope", cwd=example)
    assert bad.returncode == 2 and "unknown controller 'nope'" in bad.stderr
