"""Our own .rrd as a hopper log: each column checked against the MjData it was recorded from."""

from __future__ import annotations

from pathlib import Path

import bad_logs
import numpy as np
import pytest
import rerun as rr

from hopper.config import SimConfig
from hopper.layout import LEG_JOINTS
from hopper.logs import mcap_log, rrd_log
from hopper.logs.io import read_log
from hopper.logs.schema import Log
from hopper.sim import Simulation
from hopper.telemetry import Telemetry


class Truth:
    """A listener beside the recorder: at each tick, the state at its start t_k, read from MjData.

    After mj_step the sensors, actuator forces and body poses are those of t_k (its forward pass);
    qpos and qvel are already t_k+1's, so theirs are kept from the tick before.
    """

    def __init__(self, sim: Simulation) -> None:
        m, lay = sim.model, sim.layout
        self.dt, self.lay, self.torso = m.opt.timestep, lay, m.body("torso").id
        self.rows: dict[str, list[float]] = {}
        self.qpos, self.qvel = sim.data.qpos.copy(), sim.data.qvel.copy()

    def tick(self, sim: Simulation) -> None:
        d, lay = sim.data, self.lay
        row = {
            "time": d.time - self.dt,
            "gyro_pitch": d.sensordata[lay.s_gyro_pitch],
            "wheel_speed": d.sensordata[lay.s_wheel_speed],
            "wheel_torque_cmd": sim.controller.wheel_command,  # asked, before the delay line
            "wheel_torque": d.actuator_force[lay.a_wheel] * lay.wheel_gear,  # applied
            "foot_L_force": d.sensordata[lay.s_foot_l],
            "foot_R_force": d.sensordata[lay.s_foot_r],
            "pitch": d.sensordata[lay.s_pitch],
            "x": d.xpos[self.torso][0],
            "z": d.xpos[self.torso][2],
            "vx": self.qvel[lay.v_x],
            "vz": self.qvel[lay.v_z],
        }
        for j, q, a in zip(LEG_JOINTS, lay.q_legs, lay.a_legs, strict=True):
            row[j], row[f"{j}_torque_cmd"] = self.qpos[q], d.actuator_force[a]
        self.qpos[:], self.qvel[:] = d.qpos, d.qvel
        for name, value in row.items():
            self.rows.setdefault(name, []).append(float(value))

    def event(self, sim: Simulation, event: object) -> None:
        pass


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, np.ndarray]]:
    """One hop on flat ground, recorded, and the truth of every tick."""
    path = tmp_path_factory.mktemp("rrd") / "hop.rrd"
    sim = Simulation(SimConfig(terrain="flat"))
    truth = Truth(sim)
    with Telemetry(sim, path=path):
        sim.listeners.append(truth)
        sim.run(1)
    return path, {name: np.array(values) for name, values in truth.rows.items()}


def test_every_column_is_the_recorded_physics_in_si(recorded) -> None:
    path, truth = recorded
    log = read_log(path)
    assert isinstance(log, Log) and log.has_state() and log.gaps == ()
    np.testing.assert_allclose(log.time, truth["time"], atol=1e-9)
    float32 = ("gyro_pitch", "wheel_speed", "wheel_torque_cmd", "pitch")
    for name in float32:  # recorded as float32 in deg, rpm, N m
        np.testing.assert_allclose(log.signals[name], truth[name], rtol=1e-6, atol=1e-6, err_msg=name)
    np.testing.assert_array_equal(log.signals["pitch_rate"], log.signals["gyro_pitch"])
    for name in (*LEG_JOINTS, *(f"{j}_torque_cmd" for j in LEG_JOINTS), "foot_L_force", "foot_R_force"):
        scale = np.abs(truth[name]).max()  # float16: 11 significant bits
        np.testing.assert_allclose(log.signals[name], truth[name], rtol=1e-3, atol=1e-3 * scale, err_msg=name)
    assert np.ptp(log.signals["hip_L"]) > 0.1 and log.signals["foot_L_force"].max() > 10.0  # a hop, not a stand


def test_the_state_comes_from_the_50_hz_poses(recorded) -> None:
    """x, z: linear interpolation of a 20 ms flight arc is exact to g dt^2 / 8 (80 um on the Moon);
    vx, vz: central differences over 40 ms round each touchdown's step in velocity."""
    path, truth = recorded
    log = rrd_log.read(path)
    for name in ("x", "z"):
        assert np.abs(log.signals[name] - truth[name]).max() < 5e-4, name  # m
    for name in ("vx", "vz"):
        error = np.abs(log.signals[name] - truth[name])
        assert np.median(error) < 2e-3 and error.max() < 0.1, (name, np.median(error), error.max())  # m/s


def test_the_source_says_what_stands_in_for_what(recorded) -> None:
    path, _ = recorded
    said = "our .rrd: leg torques applied, gyro noise-free, x z vx vz from 50 Hz poses"
    assert rrd_log.read(path).source == f"{path} ({said})"


def test_our_rrd_exported_to_mcap_reads_back_the_same(recorded, tmp_path: Path) -> None:
    path, _ = recorded
    log = rrd_log.read(path)
    back = mcap_log.read(mcap_log.write(log, tmp_path / "hop.mcap"))
    assert back.source == f"{tmp_path / 'hop.mcap'} (written from {log.source})"
    np.testing.assert_array_equal(back.time, log.time)
    assert all(np.array_equal(back.signals[k], v) for k, v in log.signals.items())


def test_files_that_are_no_hopper_recording_are_refused(recorded, tmp_path: Path) -> None:
    empty = tmp_path / "empty.rrd"
    empty.write_bytes(b"")
    assert "empty file" in bad_logs.refused(rrd_log.read, empty)
    text = tmp_path / "text.rrd"
    text.write_text("time [s],gyro_pitch [rad/s]\n0,0\n")
    assert "not a rerun recording" in bad_logs.refused(rrd_log.read, text)
    whole = recorded[0].read_bytes()
    torn = tmp_path / "torn.rrd"
    torn.write_bytes(whole[: len(whole) // 3])
    message = bad_logs.refused(rrd_log.read, torn)
    assert "not a rerun recording, or one cut short" in message and message.count(str(torn)) == 1, message
    other = tmp_path / "other.rrd"
    rec = rr.RecordingStream("not-hopper")
    rec.save(str(other))
    rec.set_time("sim_time", duration=0.0)
    rec.log("points", rr.Points3D([[0.0, 0.0, 0.0]]))
    rec.flush()
    rec.disconnect()
    assert "no 'signals' entity: not a hopper recording" in bad_logs.refused(rrd_log.read, other)


def test_the_recordings_world_is_its_config_property(recorded) -> None:  # noqa: ANN001
    from hopper.logs.world import World
    from hopper.robot import PACKAGED

    path, _ = recorded
    # Ideal sensing: the command reaches the motor in the same tick; the motor is the packaged one.
    motor = (PACKAGED.wheel_torque_limit, PACKAGED.wheel_damping)
    world = World(terrain="flat", seed=0, gravity=SimConfig().gravity, delay_ticks=0, wheel_motor=motor)
    assert rrd_log.read(path).world == world


MISMATCH = (("torso_mass", 1.2), ("wheel_inertia", 0.85), ("motor_torque", 0.9))


@pytest.fixture(scope="module")
def mismatched(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three hops of a robot that differs from the one its controller knows, realistic sensing, recorded."""
    path = tmp_path_factory.mktemp("rrd") / "mismatched.rrd"
    sim = Simulation(SimConfig(terrain="flat", sensing="realistic", seed=5, mismatch=MISMATCH))
    with Telemetry(sim, path=path):
        sim.run(3)
    return path


def replayed_pitch_rms(log: Log, mismatch: tuple) -> float:
    """Pitch RMS (deg) of the log's hops replayed re-anchored on the nominal robot with `mismatch`."""
    from hopper.logs.replay import REANCHOR_S, Errors, replay_hops, world_model
    from hopper.logs.world import resolve
    from hopper.mismatch import Nominal

    world, _ = resolve(log.world)
    model, window = world_model(world)
    Nominal.of(model).apply(model, mismatch)
    parts = replay_hops(model, log, window=window, delay_ticks=world.command_delay, drive=world.drive, every=REANCHOR_S)
    return float(np.degrees(Errors.concat([e for _, e in parts]).rms("pitch")))


def test_a_recording_keeps_the_wheel_command_so_its_replay_finds_the_robot_that_flew(mismatched: Path) -> None:
    """The wheel's command column is what the controller asked, 3 ticks before the motor under
    realistic sensing: replayed, the recording tells the robot that flew it from the nominal one.
    With the applied torque for the command and no delay, as recordings had it, the replay found
    the nominal robot (0.28 deg) and not the true one (7.1 deg)."""
    log = rrd_log.read(mismatched)
    assert log.world is not None and log.world.delay_ticks == 3
    true, nominal = replayed_pitch_rms(log, MISMATCH), replayed_pitch_rms(log, ())
    assert true < 0.5 and nominal > 10 * true, (true, nominal)


def test_a_recording_made_before_the_command_was_kept_reads_with_the_applied_torque(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from hopper.telemetry import recorder, schema

    # A recorder of before: no wheel_cmd_nm among its signals, no delay or motor in its config.
    old = tuple(s for s in schema.SIGNALS_F32 if s != "wheel_cmd_nm")
    monkeypatch.setattr(recorder, "SIGNALS_F32", old)
    monkeypatch.setattr(recorder, "SIGNALS", old + schema.SIGNALS_F16)
    path = tmp_path / "old.rrd"
    sim = Simulation(SimConfig(terrain="flat", sensing="realistic"))
    truth = Truth(sim)
    with Telemetry(sim, path=path):
        sim.listeners.append(truth)
        sim.run(1)
    log = rrd_log.read(path)
    assert "applied torques stand in for the commands" in log.source
    assert log.world is not None and log.world.delay_ticks == 0 and log.world.wheel_motor is None
    np.testing.assert_allclose(log.signals["wheel_torque_cmd"], truth.rows["wheel_torque"], rtol=1e-6, atol=1e-6)
