"""The one read path for the robot's state: a named, immutable snapshot of MjData."""

from __future__ import annotations

import dataclasses

import mujoco

from hopper.layout import ModelLayout


@dataclasses.dataclass(frozen=True, slots=True)
class RobotState:
    """The robot at one instant, SI units, angles in rad; pitch + = nose down."""

    time: float  # s
    x: float  # m, torso CoM, world frame
    z: float  # m
    vx: float  # m/s
    vz: float  # m/s
    pitch: float  # rad, ground truth
    pitch_rate: float  # rad/s, the gyro's body-y axis
    wheel_angle: float  # rad, relative to the torso
    wheel_speed: float  # rad/s, relative to the torso
    wheel_torque: float  # N m at the wheel, as applied
    legs: tuple[float, float, float, float]  # rad, hip_L, knee_L, hip_R, knee_R
    foot_force_l: float  # N, touch sensor normal force
    foot_force_r: float  # N


def read_state(data: mujoco.MjData, layout: ModelLayout) -> RobotState:
    """Snapshot `data` (a few list reads; cheap enough for events and 30 Hz frames, not for every tick).

    Positions and velocities are MjData's current ones; the sensors (gyro, foot forces, wheel
    torque) are those of the last forward pass, i.e. of the start of the last step.
    """
    q, v, s = data.qpos.tolist(), data.qvel.tolist(), data.sensordata.tolist()
    x0, z0 = layout.torso_origin  # the slide joints measure from the torso's pose in the XML
    return RobotState(
        time=data.time,
        x=q[layout.q_x] + x0,
        z=q[layout.q_z] + z0,
        vx=v[layout.v_x],
        vz=v[layout.v_z],
        pitch=q[layout.q_pitch],
        pitch_rate=s[layout.s_gyro_pitch],
        wheel_angle=q[layout.q_wheel],
        wheel_speed=v[layout.v_wheel],
        wheel_torque=s[layout.s_wheel_torque] * layout.wheel_gear,
        legs=tuple(q[i] for i in layout.q_legs),  # type: ignore[arg-type]
        foot_force_l=s[layout.s_foot_l],
        foot_force_r=s[layout.s_foot_r],
    )


def angular_momentum(model: mujoco.MjModel, data: mujoco.MjData, layout: ModelLayout) -> float:
    """Total pitch angular momentum about the whole robot's CoM (kg m^2/s)."""
    mujoco.mj_subtreeVel(model, data)
    return float(data.subtree_angmom[layout.torso, 1])
