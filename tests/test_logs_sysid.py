"""hopper.logs.sysid: small fits with known truth (the full round trip is benchmarks/identify_roundtrip.py)."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from hopper.config import SensingParams, SimConfig
from hopper.logs import replay, sysid
from hopper.logs.capture import capture
from hopper.logs.replay import World, world_model
from hopper.logs.schema import Log
from hopper.mismatch import Nominal
from hopper.model import MODEL_XML

K_T, BIAS = 0.85, -0.4  # the logged robot's motor constant (x nominal) and gyro bias (deg/s)


@pytest.fixture(scope="module")
def log() -> Log:
    config = SimConfig(
        terrain="flat",
        sensing="realistic",
        seed=11,
        mismatch=(("motor_torque", K_T),),
        sensor=SensingParams(gyro_turn_on_bias=0.0, gyro_bias_fixed=BIAS),
    )
    return capture(config, 2).log


def test_the_motor_constant_and_the_gyro_bias_are_found(log: Log) -> None:
    model, _ = world_model(World())
    flight = sysid.hop_span(log, 0, 1)
    fit = sysid.identify(model, log, flight, ("motor_torque", "gyro_bias"), stages=(0.1,), max_evaluations=20)
    found = fit.values
    assert found["motor_torque"] == pytest.approx(K_T, rel=0.005)
    assert found["gyro_bias"] == pytest.approx(BIAS, abs=0.02)  # 3300 samples of 0.44 deg/s noise: 0.008
    for e in fit.estimates:
        assert 0.0 < e.sigma < 0.01 * max(abs(e.value), 1.0)
    assert fit.residual_after["pitch"] < 0.01 * fit.residual_before["pitch"]
    assert fit.not_separable() == []
    # the model is left at the estimate: it now replays the flight it was fitted on
    flights = replay.flights(log)[:1]
    nominal, _ = world_model(World())
    before = replay.replay_spans(nominal, log, flights)[0][1]
    after = replay.replay_spans(model, log, flights)[0][1]
    assert after.rms("pitch") < 0.01 * before.rms("pitch")


def test_what_a_flight_cannot_tell_apart_is_reported(log: Log) -> None:
    """In flight, k_t, the armature's share and the damping beyond k_t^2 act on the wheel through
    combinations only: the fit must say so rather than print confident numbers."""
    model, _ = world_model(World())
    names = ("wheel_inertia", "wheel_armature", "motor_torque", "motor_damping")
    fit = sysid.identify(model, log, replay.flights(log)[0], names, stages=(0.1,), max_evaluations=8)
    tangled = {n for pair in fit.not_separable() for n in pair[:2]}
    assert {"wheel_armature", "motor_torque", "motor_damping"} <= tangled
    assert all(abs(c) >= sysid.NOT_SEPARABLE for *_, c in fit.not_separable())


def test_bad_requests_are_refused(log: Log) -> None:
    model, _ = world_model(World())
    with pytest.raises(sysid.IdentifyError, match="unknown parameter.*leg_length; choose from torso_mass"):
        sysid.identify(model, log, (0, 1000), ("leg_length",))
    with pytest.raises(sysid.IdentifyError, match="parameter.*torso_mass given more than once"):
        sysid.identify(model, log, (0, 1000), ("torso_mass", "gyro_bias", "torso_mass"), stages=(0.1,))
    with pytest.raises(sysid.IdentifyError, match="has 2 hop.*hops 1..7"):
        sysid.hop_span(log, 0, 7)
    with pytest.raises(sysid.IdentifyError, match="positive"):
        sysid.identify(model, log, (0, 1000), ("friction",), stages=(0.0,))
    with pytest.raises(sysid.IdentifyError, match="max_evaluations must be at least 1, got 0"):
        sysid.identify(model, log, (0, 1000), ("friction",), stages=(0.1,), max_evaluations=0)


@pytest.mark.parametrize("spin", [0.0325125, 0.0286867, 0.04])
def test_a_thin_wheel_stays_a_valid_mjcf(spin: float, tmp_path: Path) -> None:
    """The wheel is a thin disc (A + B = C): scaled and rounded to MJCF's 6 digits, it must still load."""
    model, _ = world_model(World())
    path = tmp_path / "wheel.xml"
    path.write_text(sysid.to_spec(mujoco.MjSpec.from_file(str(MODEL_XML)), model, {"wheel_inertia": spin}).to_xml())
    loaded = mujoco.MjModel.from_xml_path(str(path))
    assert sysid.nominal(loaded)["wheel_inertia"] == pytest.approx(spin, rel=1e-5)


def test_the_identified_model_is_written_as_mjcf(tmp_path: Path) -> None:
    model, _ = world_model(World())
    values = {
        "torso_mass": 4.7, "torso_inertia": 0.1, "torso_com_x": 0.012, "torso_com_z": -0.004,
        "wheel_inertia": 0.031, "wheel_armature": 0.004, "motor_torque": 0.93, "motor_damping": 1.1,
        "friction": 0.55, "gyro_bias": 0.3,
    }  # fmt: skip
    spec = sysid.to_spec(mujoco.MjSpec.from_file(str(MODEL_XML)), model, values)
    path = tmp_path / "identified.xml"
    path.write_text(spec.to_xml())
    loaded = mujoco.MjModel.from_xml_path(str(path))
    read = sysid.nominal(loaded)  # the motor's factors and the bias are not in nominal(): checked below
    for name in ("torso_mass", "torso_inertia", "torso_com_x", "torso_com_z", "wheel_inertia", "wheel_armature"):
        assert read[name] == pytest.approx(values[name], rel=1e-5, abs=1e-9), name  # MJCF: 6 digits
    assert np.all(loaded.geom_friction[:, 0] == pytest.approx(0.55))
    base = Nominal.of(model)
    motor = loaded.actuator("wheel").id
    assert loaded.actuator_gainprm[motor, 0] == pytest.approx(0.93 * base.actuator_gainprm[motor, 0])
    assert loaded.actuator_biasprm[motor, 2] == pytest.approx(0.93**2 * 1.1 * base.actuator_biasprm[motor, 2])
    assert loaded.actuator_forcerange[motor] == pytest.approx(0.93 * base.actuator_forcerange[motor])
    assert loaded.numeric("gyro_bias").data[0] == pytest.approx(math.radians(0.3))
    # and a model set by Robot.set is the same robot as the one compiled from the file
    robot = sysid.Robot(model)
    robot.set({k: v for k, v in values.items() if k != "gyro_bias"})
    for field in ("body_mass", "body_inertia", "body_ipos", "dof_armature", "actuator_gainprm", "actuator_biasprm"):
        assert np.allclose(getattr(model, field), getattr(loaded, field), rtol=1e-5, atol=1e-9), field


def test_friction_is_found_by_its_line_search() -> None:
    """Friction's cost is piecewise (a foot slips or sticks): least squares alone stalls short of it."""
    config = SimConfig(terrain="flat", sensing="realistic", seed=4, mismatch=(("friction", 0.75),))
    log = capture(config, 1).log
    model, _ = world_model(World())
    fit = sysid.identify(model, log, sysid.hop_span(log, 0, 1), ("friction",), stages=(0.05,), max_evaluations=6)
    assert fit.values["friction"] == pytest.approx(0.6, rel=0.10)  # the tolerance for friction
    low, high = fit.profile["friction"]
    assert low <= fit.values["friction"] <= high


def test_the_residuals_before_and_after_are_over_the_last_stages_windows(log: Log) -> None:
    """identify printed stage 1's 0.05 s windows as 'before' beside the last stage's 0.3 s as 'after'."""
    model, _ = world_model(World())
    flight, names = replay.flights(log)[0], ("motor_torque",)
    fit = sysid.identify(model, log, flight, names, stages=(0.05, 0.3), max_evaluations=3)
    fresh, _ = world_model(World())
    last = sysid.Problem(sysid.Robot(fresh), log, replay.windows(log, flight, 0.3), names, sysid.DEFAULT_DELAY_TICKS)
    assert fit.windows == len(last.spans)
    assert fit.residual_before == pytest.approx(last.channel_rms(last.residuals(np.zeros(1))), rel=1e-12)
    z = np.array([(fit.values["motor_torque"] - 1.0) / last.scale[0]])
    assert fit.residual_after == pytest.approx(last.channel_rms(last.residuals(z)), rel=1e-9)


def test_the_motor_of_a_robot_with_its_own_motor_is_found(tmp_path: Path) -> None:
    """A --model robot's commands are made for its own motor (k_t 0.85): the fit's drive inverts that
    motor and the candidate's turns the voltage into torque, so motor_torque is found against the
    packaged model's (it came out 1.0008 while the drive inverted the packaged motor)."""
    import variants

    from hopper.logs.world import resolve

    path = str(variants.motor_constant(tmp_path, 0.85))
    log = capture(SimConfig(terrain="flat", sensing="realistic", seed=3, model=path), 1).log
    world, _ = resolve(log.world)  # the packaged model, the log's drive
    model, _ = world_model(world)
    flight = replay.flights(log)[0]
    fit = sysid.identify(model, log, flight, ("motor_torque",), stages=(0.3,), max_evaluations=10, drive=world.drive)
    assert fit.values["motor_torque"] == pytest.approx(0.85, rel=0.01)
