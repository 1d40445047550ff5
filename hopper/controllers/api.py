"""The controller API: what a flight wheel law sees (Observation), what it may declare (Param), and
the small protocol it implements (Controller). README.md's "Bring your own controller" is the guide.

A controller is any class with `__call__(self, obs) -> float`: the wheel motor's torque command in
N m, in the kernel's sign convention (the paper's PID reads `kp * pitch + kd * rate + ki * integral`;
MuJoCo's motor torque acts on the wheel and the torso takes its reaction). The motor's torque-speed
envelope clamps it. `reset(self, obs)`, if defined, is called at each liftoff before the first call.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple, Protocol, runtime_checkable

from hopper.errors import HopperError


class ControllerError(HopperError):
    """A controller that cannot be loaded, takes a bad parameter, or misbehaved; the message names it."""


class Observation(NamedTuple):
    """One flight tick as the controller's sensing gives it, SI units (read-only)."""

    pitch: float  # rad, torso pitch (truth in ideal sensing, the IMU's estimate in realistic)
    rate: float  # rad/s, torso pitch rate (the same)
    wheel_speed: float  # rad/s, the wheel relative to the torso (its encoder)
    time: float  # s, simulation time
    time_since_liftoff: float  # s
    time_to_touchdown: float  # s, predicted from the ballistic arc and the terrain under the planned feet
    gravity: float  # m/s^2, magnitude
    dt: float  # s, the control period
    momentum_headroom: tuple[float, float]  # N m s the wheel can still take (speeding up +, -) before its top speed
    torque_bounds: tuple[float, float]  # N m, (low, high) the motor's envelope allows at this wheel speed
    wheel_inertia: float  # kg m^2, the wheel's spin inertia with the motor's reflected rotor inertia
    wheel_speed_limit: float  # rad/s, the motor's no-load speed at the wheel


class Param(NamedTuple):
    """A tunable parameter a controller declares: a dashboard slider, a sweep/tune axis, a field in
    recordings and run JSON. The value is set as an attribute of the controller's instance."""

    name: str
    default: float
    range: tuple[float, float]
    unit: str = ""

    def check(self, value: float, owner: str) -> float:
        """`value` as a float, or ControllerError naming the parameter and its range."""
        low, high = self.range
        try:
            value = float(value)
        except (TypeError, ValueError):
            raise ControllerError(f"{owner}: parameter {self.name} must be a number, got {value!r}") from None
        if not (math.isfinite(value) and low <= value <= high):
            raise ControllerError(
                f"{owner}: parameter {self.name} = {value:g} is outside [{low:g}, {high:g}] {self.unit}".rstrip()
            )
        return value


@runtime_checkable
class Controller(Protocol):
    """The flight wheel law. Optional members: `params` (a sequence of Param, or of (name, default,
    (low, high), unit) tuples), `reset(obs)` (at each liftoff), `configure(context)` (when attached,
    and again when gravity, sensing or the model change; context is a ControllerContext)."""

    def __call__(self, obs: Observation) -> float: ...


class ControllerContext(NamedTuple):
    """What a controller may read when it is configured (a model-based design reads the plant)."""

    config: Any  # hopper.config.SimConfig: gravity, sensing, gait, timestep
    model: Any  # mujoco.MjModel of the robot
