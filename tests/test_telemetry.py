"""Telemetry: recordings read back with rerun's own reader, interrupts, paths, the package's boundaries."""

from __future__ import annotations

import ast
import math
import os
import signal
import subprocess
import sys
import time
import typing
from collections import defaultdict
from decimal import Decimal
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
from rerun.chunk import RrdReader
from rrd import verify

from hopper.config import Gains, SimConfig
from hopper.metrics import HopMetrics
from hopper.sim import Simulation
from hopper.telemetry import HOP_DECIMALS, SIGNALS, Telemetry, check_writable, session_path

REPO = Path(__file__).resolve().parent.parent


class Probe:
    """A reference listener: what MjData holds after each step, read independently of Telemetry."""

    def __init__(self, sim: Simulation) -> None:
        m = sim.model
        self.dt = m.opt.timestep
        self.pitch_adr = m.sensor("imu_pitch").adr[0]
        self.rpm_adr = m.sensor("wheel_speed").adr[0]
        self.wheel_id, self.gear = m.actuator("wheel").id, m.actuator("wheel").gear[0]
        self.hip_adr = m.joint("hip_L").qposadr[0]
        self.initial_hip = sim.data.qpos[self.hip_adr]
        self.times: list[float] = []
        self.pitch: list[float] = []
        self.rpm: list[float] = []
        self.torque: list[float] = []
        self.hip_after: list[float] = []  # qpos after the step: the state at the next tick's start

    def tick(self, sim: Simulation) -> None:
        d = sim.data
        self.times.append(d.time - self.dt)
        self.pitch.append(d.sensordata[self.pitch_adr])
        self.rpm.append(d.sensordata[self.rpm_adr])
        self.torque.append(d.actuator_force[self.wheel_id] * self.gear)
        self.hip_after.append(d.qpos[self.hip_adr])

    def event(self, sim: Simulation, event: object) -> None:
        pass


def read(path: Path) -> dict[str, pa.Table]:
    """The recording's non-static rows per entity path, as Arrow tables."""
    batches = defaultdict(list)
    for chunk in RrdReader(path).stream():
        if not chunk.is_static:
            batches[chunk.entity_path.lstrip("/")].append(chunk.to_record_batch())
    return {entity: pa.Table.from_batches(b).combine_chunks() for entity, b in batches.items()}


def property_rows(path: Path, name: str) -> list[dict]:
    """Every value sent of the recording property `name`, oldest first (the viewer shows the last)."""
    rows = [
        row
        for chunk in RrdReader(path).stream()
        if chunk.entity_path == f"/__properties/{name}"
        for row in chunk.to_record_batch().to_pylist()
    ]
    rows.sort(key=lambda row: row.pop("rerun.controls.RowId"))  # row ids grow with time
    return [{field: cell[0] for field, cell in row.items()} for row in rows]


def seconds(table: pa.Table) -> np.ndarray:
    return table.column("sim_time").cast(pa.int64()).to_numpy() / 1e9


def cells(table: pa.Table, name: str) -> list:
    """One value per row of a component column (each row holds a one-element list)."""
    column = table.column(name).to_pylist()
    assert all(len(row) == 1 for row in column), f"{name}: rows must hold exactly one value"
    return [row[0] for row in column]


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Simulation, Probe, Path, dict[str, pa.Table]]:
    """Two hops on flat ground with a gain change before the first and a pitch kick in the second."""
    path = tmp_path_factory.mktemp("rec") / "run.rrd"
    sim = Simulation(SimConfig(terrain="flat"))
    probe = Probe(sim)
    with Telemetry(sim, path=path) as telemetry:
        assert sim.listeners == [telemetry]
        sim.listeners.append(probe)
        sim.set_gains(Gains(kp=500.0, ki=40.0, kd=28.0))
        sim.run(1)
        sim.disturb("pitch_kick", 0.5)
        sim.run(2)
    assert telemetry.closed and telemetry not in sim.listeners
    return sim, probe, path, read(path)


def test_recording_verifies_and_has_both_timelines(run) -> None:
    _, _, path, tables = run
    verify(path)
    timelines = {name for table in tables.values() for name in table.column_names}
    assert {"sim_time", "hop"} <= timelines
    assert tables["hops"].column("hop").to_pylist() == [1, 2]


def test_signals_hold_one_sample_per_tick(run) -> None:
    sim, probe, _, tables = run
    signals = tables["signals"]
    t = seconds(signals)
    assert len(t) == len(probe.times) == round(sim.time / probe.dt) > 5000
    np.testing.assert_allclose(t, probe.times, atol=1e-9)
    assert np.all(np.diff(t) > 0.0)
    values = cells(signals, "signals")
    assert set(values[0]) == set(SIGNALS)
    for name in ("pitch_deg", "wheel_rpm", "wheel_torque_nm"):
        assert sum(v[name] is not None for v in values) == len(t), name


def test_signals_match_the_physics(run) -> None:
    _, probe, _, tables = run
    values = cells(tables["signals"], "signals")
    pitch = np.array([v["pitch_deg"] for v in values])
    np.testing.assert_allclose(pitch, np.degrees(probe.pitch).astype(np.float32), rtol=1e-6, atol=1e-6)
    rpm = np.array([v["wheel_rpm"] for v in values])
    np.testing.assert_allclose(rpm, np.array(probe.rpm) * 60 / (2 * math.pi), rtol=1e-6, atol=1e-4)
    capacity = np.array([v["wheel_capacity_pct"] for v in values])  # momentum / (I_w + armature) w_max
    np.testing.assert_allclose(capacity, rpm / 400.0 * 100.0, rtol=1e-5, atol=1e-4)
    torque = np.array([v["wheel_torque_nm"] for v in values])
    np.testing.assert_allclose(torque, probe.torque, rtol=1e-6, atol=1e-5)
    assert np.abs(torque).max() > 1.0  # the wheel did work: the comparison is not of zeros
    # Joint angles come from the qpos of the previous tick, the state at this tick's start.
    hip = np.array([v["hip_L_deg"] for v in values])
    expected = np.degrees([probe.initial_hip, *probe.hip_after[:-1]])
    np.testing.assert_allclose(hip, expected, atol=np.abs(expected).max() / 1000)  # float16


def test_each_touchdown_has_the_runner_metrics(run) -> None:
    sim, _, _, tables = run
    hops = tables["hops"]
    assert hops.num_rows == len(sim.hops) == 2
    for row, hop in enumerate(sim.hops):
        for name, value in hop.as_dict().items():
            half_unit = 0.5 * 10.0 ** -HOP_DECIMALS[name] if isinstance(value, float) else 0
            assert abs(cells(hops, name)[row] - value) <= half_unit + 1e-12, name
    assert cells(hops, "index") == [1, 2] and cells(hops, "completed") == [True, True]
    np.testing.assert_allclose(seconds(hops), [h.touchdown_time_s for h in sim.hops], atol=1e-9)


def test_hop_table_floats_are_rounded_to_each_fields_resolution(run) -> None:
    sim, _, _, tables = run
    floats = [name for name, kind in typing.get_type_hints(HopMetrics).items() if kind is float]
    assert sorted(floats) == sorted(HOP_DECIMALS)  # a new float field needs a resolution
    for name in floats:
        decimals = HOP_DECIMALS[name]
        for value in cells(tables["hops"], name):
            assert value == round(value, decimals), (name, value)
            # What a dataframe view prints (the shortest repr): at most `decimals` decimals.
            assert -Decimal(repr(value)).normalize().as_tuple().exponent <= decimals, (name, value)


def test_events_include_gains_disturbance_and_phase_events(run) -> None:
    sim, _, _, tables = run
    events = tables["events"]
    kinds, texts = cells(events, "kind"), cells(events, "TextLog:text")
    assert "gains: gains Kp 500 N m/rad, Ki 40 N m/(rad s), Kd 28 N m s/rad" in texts
    assert "disturbance: pitch kick +0.5 N m s" in texts
    assert kinds.count("liftoff") == kinds.count("touchdown") == 2 and kinds.count("apex") == 2
    touchdowns = [text for text in texts if text.startswith("touchdown")]
    assert f"distance {sim.hops[1].distance_m:.3f} m" in touchdowns[1]
    states = cells(tables["phase"], "StateChange:state")
    assert states[0] == "stance" and states.count("flight") == 2
    assert all(a != b for a, b in zip(states, states[1:], strict=False))  # logged on change only


def test_config_property_follows_the_live_settings(tmp_path: Path) -> None:
    """A session switched to Mars with the wheel off is labelled so (it was once recorded as Moon)."""
    sim = Simulation(SimConfig(terrain="flat"))
    path = tmp_path / "mars.rrd"
    with Telemetry(sim, path=path):
        for _ in range(100):
            sim.step()
        sim.set_gravity(3.72)
        sim.set_wheel(False)
        for _ in range(100):
            sim.step()
    configs = property_rows(path, "config")
    assert configs[0]["gravity"] == 1.625 and configs[0]["wheel"] is True
    assert configs[-1]["gravity"] == 3.72 and configs[-1]["wheel"] is False
    assert configs[-1]["terrain"] == "flat" and configs[-1]["kp"] == Gains().kp
    events = read(path)["events"]
    gravity = cells(events, "kind").index("gravity")
    assert cells(events, "TextLog:text")[gravity] == "gravity: gravity 3.72 m/s²"
    assert seconds(events)[gravity] == pytest.approx(0.1)


@pytest.mark.parametrize("sensing", ["ideal", "realistic"])
def test_the_estimate_is_recorded_beside_the_truth(tmp_path: Path, sensing: str) -> None:
    """Realistic sensing: the controller's pitch estimate, row by row, as the kernel made it."""
    sim = Simulation(SimConfig(terrain="flat", sensing=sensing))  # type: ignore[arg-type]
    path, estimates = tmp_path / f"{sensing}.rrd", []
    with Telemetry(sim, path=path, batch_ticks=400):
        for _ in range(1200):
            sim.step()
            estimates.append(float(sim.controller.mem["pitch_est"][0]))
    values = cells(read(path)["signals"], "signals")
    recorded = np.array([v["pitch_est_deg"] for v in values])
    np.testing.assert_allclose(recorded, np.degrees(estimates).astype(np.float32), rtol=1e-6, atol=1e-6)
    truth = np.array([v["pitch_deg"] for v in values])
    gap = np.abs(recorded - truth).max()
    assert gap < 1e-4 if sensing == "ideal" else 1e-3 < gap < 2.0, gap  # deg: noise and bias, bounded


def test_reset_keeps_sim_time_monotonic(tmp_path: Path) -> None:
    sim = Simulation(SimConfig(terrain="flat"))
    path = tmp_path / "reset.rrd"
    with Telemetry(sim, path=path, batch_ticks=100):
        for _ in range(250):
            sim.step()
        sim.reset(reason="test")
        for _ in range(150):
            sim.step()
    tables = read(path)
    t = seconds(tables["signals"])
    assert len(t) == 400
    np.testing.assert_allclose(np.diff(t), sim.model.opt.timestep, atol=1e-9)
    reset = cells(tables["events"], "TextLog:text").index("reset: reset (test)")
    assert seconds(tables["events"])[reset] == pytest.approx(t[250])


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_interrupt_leaves_a_verified_recording(tmp_path: Path, signum: int) -> None:
    path = tmp_path / "interrupted.rrd"
    script = (
        "import signal, sys\n"
        "from hopper.config import SimConfig\n"
        "from hopper.sim import Simulation\n"
        "from hopper.telemetry import Telemetry\n"
        "signal.signal(signal.SIGTERM, lambda signum, _: sys.exit(128 + signum))  # as a CLI does\n"
        "sim = Simulation(SimConfig(terrain='flat'))\n"
        "try:\n"
        "    with Telemetry(sim, path=sys.argv[1]):\n"
        "        for i in range(10**9):\n"
        "            sim.step()\n"
        "            if i == 2500:\n"
        "                print('ready', flush=True)\n"
        "finally:\n"
        "    print(round(sim.time / sim.model.opt.timestep), flush=True)\n"
    )
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    child = subprocess.Popen([sys.executable, "-c", script, str(path)], stdout=subprocess.PIPE, text=True, env=env)
    try:
        assert child.stdout is not None and child.stdout.readline().strip() == "ready"
        time.sleep(1.0)  # not a wait: the moment of the signal, mid-recording (any moment must do)
        child.send_signal(signum)
        code = child.wait(timeout=60)
        steps = int(child.stdout.read().split()[-1])
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    assert code == (-signal.SIGINT if signum == signal.SIGINT else 128 + signal.SIGTERM)
    verify(path)
    t = seconds(read(path)["signals"])
    # Every step is there, the partial last batch too; the signal may land between a step and its tick().
    assert steps - 1 <= len(t) <= steps and steps > 2500
    np.testing.assert_allclose(np.diff(t), 0.001, atol=1e-9)


def test_check_writable(tmp_path: Path) -> None:
    good = tmp_path / "a.rrd"
    assert check_writable(good) == good and not good.exists()  # probing leaves nothing behind
    cases = {
        tmp_path / "missing" / "a.rrd": "does not exist",
        tmp_path: "must end in .rrd",
        tmp_path / "dir.rrd": "is a directory",
        tmp_path / "a.txt": "must end in .rrd",
    }
    (tmp_path / "dir.rrd").mkdir()
    if Path("/sys").is_dir():  # sysfs refuses new files even to root
        cases[Path("/sys/hopper.rrd")] = "Permission denied"
    for path, reason in cases.items():
        with pytest.raises(ValueError, match=reason) as error:
            check_writable(path)
        assert "\n" not in str(error.value)
    with pytest.raises(ValueError, match="does not exist"):
        Telemetry(Simulation(SimConfig(terrain="flat")), path=tmp_path / "missing" / "a.rrd")


def test_session_path_is_new_and_timestamped(tmp_path: Path) -> None:
    first = session_path(tmp_path / "sessions")
    first.touch()
    second = session_path(tmp_path / "sessions")
    assert first.parent == second.parent == tmp_path / "sessions"
    assert first.suffix == ".rrd" and first.name.startswith("hopper-20") and second != first


def test_a_session_folder_is_made_only_in_a_folder_that_exists(tmp_path: Path) -> None:
    """The Record button's folder, gone since start-up with its parent: refused in one line (the
    dashboard shows it), not made again with a new parent."""
    with pytest.raises(ValueError, match="cannot make sessions folder .*: No such file or directory") as error:
        session_path(tmp_path / "missing" / "sessions")
    assert "\n" not in str(error.value) and not any(tmp_path.iterdir())


def test_close_is_idempotent_and_detaches(tmp_path: Path) -> None:
    sim = Simulation(SimConfig(terrain="flat"))
    telemetry = Telemetry(sim, path=tmp_path / "c.rrd")
    for _ in range(30):
        sim.step()
    telemetry.close()
    telemetry.close()
    sim.step()  # no listener left to fail
    assert sim.listeners == [] and len(seconds(read(tmp_path / "c.rrd")["signals"])) == 30


def test_on_close_runs_once_after_the_footer_or_when_starting_fails(tmp_path: Path) -> None:
    sim = Simulation(SimConfig(terrain="flat"))
    path, sizes = tmp_path / "c.rrd", []
    telemetry = Telemetry(sim, path=path, on_close=lambda: sizes.append(path.stat().st_size))
    for _ in range(30):
        sim.step()
    telemetry.close()
    telemetry.close()
    assert sizes == [path.stat().st_size]  # the file was final when it ran
    failed = []
    with pytest.raises(ValueError, match="nothing to record to"):
        Telemetry(sim, on_close=lambda: failed.append(True))
    assert failed == [True] and sim.listeners == []


def test_telemetry_package_starts_no_processes_and_imports_no_app() -> None:
    """Viewer processes and ports belong to hopper.app.rerun_viewer; the core only takes sinks."""
    modules = sorted((REPO / "hopper" / "telemetry").glob("*.py"))
    assert len(modules) > 1
    for module in modules:
        for node in ast.walk(ast.parse(module.read_text())):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = ["." * node.level + (node.module or "")]
            else:
                continue
            for name in names:
                assert name.split(".")[0] not in ("subprocess", "socket", "app"), f"{module.name} imports {name}"
                assert not name.startswith(("hopper.app", ".")), f"{module.name} imports {name}"
