"""The simulated dynamics against references: momentum, the reduced model, ballistics."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from hopper.config import SimConfig
from hopper.model import MODEL_XML, build_model


def _airborne(model: mujoco.MjModel) -> mujoco.MjData:
    """The robot high above the terrain (no contact), legs folded, at rest."""
    data = mujoco.MjData(model)
    data.joint("root_z").qpos = 5.0
    for side in "LR":
        data.joint(f"hip_{side}").qpos = 0.6
        data.joint(f"knee_{side}").qpos = -1.2
    mujoco.mj_forward(model, data)
    return data


def _pitch_momentum(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    mujoco.mj_subtreeVel(model, data)
    return float(data.subtree_angmom[model.body("torso").id, 1])


def test_flight_conserves_pitch_momentum_while_the_wheel_and_legs_move() -> None:
    """Real flights of the hop controller: the PID drives the wheel, the legs swing to land.

    The controller leaves the ground with almost no momentum, so each flight starts with a
    pitch kick (alternating sign): the wheel must then carry 0.6 N m s all through the flight.
    """
    from hopper.control import Phase
    from hopper.events import EventKind
    from hopper.sim import Simulation
    from hopper.state import angular_momentum

    sim = Simulation(SimConfig(terrain="flat"))
    flights: list[list[float]] = [[]]
    wheel_speeds = []
    kicks = 0
    while len(sim.hops) < 3:
        if sim.step() and sim.events[-1].kind is EventKind.LIFTOFF:
            sim.disturb("pitch_kick", 0.6 * (-1) ** kicks)
            kicks += 1
        if sim.phase is Phase.FLIGHT and sim.data.ncon == 0:  # debounced phases lag contact by ms
            flights[-1].append(angular_momentum(sim.model, sim.data, sim.layout))
            wheel_speeds.append(abs(sim.data.joint("wheel").qvel[0]))
        elif flights[-1]:
            flights.append([])
    assert max(wheel_speeds) > 10.0  # rad/s: the wheel really was driven
    for momentum in flights[:-1]:
        h = np.array(momentum[5:-5])  # away from the contact transitions
        assert abs(h[0]) > 0.1
        assert np.abs(h - h[0]).max() / abs(h[0]) < 1e-3


def _locked_legs_model() -> mujoco.MjModel:
    """The robot with its leg joints removed: legs welded to the torso, as the reduced model assumes."""
    spec = mujoco.MjSpec.from_string(MODEL_XML.read_text())
    for name in ("hip_L", "knee_L", "hip_R", "knee_R"):
        spec.delete(spec.joint(name))
    for name in ("hip_L", "knee_L", "hip_R", "knee_R"):
        spec.delete(spec.sensor(f"{name}_torque"))  # the energy metrics' actuatorfrc sensors go with them
        spec.delete(spec.actuator(name))
    for name in ("foot_L", "foot_R"):  # keep the feet out of the way of the terrain
        spec.geom(name).contype = 0
    spec.geom("torso").contype = 0
    return spec.compile()


@pytest.mark.parametrize("armature", [0.0, None])
def test_torso_acceleration_matches_the_reduced_model(armature: float | None) -> None:
    """(I_locked - I_w) theta_ddot = -tau_w in flight (PHYSICS.md), with the rotor's armature a:
    theta_ddot = -I_w tau / (I_locked (I_w + a) - I_w^2)."""
    model = _locked_legs_model()
    dof = model.joint("wheel").dofadr[0]
    if armature is not None:
        model.dof_armature[dof] = armature
    a = model.dof_armature[dof]
    data = mujoco.MjData(model)
    data.joint("root_z").qpos = 5.0
    # I_locked: angular momentum about the CoM for a unit pitch rate with the wheel locked.
    data.joint("pitch").qvel = 1.0
    mujoco.mj_forward(model, data)
    i_locked = _pitch_momentum(model, data)
    i_w = model.body("wheel").inertia.max()
    assert 0.25 < i_locked < 0.8
    data.qvel[:] = 0.0
    for ctrl in (0.3, -1.0):
        data.ctrl[model.actuator("wheel").id] = ctrl
        mujoco.mj_forward(model, data)
        tau = data.actuator_force[model.actuator("wheel").id] * 30
        expected = -i_w * tau / (i_locked * (i_w + a) - i_w**2)
        assert data.joint("pitch").qacc[0] == pytest.approx(expected, rel=0.02)


def test_ballistic_apex_matches_v_squared_over_2g() -> None:
    for gravity in (1.625, 3.72):
        model = build_model(SimConfig(terrain="flat", gravity=gravity))
        model.opt.disableactuator = 0xFF  # no motors: a rigid ballistic body
        data = _airborne(model)
        v = 1.2
        data.qvel[model.joint("root_z").dofadr[0]] = v
        z0, top = data.qpos[1], data.qpos[1]
        while data.qvel[model.joint("root_z").dofadr[0]] > 0:
            mujoco.mj_step(model, data)
            top = max(top, data.qpos[1])
        assert top - z0 == pytest.approx(v**2 / (2 * gravity), rel=0.01)
