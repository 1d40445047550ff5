"""The motors' electrical energy per tick, from a DC motor model: copper loss plus mechanical power.

A joint torque tau through a gear N needs the motor torque tau / N, so the current I = tau / (N k_t),
and the motor draws P = I^2 R + tau * w (w the joint's speed; tau * w is the motor's mechanical power,
negative when it brakes). Braking does not regenerate by default (hopper.config.REGENERATIVE_DRIVES):
a negative P, the motor generating more than its copper loss burns, is burnt in the drive and counts
as zero, each drive on its own (no exchange between the motors over a shared bus). Left out: iron and
friction losses, the gearbox's, the drive's. The figures are in hopper.config (MOTOR_*, LEG_MOTOR_GEAR);
a motor_torque mismatch (hopper.mismatch) scales the wheel motor's k_t here as it does in the model,
and a model whose motors are n times stronger has n of them in parallel (hopper.control.controller).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def motor_power(
    torque: float, speed: float, gear: float, torque_constant: float, resistance: float, regenerate: bool
) -> float:
    """Electrical power (W) of a motor giving joint `torque` (N m) at joint `speed` (rad/s) through
    `gear` (joint torque / motor torque), with k_t `torque_constant` (N m/A) and winding `resistance`
    (ohm); a negative power counts only if the drive can `regenerate`."""
    current = torque / (gear * torque_constant)
    power = current * current * resistance + torque * speed
    return power if regenerate or power > 0.0 else 0.0


@njit(cache=True)
def spend(m, qvel: np.ndarray, sensors: np.ndarray) -> None:  # noqa: ANN001 (a MEMORY record)
    """Add one tick of each motor's electrical energy (J) to the hop's accumulators.

    The force MuJoCo applied over the step just taken (actuatorfrc, computed before it integrated)
    against the speed it left: MuJoCo's integrators move qpos by dt times the new qvel, so tau * w * dt
    is exactly that step's work.
    """
    dt, regen = m.dt, m.regenerate
    wheel = sensors[m.s_wheel_torque] * m.wheel_gear  # N m at the wheel
    m.acc_wheel_energy += dt * motor_power(wheel, qvel[m.v_wheel], m.wheel_gear, m.wheel_kt, m.wheel_resistance, regen)
    kt, legs, r = m.leg_kt, m.leg_motor_gear, m.leg_resistance
    g = m.leg_gear  # actuator force to joint torque
    power = motor_power(sensors[m.s_torque_hip_l] * g, qvel[m.v_hip_l], legs, kt, r, regen)
    power += motor_power(sensors[m.s_torque_knee_l] * g, qvel[m.v_knee_l], legs, kt, r, regen)
    power += motor_power(sensors[m.s_torque_hip_r] * g, qvel[m.v_hip_r], legs, kt, r, regen)
    power += motor_power(sensors[m.s_torque_knee_r] * g, qvel[m.v_knee_r], legs, kt, r, regen)
    m.acc_leg_energy += dt * power
