"""The MJCF: the paper's Table I, the sensors and actuators the controller relies on."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from hopper import config
from hopper.config import SimConfig
from hopper.layout import LEG_JOINTS, ModelLayout
from hopper.model import MODEL_XML, build_model, set_wheel_enabled
from hopper.state import read_state


def test_loads_on_its_own_with_moon_gravity_and_1khz() -> None:
    model = mujoco.MjModel.from_xml_string(MODEL_XML.read_text())
    assert model.opt.gravity[2] == pytest.approx(-1.625)
    assert model.opt.timestep == pytest.approx(0.001)
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICIT


def test_masses_match_table_one() -> None:
    model = mujoco.MjModel.from_xml_string(MODEL_XML.read_text())
    assert model.body_subtreemass[model.body("torso").id] == pytest.approx(8.2)
    masses = {n: model.body(n).mass[0] for n in ("torso", "wheel", "thigh_L", "shank_L", "thigh_R", "shank_R")}
    assert masses == pytest.approx(
        {"torso": 4.0, "wheel": 3.0, "thigh_L": 0.4, "shank_L": 0.2, "thigh_R": 0.4, "shank_R": 0.2}
    )
    # Wheel: 3 kg disc of radius 0.15 m about its spin axis (the largest principal moment).
    assert model.body("wheel").inertia.max() == pytest.approx(0.5 * 3.0 * 0.15**2)


def test_joint_ranges_and_foot_radius() -> None:
    model = mujoco.MjModel.from_xml_string(MODEL_XML.read_text())
    for side in "LR":
        assert np.degrees(model.joint(f"hip_{side}").range) == pytest.approx([-120, 120])
        assert np.degrees(model.joint(f"knee_{side}").range) == pytest.approx([-160, 0])
        assert model.geom(f"foot_{side}").size[0] == pytest.approx(0.04)
    assert not model.jnt_limited[model.joint("pitch").id]


def test_wheel_motor_envelope() -> None:
    """29.5 N m at stall through the 30:1 gear, falling linearly to zero at the no-load speed."""
    model = build_model(SimConfig(terrain="flat"))
    data = mujoco.MjData(model)
    wheel = model.actuator("wheel")
    assert wheel.gear[0] == 30
    dof = model.joint("wheel").dofadr[0]

    def torque(speed: float, ctrl: float) -> float:
        data.qvel[:] = 0
        data.qvel[dof] = speed
        data.ctrl[wheel.id] = ctrl
        mujoco.mj_forward(model, data)
        return data.actuator_force[wheel.id] * 30

    from hopper.config import WHEEL_NO_LOAD_SPEED

    assert torque(0.0, 1.0) == pytest.approx(29.5, rel=1e-3)
    assert torque(WHEEL_NO_LOAD_SPEED / 2, 1.0) == pytest.approx(29.5 / 2, rel=1e-3)
    assert torque(WHEEL_NO_LOAD_SPEED, 1.0) == pytest.approx(0.0, abs=1e-3)
    assert torque(-WHEEL_NO_LOAD_SPEED / 2, 1.0) == pytest.approx(29.5, rel=1e-3)  # current limit when braking
    set_wheel_enabled(model, False)
    assert torque(5.0, 1.0) == 0.0  # wheel off: no torque, and no back-EMF braking either


def test_the_state_reader_names_what_it_reads() -> None:
    model = build_model(SimConfig(terrain="flat"))
    data = mujoco.MjData(model)
    data.joint("pitch").qpos = 0.1
    data.joint("wheel").qvel = 7.0
    data.joint("hip_R").qpos = 0.3
    data.joint("root_x").qvel = 0.25
    mujoco.mj_forward(model, data)
    state = read_state(data, ModelLayout.of(model))
    assert state.pitch == pytest.approx(0.1)
    assert state.wheel_speed == pytest.approx(7.0)
    assert state.vx == pytest.approx(0.25)
    assert state.legs[2] == pytest.approx(0.3) and state.legs[:2] == (0.0, 0.0)
    assert (state.x, state.z) == pytest.approx((model.body("torso").pos[0], model.body("torso").pos[2]))
    assert not math.isnan(state.foot_force_l)


def test_config_constants_match_the_model() -> None:
    """hopper.config mirrors models/hopper.xml for the controller's kinematics: they must agree."""
    model = mujoco.MjModel.from_xml_string(MODEL_XML.read_text())
    wheel, thigh, shank = model.body("wheel"), model.body("thigh_L"), model.body("shank_L")
    assert model.body_subtreemass[model.body("torso").id] == pytest.approx(config.TOTAL_MASS)
    assert wheel.inertia.max() == pytest.approx(config.WHEEL_INERTIA)
    assert model.dof_armature[model.joint("wheel").dofadr[0]] == pytest.approx(config.WHEEL_ARMATURE)
    assert model.actuator("wheel").gear[0] == pytest.approx(config.WHEEL_GEAR)
    stall = model.actuator("wheel").gainprm[0] * config.WHEEL_GEAR
    assert stall == pytest.approx(config.WHEEL_TORQUE_LIMIT, rel=1e-3)
    # No-load speed at the wheel: where the motor's back-EMF cancels the stall torque.
    no_load = model.actuator("wheel").gainprm[0] / -model.actuator("wheel").biasprm[2] / config.WHEEL_GEAR
    assert no_load == pytest.approx(config.WHEEL_NO_LOAD_SPEED, rel=1e-3)
    assert thigh.pos[2] == pytest.approx(config.HIP_OFFSET_Z)
    assert -shank.pos[2] == pytest.approx(config.THIGH_LENGTH)
    assert -model.site("foot_L").pos[2] == pytest.approx(config.SHANK_LENGTH)
    assert model.geom("foot_L").size[0] == pytest.approx(config.FOOT_RADIUS)
    for leg in LEG_JOINTS:
        assert model.actuator(leg).ctrlrange == pytest.approx([-config.LEG_TORQUE_LIMIT, config.LEG_TORQUE_LIMIT])
