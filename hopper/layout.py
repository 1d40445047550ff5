"""Where the robot's joints, sensors, actuators and bodies live in MjModel's arrays, resolved by name once."""

from __future__ import annotations

import dataclasses

import mujoco

from hopper.errors import ModelError

LEG_JOINTS = ("hip_L", "knee_L", "hip_R", "knee_R")
# Every name the product looks up in a model (models/hopper.xml), by kind: a user's model
# (`--model`) must have them all (check_names).
NAMES: dict[str, tuple[str, ...]] = {
    "joint": ("root_x", "root_z", "pitch", "wheel", *LEG_JOINTS),
    "actuator": ("wheel", *LEG_JOINTS),
    "sensor": ("imu_pitch", "imu_gyro", "wheel_speed", "foot_L", "foot_R", "wheel_torque", "imu_accel", "com")
    + ("com_vel", "angmom", *(f"{j}_torque" for j in LEG_JOINTS)),
    "body": ("torso", "wheel", "thigh_L", "shank_L", "thigh_R", "shank_R"),
    "site": ("imu", "foot_L", "foot_R"),
    "geom": ("terrain", "torso", "foot_L", "foot_R"),
    "hfield": ("terrain",),
}
PLURAL = {"body": "bodies"}  # the MjSpec lists (spec.joints, spec.bodies, ...)


def check_names(spec: mujoco.MjSpec, source: str) -> None:
    """ModelError, in one line naming the first missing name of each kind and what is expected,
    unless `spec` (read from `source`) has every name of NAMES."""
    problems = []
    for kind, names in NAMES.items():
        found = [e.name for e in getattr(spec, PLURAL.get(kind, kind + "s"))]
        missing = [n for n in names if n not in found]
        if missing:
            others = ", ".join(repr(n) for n in found if n and n not in names) or "none"
            problems.append(
                f"no {kind} {', '.join(repr(n) for n in missing)} (the model's other {PLURAL.get(kind, kind + 's')}: "
                f"{others}; expected {', '.join(names)})"
            )
    if problems:
        raise ModelError(f"model {source}: " + "; ".join(problems))


@dataclasses.dataclass(frozen=True)
class ModelLayout:
    """Indices into MjData's arrays for the names in models/hopper.xml.

    Every reader (the control kernel, the state reader, telemetry) takes its indices from here,
    so reordering the model's joints or sensors is harmless. `q_*` index qpos, `v_*` qvel,
    `s_*` sensordata, `a_*` ctrl and actuator_force.
    """

    q_x: int
    q_z: int
    q_pitch: int
    q_wheel: int
    q_legs: tuple[int, int, int, int]  # LEG_JOINTS order
    v_x: int
    v_z: int
    v_pitch: int
    v_wheel: int
    v_legs: tuple[int, int, int, int]
    s_pitch: int  # imu_pitch: the pitch joint's angle (ground truth)
    s_gyro_pitch: int  # imu_gyro's body-y axis: pitch rate
    s_wheel_speed: int
    s_foot_l: int  # touch sensor, normal force (N)
    s_foot_r: int
    s_wheel_torque: int  # actuatorfrc of the wheel motor (motor side, before the gear)
    s_com: int  # subtreecom of the whole robot: world (x, y, z), m
    s_com_vel: int  # subtreelinvel: (vx, vy, vz), m/s
    s_angmom: int  # subtreeangmom about the robot's CoM, pitch (y) component, kg m^2/s
    s_accel: int  # imu_accel's x axis (z is s_accel + 2): specific force in the torso frame (m/s^2)
    s_leg_torques: tuple[int, int, int, int]  # actuatorfrc of each leg motor, LEG_JOINTS order
    a_wheel: int
    a_legs: tuple[int, int, int, int]
    torso: int  # body id
    wheel_gear: float
    leg_gear: float  # the leg actuators' gear: joint torque per unit of actuator force (1 in the XML)
    torso_origin: tuple[float, float]  # torso (x, z) in the XML: the slide joints measure from it

    @classmethod
    def of(cls, model: mujoco.MjModel) -> ModelLayout:
        """Look every name up in `model`; KeyError names anything missing."""

        def q(name: str) -> int:
            return int(model.joint(name).qposadr[0])

        def v(name: str) -> int:
            return int(model.joint(name).dofadr[0])

        def s(name: str, axis: int = 0) -> int:
            return int(model.sensor(name).adr[0]) + axis

        x, _, z = model.body("torso").pos.tolist()
        return cls(
            q_x=q("root_x"),
            q_z=q("root_z"),
            q_pitch=q("pitch"),
            q_wheel=q("wheel"),
            q_legs=tuple(q(j) for j in LEG_JOINTS),  # type: ignore[arg-type]
            v_x=v("root_x"),
            v_z=v("root_z"),
            v_pitch=v("pitch"),
            v_wheel=v("wheel"),
            v_legs=tuple(v(j) for j in LEG_JOINTS),  # type: ignore[arg-type]
            s_pitch=s("imu_pitch"),
            s_gyro_pitch=s("imu_gyro", 1),
            s_wheel_speed=s("wheel_speed"),
            s_foot_l=s("foot_L"),
            s_foot_r=s("foot_R"),
            s_wheel_torque=s("wheel_torque"),
            s_com=s("com"),
            s_com_vel=s("com_vel"),
            s_angmom=s("angmom", 1),
            s_accel=s("imu_accel"),
            s_leg_torques=tuple(s(f"{j}_torque") for j in LEG_JOINTS),  # type: ignore[arg-type]
            a_wheel=int(model.actuator("wheel").id),
            a_legs=tuple(int(model.actuator(j).id) for j in LEG_JOINTS),  # type: ignore[arg-type]
            torso=int(model.body("torso").id),
            wheel_gear=float(model.actuator("wheel").gear[0]),
            leg_gear=_one_gear(model),
            torso_origin=(x, z),
        )


def _one_gear(model: mujoco.MjModel) -> float:
    """The leg actuators' common gear (the kernel keeps one); ValueError if they differ."""
    gears = {float(model.actuator(j).gear[0]) for j in LEG_JOINTS}
    if len(gears) != 1:
        raise ValueError(f"the leg actuators must share one gear, got {sorted(gears)}")
    return gears.pop()
