"""Users' models for the tests, derived from the packaged MJCF with mujoco.MjSpec (STYLE.md item 31)."""

from __future__ import annotations

from pathlib import Path

import mujoco

from hopper.model import MODEL_XML


def packaged() -> mujoco.MjSpec:
    return mujoco.MjSpec.from_string(MODEL_XML.read_text(encoding="utf-8"))


def longer_legs(spec: mujoco.MjSpec, factor: float) -> None:
    """Both legs `factor` times as long: knee, foot, capsules and the shanks' and thighs' centres of mass."""
    for side in "LR":
        thigh, shank = spec.body(f"thigh_{side}"), spec.body(f"shank_{side}")
        shank.pos = [p * factor for p in shank.pos]
        for body in (thigh, shank):
            body.ipos = [p * factor for p in body.ipos]
            for geom in body.geoms:
                if geom.type == mujoco.mjtGeom.mjGEOM_CAPSULE:
                    geom.fromto = [p * factor for p in geom.fromto]
        spec.geom(f"foot_{side}").pos = [p * factor for p in spec.geom(f"foot_{side}").pos]
        spec.site(f"foot_{side}").pos = [p * factor for p in spec.site(f"foot_{side}").pos]


def variant(folder: Path, wheel_inertia: float = 1.3, legs: float = 1.1, name: str = "variant.xml") -> Path:
    """The issue's variant: the wheel's inertia x `wheel_inertia`, legs x `legs` long; its path."""
    spec = packaged()
    wheel = spec.body("wheel")
    wheel.inertia = [i * wheel_inertia for i in wheel.inertia]
    longer_legs(spec, legs)
    path = folder / name
    path.write_text(spec.to_xml(), encoding="utf-8")
    return path


def renamed_actuator(folder: Path, old: str = "wheel", new: str = "wheel_motor") -> Path:
    """The packaged model with actuator `old` renamed `new` (its sensor follows); its path."""
    spec = packaged()
    spec.actuator(old).name = new
    for sensor in spec.sensors:
        if sensor.objname == old and sensor.objtype == mujoco.mjtObj.mjOBJ_ACTUATOR:
            sensor.objname = new
    path = folder / "renamed.xml"
    path.write_text(spec.to_xml(), encoding="utf-8")
    return path


def stronger_motor(folder: Path, factor: float = 1.2) -> Path:
    """The packaged model with a wheel motor `factor` times as strong (stall torque and no-load speed)."""
    spec = packaged()
    motor = spec.actuator("wheel")
    motor.gainprm = [motor.gainprm[0] * factor, *motor.gainprm[1:]]
    motor.forcerange = [r * factor for r in motor.forcerange]
    path = folder / "stronger.xml"
    path.write_text(spec.to_xml(), encoding="utf-8")
    return path


def motor_constant(folder: Path, k: float) -> Path:
    """The packaged model with its wheel motor's k_t times `k`, as hopper.mismatch's motor_torque: the
    stall torque (gain and force range) x k, the back-EMF slope x k^2; its path."""
    spec = packaged()
    motor = spec.actuator("wheel")
    motor.gainprm = [motor.gainprm[0] * k, *motor.gainprm[1:]]
    motor.biasprm = [*motor.biasprm[:2], motor.biasprm[2] * k * k, *motor.biasprm[3:]]
    motor.forcerange = [r * k for r in motor.forcerange]
    path = folder / f"kt{k:g}.xml"
    path.write_text(spec.to_xml(), encoding="utf-8")
    return path
