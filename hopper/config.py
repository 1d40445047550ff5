"""Configuration dataclasses, validated on construction, with units and sources."""

from __future__ import annotations

import dataclasses
import math
from typing import Literal, NamedTuple

from hopper.terrain import CraterParams

MOON_GRAVITY = 1.625  # m/s^2, paper Table I
GRAVITY_PRESETS: dict[str, float] = {  # m/s^2, PHYSICS.md
    "moon": MOON_GRAVITY,
    "mars": 3.72,
    "ceres": 0.28,
    "earth": 9.81,
}
TIMESTEP = 0.001  # s, 1 kHz physics and control, paper Table I

# Robot constants shared by the controller and the metrics (they mirror models/hopper.xml).
TOTAL_MASS = 8.2  # kg, Table I
WHEEL_INERTIA = 0.03375  # kg m^2, 3 kg disc of radius 0.15 m
WHEEL_ARMATURE = 0.0045  # kg m^2, reflected rotor inertia N^2 J_m (models/hopper.xml): adds to the spin
WHEEL_GEAR = 30.0  # Table I
WHEEL_TORQUE_LIMIT = 29.5  # N m at the wheel, Table I
WHEEL_NO_LOAD_SPEED = 400 * 2 * math.pi / 60  # rad/s at the wheel (12000 rpm motor / 30), ours
LEG_TORQUE_LIMIT = 30.0  # N m per leg joint, ours (models/hopper.xml)
THIGH_LENGTH = 0.5  # m, Table I
SHANK_LENGTH = 0.5  # m, Table I
HIP_OFFSET_Z = -0.18  # m, hips below the torso CoM (models/hopper.xml)
FOOT_RADIUS = 0.04  # m, Table I
SATURATION_FRACTION = 0.98  # of the torque limit counts as saturated, paper Sec. V-D


class GainRange(NamedTuple):
    """The one allowed range of a flight gain: the core validates it, the CLIs and the dashboard show it."""

    low: float
    high: float
    unit: str


# Wide enough to reach a visibly unstable or saturating loop (PHYSICS.md's LQR range is kp 340 to
# 850, kd 17 to 31), narrow enough for a slider.
GAIN_RANGES: dict[str, GainRange] = {
    "kp": GainRange(0.0, 2000.0, "N m/rad"),
    "ki": GainRange(0.0, 500.0, "N m/(rad s)"),
    "kd": GainRange(0.0, 100.0, "N m s/rad"),
}


class InvalidConfig(ValueError):
    """A configuration value outside its allowed range."""


def require_finite(name: str, value: float, low: float = -math.inf, high: float = math.inf, unit: str = "") -> None:
    """Raise InvalidConfig unless low <= value <= high and value is finite."""
    if not isinstance(value, (int, float)) or not math.isfinite(value) or not low <= value <= high:
        u = f" {unit}" if unit else ""
        raise InvalidConfig(f"{name} must be a finite number in [{low:g}, {high:g}]{u}, got {value!r}")


@dataclasses.dataclass(frozen=True, kw_only=True)
class Gains:
    """Flight PID gains for the wheel: torque on the torso = -kp theta - kd theta_dot - ki int theta.

    Defaults place the closed-loop poles at wn = 30 rad/s, zeta = 1 for the effective inertia
    I_locked - I_w ~ 0.5 kg m^2 (PHYSICS.md's LQR range: kp 340 to 850, kd 17 to 31); ki only trims
    model error, as there is no gravity torque in flight.
    """

    kp: float = 450.0  # N m / rad
    ki: float = 50.0  # N m / (rad s)
    kd: float = 30.0  # N m s / rad

    def __post_init__(self) -> None:
        for name, (low, high, unit) in GAIN_RANGES.items():
            require_finite(name, getattr(self, name), low, high, unit)


@dataclasses.dataclass(frozen=True, kw_only=True)
class GaitParams:
    """The hop cycle's targets. Lengths are hip heights above the feet, in metres."""

    apex_height: float = 0.25  # m above the liftoff height; v_z = sqrt(2 g h)
    forward_speed: float = 0.4  # m/s at liftoff on the Moon; sqrt(g) elsewhere (hopper.control.gait)
    stand_height: float = 0.85  # m
    crouch_height: float = 0.68  # m
    push_length: float = 0.96  # m, leg length where the push stops
    flight_length: float = 0.86  # m, leg length held in flight for landing, after the apex
    tuck_length: float = 0.75  # m, leg length while rising, for clearance over rims ahead
    foot_spread: float = 0.36  # m between the feet at landing, a support base for stance pitch
    crouch_lean: float = 0.1  # m, torso CoM ahead of the feet midpoint before the push
    stance_time: float = 0.25  # s, minimum stabilisation time before the crouch
    friction: float = 0.7  # friction coefficient the stance forces assume (model: 0.8)

    def __post_init__(self) -> None:
        require_finite("apex_height", self.apex_height, 0.02, 3.0)
        require_finite("forward_speed", self.forward_speed, -2.0, 2.0)
        require_finite("crouch_height", self.crouch_height, 0.45, self.stand_height)
        require_finite("stand_height", self.stand_height, 0.5, 0.98)
        require_finite("push_length", self.push_length, self.stand_height, 0.99)


@dataclasses.dataclass(frozen=True, kw_only=True)
class SimConfig:
    """Everything that defines one simulation run."""

    seed: int = 0
    terrain: Literal["crater", "flat"] = "crater"
    gravity: float = MOON_GRAVITY  # m/s^2, magnitude
    timestep: float = TIMESTEP  # s
    gains: Gains = dataclasses.field(default_factory=Gains)
    gait: GaitParams = dataclasses.field(default_factory=GaitParams)
    wheel: bool = True  # False: zero wheel torque, wheel free to spin
    craters: CraterParams = dataclasses.field(default_factory=CraterParams)

    def __post_init__(self) -> None:
        if self.terrain not in ("crater", "flat"):
            raise InvalidConfig(f"terrain must be 'crater' or 'flat', got {self.terrain!r}")
        if not isinstance(self.seed, int) or self.seed < 0:
            raise InvalidConfig(f"seed must be a non-negative integer, got {self.seed!r}")
        require_finite("gravity", self.gravity, 0.05, 30.0)
        require_finite("timestep", self.timestep, 1e-4, 5e-3)
