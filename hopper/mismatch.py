"""Model mismatch: the simulated robot differs from the one the controllers were designed for.

Each factor scales a group of the compiled model's parameters in place, each offset moves the
torso's centre of mass (restorable, so a batch reuses one model); the controllers keep designing on
the nominal model (hopper.laws.plant linearizes a mismatch-free copy) and the kernel keeps its
nominal constants, so what they see is a real robot that is not the datasheet's.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np

from hopper.config import MISMATCH_FACTORS as MISMATCH_FACTORS  # the names and what each scales
from hopper.config import MISMATCH_OFFSETS as MISMATCH_OFFSETS

PARTS = {"torso": ("torso",), "wheel": ("wheel",), "thigh": ("thigh_L", "thigh_R"), "shank": ("shank_L", "shank_R")}
COM_AXES = {"com_x": 0, "com_z": 2}  # body_ipos columns


@dataclasses.dataclass(frozen=True)
class Nominal:
    """The compiled model's parameters that mismatch factors scale, as built."""

    body_mass: np.ndarray
    body_inertia: np.ndarray
    body_ipos: np.ndarray
    dof_armature: np.ndarray
    actuator_gainprm: np.ndarray
    actuator_biasprm: np.ndarray
    actuator_forcerange: np.ndarray
    geom_friction: np.ndarray

    @classmethod
    def of(cls, model: mujoco.MjModel) -> Nominal:
        return cls(*(getattr(model, f.name).copy() for f in dataclasses.fields(cls)))

    def apply(self, model: mujoco.MjModel, mismatch: tuple[tuple[str, float], ...]) -> None:
        """Back to nominal, then scale by each factor and move by each offset (in place)."""
        for f in dataclasses.fields(self):
            getattr(model, f.name)[:] = getattr(self, f.name)
        for name, value in mismatch:
            _apply_one(model, name, value)
        # Masses changed: the derived quantities (subtree masses, ...) follow at mj_setConst.
        mujoco.mj_setConst(model, mujoco.MjData(model))


def _bodies(model: mujoco.MjModel, part: str) -> list[int]:
    return [model.body(name).id for name in PARTS[part]]


def _apply_one(model: mujoco.MjModel, name: str, value: float) -> None:
    kind, _, part = name.partition("_")
    if name in COM_AXES:
        model.body_ipos[model.body("torso").id, COM_AXES[name]] += value
    elif kind in ("mass", "inertia") and part in PARTS:  # one quantity of one part
        for body in _bodies(model, part):
            getattr(model, f"body_{kind}")[body] *= value
    elif name in ("torso_mass", "leg_mass"):  # a denser body: mass and inertia together
        parts = ("torso",) if name == "torso_mass" else ("thigh", "shank")
        for body in (b for p in parts for b in _bodies(model, p)):
            model.body_mass[body] *= value
            model.body_inertia[body] *= value
    elif name == "wheel_inertia":
        model.body_inertia[model.body("wheel").id] *= value
        model.dof_armature[model.jnt_dofadr[model.joint("wheel").id]] *= value
    elif name == "motor_torque":  # a DC motor: torque k_t I, back-EMF k_t w, so damping k_t^2 / R
        wheel = model.actuator("wheel").id
        model.actuator_gainprm[wheel, 0] *= value
        model.actuator_biasprm[wheel, 2] *= value * value
        model.actuator_forcerange[wheel] *= value
    elif name == "friction":
        model.geom_friction[:, 0] *= value
    else:
        raise ValueError(f"unknown mismatch {name!r}")  # check_mismatch refuses it first


def pitch_inertia(model: mujoco.MjModel, body: int) -> float:
    """A body's moment of inertia about its CoM's pitch (y) axis, kg m^2: body_inertia holds principal
    moments in the frame body_iquat turns, so I_yy = sum_k R[1, k]^2 I_k."""
    rotation = np.empty(9)
    mujoco.mju_quat2Mat(rotation, model.body_iquat[body])
    return float(rotation.reshape(3, 3)[1] ** 2 @ model.body_inertia[body])


def quantities(model: mujoco.MjModel) -> dict[str, float]:
    """The physical quantities a mismatch changes, read from the model, in SI units: per part
    `mass_<part>` (kg, each body) and `inertia_<part>` (kg m^2 about pitch; not the wheel), `wheel_spin` (the
    wheel's spin inertia plus the motor's reflected rotor inertia, kg m^2), `com_x` / `com_z` (m),
    `friction` (the left foot's; every geom is scaled alike), the wheel motor's `stall_torque` (N m
    at the motor) and `back_emf_damping` (N m s/rad)."""
    out: dict[str, float] = {}
    for part in PARTS:
        body = _bodies(model, part)[0]
        out[f"mass_{part}"] = float(model.body_mass[body])
        if part != "wheel":  # the wheel's is wheel_spin
            out[f"inertia_{part}"] = pitch_inertia(model, body)
    wheel = model.body("wheel").id
    dof = model.jnt_dofadr[model.joint("wheel").id]
    out["wheel_spin"] = float(model.body_inertia[wheel].max() + model.dof_armature[dof])
    torso = model.body("torso").id
    out |= {name: float(model.body_ipos[torso, axis]) for name, axis in COM_AXES.items()}
    out["friction"] = float(model.geom_friction[model.geom("foot_L").id, 0])
    motor = model.actuator("wheel").id
    out["stall_torque"] = float(model.actuator_gainprm[motor, 0])
    out["back_emf_damping"] = float(-model.actuator_biasprm[motor, 2])
    return out
