"""The reaction wheel: its DC motor's torque-speed envelope and the paper's flight PID."""

from __future__ import annotations

from numba import njit

from hopper.control.legs import clamp
from hopper.robot import PACKAGED

# The packaged robot's back-EMF slope, N m s/rad at the wheel; the kernel reads the flown robot's
# (m.wheel_damping, hopper.robot.Robot.wheel_damping).
WHEEL_DAMPING = PACKAGED.wheel_damping


@njit(cache=True)
def wheel_torque_bound(m, wheel_speed: float, torque: float) -> float:  # noqa: ANN001 (a MEMORY record)
    """Clamp a wheel torque (N m) to the motor's torque-speed envelope at `wheel_speed` (rad/s):
    the stall torque m.wheel_limit less the back-EMF m.wheel_damping * speed."""
    limit = m.wheel_limit
    back_emf = m.wheel_damping * wheel_speed
    low = max(-limit, -limit - back_emf)
    high = min(limit, limit - back_emf)
    return low if torque < low else high if torque > high else torque


@njit(cache=True)
def wheel_ctrl(m, torque: float, wheel_speed: float) -> float:  # noqa: ANN001 (a MEMORY record)
    """Normalised motor voltage in [-1, 1] giving `torque` (N m at the wheel) at `wheel_speed`.

    Inverts the model's DC motor: torque = limit * u - damping * speed, clamped to the limit.
    """
    return clamp((torque + m.wheel_damping * wheel_speed) / m.wheel_limit, 1.0)


@njit(cache=True)
def wheel_pid(m, pitch: float, rate: float, wheel_speed: float) -> float:  # noqa: ANN001 (a MEMORY record)
    """The paper's flight law on the measured pitch and rate, clamped to the envelope, anti-windup.

    Sign: the paper's tau_w is the torque on the torso; MuJoCo's motor torque acts on the wheel
    and the torso takes its reaction, so the motor command is kp theta + kd theta_dot + ki int.
    D acts on the measured rate, so a gain change causes no derivative kick.
    """
    command = m.kp * pitch + m.kd * rate + m.ki * m.integral
    torque = wheel_torque_bound(m, wheel_speed, command)
    m.saturated = torque != command
    if not m.saturated:  # conditional integration: no windup while saturated
        m.integral += pitch * m.dt
    return torque
