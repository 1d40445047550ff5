"""The robot's constants the controller uses (mass, wheel, motors, leg geometry), read from a compiled model once."""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np

from hopper import config
from hopper.errors import ModelError

# The packaged XML writes its wheel motor to 4 significant figures (gain 0.9833 N m, slope 0.0007825
# N m s/rad at the motor: 29.499 N m and 41.8871 rad/s at the wheel); its figures are Table I's
# 29.5 N m and 400 rpm. A model's figure within this share of the packaged robot's is that figure.
PACKAGED_TOLERANCE = 1e-4
WHEEL_ACTUATOR_GROUP = 1  # models/hopper.xml: disabling this group turns the wheel off (hopper.model)
SAME = 1e-9  # m or share: what counts as equal in the geometry the controller assumes


@dataclasses.dataclass(frozen=True, kw_only=True)
class Robot:
    """What the controller knows of the robot it flies, SI units; `Robot.of(model)` reads it.

    The controller assumes a planar biped: each leg a thigh and an equal shank hanging straight
    down from a hip below the torso's frame origin, a spherical foot, leg motors acting on their
    joints directly (gear 1, ctrl in N m), and the wheel's voltage-driven DC motor (ctrl in [-1, 1],
    force = gain u - slope v, models/hopper.xml).
    """

    mass: float  # kg, the whole robot (the torso's subtree)
    wheel_inertia: float  # kg m^2, the wheel body's about its axle
    wheel_armature: float  # kg m^2, the motor's reflected rotor inertia on the wheel joint
    wheel_gear: float  # wheel torque / motor torque
    wheel_torque_limit: float  # N m at the wheel: the stall torque
    wheel_no_load_speed: float  # rad/s at the wheel
    leg_torque_limit: float  # N m at each leg joint
    thigh: float  # m, hip to knee
    shank: float  # m, knee to the foot's centre
    hip_z: float  # m, the hips above the torso frame's origin (negative: below)
    foot_y: float  # m, each leg's lateral offset (left +y, right -y)
    foot_radius: float  # m

    @property
    def spin_inertia(self) -> float:
        """kg m^2, what the wheel motor spins: the wheel and the rotor reflected through the gear."""
        return self.wheel_inertia + self.wheel_armature

    @property
    def wheel_damping(self) -> float:
        """N m s/rad at the wheel, the back-EMF slope: the stall torque over the no-load speed."""
        return self.wheel_torque_limit / self.wheel_no_load_speed

    @property
    def momentum_capacity(self) -> float:
        """N m s, the wheel's momentum at its no-load speed, armature included (PHYSICS.md)."""
        return self.spin_inertia * self.wheel_no_load_speed

    def wheel_torque_bound(self, wheel_speed: float, torque: float) -> float:
        """`torque` (N m) clamped to the motor's torque-speed envelope at `wheel_speed` (rad/s)."""
        limit, back_emf = self.wheel_torque_limit, self.wheel_damping * wheel_speed
        return min(max(torque, max(-limit, -limit - back_emf)), min(limit, limit - back_emf))

    @classmethod
    def of(cls, model: mujoco.MjModel, source: str = "the model") -> Robot:
        """Read the constants from `model` (compiled, before any mismatch); ModelError, naming
        `source` and the assumption, for a robot the controller does not describe."""
        return _read(model, source)


# The packaged robot, as config.py states it (tests/test_robot_model.py reads models/hopper.xml back to it).
PACKAGED = Robot(
    mass=config.TOTAL_MASS,
    wheel_inertia=config.WHEEL_INERTIA,
    wheel_armature=config.WHEEL_ARMATURE,
    wheel_gear=config.WHEEL_GEAR,
    wheel_torque_limit=config.WHEEL_TORQUE_LIMIT,
    wheel_no_load_speed=config.WHEEL_NO_LOAD_SPEED,
    leg_torque_limit=config.LEG_TORQUE_LIMIT,
    thigh=config.THIGH_LENGTH,
    shank=config.SHANK_LENGTH,
    hip_z=config.HIP_OFFSET_Z,
    foot_y=0.11,  # m, models/hopper.xml: the thighs sit at y = +-0.11
    foot_radius=config.FOOT_RADIUS,
)


def _read(model: mujoco.MjModel, source: str) -> Robot:
    def refuse(why: str) -> ModelError:
        return ModelError(f"model {source}: {why}")

    wheel_joint = model.joint("wheel")
    wheel_body = model.body("wheel").id
    # The wheel body's inertia about its axle: the principal moments weighted by the axle's
    # direction in the principal frame (body_iquat turns the principal frame into the body's).
    frame = np.empty(9)
    mujoco.mju_quat2Mat(frame, model.body_iquat[wheel_body])
    axis = frame.reshape(3, 3).T @ model.jnt_axis[wheel_joint.id]
    spin = float(np.dot(model.body_inertia[wheel_body], axis * axis))
    motor = model.actuator("wheel")
    gain, slope, gear = float(motor.gainprm[0]), -float(motor.biasprm[2]), float(motor.gear[0])
    dc_motor = (
        motor.gaintype[0] == mujoco.mjtGain.mjGAIN_FIXED
        and motor.biastype[0] == mujoco.mjtBias.mjBIAS_AFFINE
        and motor.biasprm[0] == 0.0
        and motor.biasprm[1] == 0.0
        and gain > 0.0
        and slope > 0.0
        and gear > 0.0
        and bool(motor.ctrllimited[0])
        and tuple(motor.ctrlrange) == (-1.0, 1.0)
    )
    if not dc_motor:
        raise refuse(
            "actuator 'wheel' must be a voltage-driven DC motor as in models/hopper.xml (general, gear > 0, "
            "ctrlrange -1 1, gainprm K > 0, biastype affine, biasprm 0 0 -b with b > 0)"
        )
    if motor.group[0] != WHEEL_ACTUATOR_GROUP:
        raise refuse(f"actuator 'wheel' must be in group {WHEEL_ACTUATOR_GROUP} (wheel off disables that group)")
    stall = gain if not motor.forcelimited[0] else min(gain, float(motor.forcerange[1]))
    legs = [model.actuator(j) for j in ("hip_L", "knee_L", "hip_R", "knee_R")]
    if any(a.gear[0] != 1.0 for a in legs):
        raise refuse("the leg actuators must act on their joints directly (gear 1: the controller's ctrl is N m)")
    limits = [
        min(
            float(a.ctrlrange[1]) if a.ctrllimited[0] else math.inf,
            float(a.forcerange[1]) if a.forcelimited[0] else math.inf,
        )
        for a in legs
    ]
    if not all(0.0 < v < math.inf for v in limits):
        raise refuse("each leg actuator needs a torque limit (ctrlrange or forcerange, N m)")
    geometry = {}
    for side in "LR":
        hip = model.body_pos[model.body(f"thigh_{side}").id]
        knee = model.body_pos[model.body(f"shank_{side}").id]
        foot = model.site_pos[model.site(f"foot_{side}").id]
        if model.site_bodyid[model.site(f"foot_{side}").id] != model.body(f"shank_{side}").id:
            raise refuse(f"site 'foot_{side}' must be on body 'shank_{side}'")
        if abs(hip[0]) > SAME or abs(knee[0]) > SAME or abs(foot[0]) > SAME or knee[2] >= 0.0 or foot[2] >= 0.0:
            raise refuse(f"leg {side}: the hip must sit under the torso's origin (x = 0) and the knee and foot hang "
                         f"straight below it (shank_{side} and site foot_{side} at x = 0, z < 0)")  # fmt: skip
        foot_geom = model.geom(f"foot_{side}").id
        if model.geom_type[foot_geom] != mujoco.mjtGeom.mjGEOM_SPHERE:
            raise refuse(f"geom 'foot_{side}' must be a sphere")
        geometry[side] = (
            -float(knee[2]),
            -float(foot[2]),
            float(hip[2]),
            float(hip[1]),
            float(model.geom_size[foot_geom, 0]),
        )
    (thigh, shank, hip_z, foot_y, radius), right = geometry["L"], geometry["R"]
    mirrored = (thigh, shank, hip_z, -foot_y, radius)
    if any(abs(a - b) > SAME for a, b in zip(mirrored, right, strict=True)):
        raise refuse("the right leg must mirror the left (thigh, shank, hip height, lateral offset, foot radius)")
    if abs(thigh - shank) > SAME * max(thigh, 1.0):
        raise refuse(f"the controller's virtual leg needs a shank as long as the thigh (got {thigh:g} and {shank:g} m)")
    read = Robot(
        mass=float(model.body_subtreemass[model.body("torso").id]),
        wheel_inertia=spin,
        wheel_armature=float(model.dof_armature[wheel_joint.dofadr[0]]),
        wheel_gear=gear,
        wheel_torque_limit=gear * stall,
        wheel_no_load_speed=gain / (slope * gear),  # force K u - b (gear w) is zero at u = 1
        leg_torque_limit=min(limits),
        thigh=thigh,
        shank=shank,
        hip_z=hip_z,
        foot_y=foot_y,
        foot_radius=radius,
    )
    return _packaged_figures(read)


def _packaged_figures(robot: Robot) -> Robot:
    """`robot` with each figure within PACKAGED_TOLERANCE of the packaged robot's replaced by it."""
    changes = {}
    for field in dataclasses.fields(Robot):
        value, rated = getattr(robot, field.name), getattr(PACKAGED, field.name)
        if value != rated and abs(value - rated) <= PACKAGED_TOLERANCE * abs(rated):
            changes[field.name] = rated
    return dataclasses.replace(robot, **changes)
