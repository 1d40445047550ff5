"""The reaction wheel: its DC motor's torque-speed envelope and the paper's flight PID."""

from __future__ import annotations

from numba import njit

from hopper.config import SATURATION_FRACTION, WHEEL_NO_LOAD_SPEED, WHEEL_TORQUE_LIMIT
from hopper.control.legs import clamp

WHEEL_DAMPING = WHEEL_TORQUE_LIMIT / WHEEL_NO_LOAD_SPEED  # N m s/rad, back-EMF slope at the wheel
SATURATION_TORQUE = SATURATION_FRACTION * WHEEL_TORQUE_LIMIT  # N m


@njit(cache=True)
def wheel_torque_bound(wheel_speed: float, torque: float) -> float:
    """Clamp a wheel torque (N m) to the motor's torque-speed envelope at `wheel_speed` (rad/s)."""
    back_emf = WHEEL_DAMPING * wheel_speed
    low = max(-WHEEL_TORQUE_LIMIT, -WHEEL_TORQUE_LIMIT - back_emf)
    high = min(WHEEL_TORQUE_LIMIT, WHEEL_TORQUE_LIMIT - back_emf)
    return low if torque < low else high if torque > high else torque


@njit(cache=True)
def wheel_ctrl(torque: float, wheel_speed: float) -> float:
    """Normalised motor voltage in [-1, 1] giving `torque` (N m at the wheel) at `wheel_speed`.

    Inverts the model's DC motor: torque = limit * u - damping * speed, clamped to the limit.
    """
    return clamp((torque + WHEEL_DAMPING * wheel_speed) / WHEEL_TORQUE_LIMIT, 1.0)


@njit(cache=True)
def wheel_pid(m, pitch: float, rate: float, wheel_speed: float) -> float:  # noqa: ANN001 (a MEMORY record)
    """The paper's flight law on the measured pitch and rate, clamped to the envelope, anti-windup.

    Sign: the paper's tau_w is the torque on the torso; MuJoCo's motor torque acts on the wheel
    and the torso takes its reaction, so the motor command is kp theta + kd theta_dot + ki int.
    D acts on the measured rate, so a gain change causes no derivative kick.
    """
    command = m.kp * pitch + m.kd * rate + m.ki * m.integral
    torque = wheel_torque_bound(wheel_speed, command)
    m.saturated = torque != command
    if not m.saturated:  # conditional integration: no windup while saturated
        m.integral += pitch * m.dt
    return torque
