"""Model mismatch: the simulated robot differs from the one the controllers were designed for.

Each factor scales a group of the compiled model's parameters in place (restorable, so a batch
reuses one model); the controllers keep designing on the nominal model (hopper.laws.plant
linearizes a mismatch-free copy) and the kernel keeps its nominal constants, so what they see is
a real robot that is not the datasheet's.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np

from hopper.config import MISMATCH_FACTORS as MISMATCH_FACTORS  # the names and what each scales


@dataclasses.dataclass(frozen=True)
class Nominal:
    """The compiled model's parameters that mismatch factors scale, as built."""

    body_mass: np.ndarray
    body_inertia: np.ndarray
    dof_armature: np.ndarray
    actuator_gainprm: np.ndarray
    actuator_biasprm: np.ndarray
    actuator_forcerange: np.ndarray
    geom_friction: np.ndarray

    @classmethod
    def of(cls, model: mujoco.MjModel) -> Nominal:
        return cls(
            model.body_mass.copy(),
            model.body_inertia.copy(),
            model.dof_armature.copy(),
            model.actuator_gainprm.copy(),
            model.actuator_biasprm.copy(),
            model.actuator_forcerange.copy(),
            model.geom_friction.copy(),
        )

    def apply(self, model: mujoco.MjModel, mismatch: tuple[tuple[str, float], ...]) -> None:
        """Back to nominal, then scale by each factor (in place)."""
        model.body_mass[:], model.body_inertia[:] = self.body_mass, self.body_inertia
        model.dof_armature[:], model.geom_friction[:] = self.dof_armature, self.geom_friction
        model.actuator_gainprm[:], model.actuator_biasprm[:] = self.actuator_gainprm, self.actuator_biasprm
        model.actuator_forcerange[:] = self.actuator_forcerange
        for name, factor in mismatch:
            if name == "torso_mass":
                bodies = [model.body("torso").id]
            elif name == "leg_mass":
                bodies = [model.body(f"{part}_{side}").id for part in ("thigh", "shank") for side in "LR"]
            elif name == "wheel_inertia":
                wheel = model.body("wheel").id
                model.body_inertia[wheel] *= factor
                model.dof_armature[model.jnt_dofadr[model.joint("wheel").id]] *= factor
                continue
            elif name == "motor_torque":  # a DC motor: torque k_t I, back-EMF k_t w, so damping k_t^2 / R
                wheel = model.actuator("wheel").id
                model.actuator_gainprm[wheel, 0] *= factor
                model.actuator_biasprm[wheel, 2] *= factor * factor
                model.actuator_forcerange[wheel] *= factor
                continue
            else:  # friction
                model.geom_friction[:, 0] *= factor
                continue
            for body in bodies:
                model.body_mass[body] *= factor
                model.body_inertia[body] *= factor
        # Masses changed: the derived quantities (subtree masses, ...) follow at mj_setConst.
        mujoco.mj_setConst(model, mujoco.MjData(model))
