"""The paper's flight PID as a controller of the API; the kernel runs the same law compiled."""

from __future__ import annotations

from hopper.config import GAIN_RANGES, Gains
from hopper.controllers.api import Observation, Param

_DEFAULT = Gains()


class PaperPID:
    """tau = kp theta + kd theta_dot + ki int theta, with conditional integration (no windup while
    the motor's envelope clamps the command) and the integral reset at liftoff.

    `compiled = "pid"`: a simulation flies this law inside its numba kernel (hopper.control.wheel.
    wheel_pid), with the config's Gains as the params. The Python `__call__` is the same law, float
    for float (tests/test_controllers.py flies both and compares them bit for bit): a subclass
    without `compiled` runs it through the API like any controller.
    """

    compiled = "pid"
    params = tuple(Param(name, getattr(_DEFAULT, name), (r.low, r.high), r.unit) for name, r in GAIN_RANGES.items())

    def __init__(self) -> None:
        self.integral = 0.0  # rad s

    def reset(self, obs: Observation) -> None:
        self.integral = 0.0

    def __call__(self, obs: Observation) -> float:
        command = self.kp * obs.pitch + self.kd * obs.rate + self.ki * self.integral
        low, high = obs.torque_bounds
        if low <= command <= high:  # not saturated: integrate
            self.integral += obs.pitch * obs.dt
        return command
