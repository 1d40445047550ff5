"""The learned controllers' observation layout: an Observation as a normalised float vector, versioned.

The Gymnasium environment (hopper.gym_env) and the policy (hopper.laws.policy) both read an
Observation through `features`, with the integral of pitch since liftoff that each keeps in a
PitchIntegral (the paper's PID's, hopper.laws.pid); a weights file records LAYOUT and is refused
for another one. Version 2 added the integral: version 1 was stateless.
"""

from __future__ import annotations

import hashlib
import json

import numpy as np

from hopper.controllers.api import Observation

LAYOUT_VERSION = 2
# (name, scale, low, high): feature = clip(value / scale, low, high); the value is in SI units.
FIELDS: tuple[tuple[str, float, float, float], ...] = (
    ("pitch", 0.1, -10.0, 10.0),  # rad / 0.1 rad (5.7 deg)
    ("rate", 1.0, -10.0, 10.0),  # rad/s / 1 rad/s
    ("wheel_speed", 1.0, -2.0, 2.0),  # / wheel_speed_limit (the no-load speed, 41.9 rad/s)
    ("time_to_touchdown", 1.0, 0.0, 5.0),  # s / 1 s
    ("time_since_liftoff", 1.0, 0.0, 5.0),  # s / 1 s
    ("headroom_up", 1.0, 0.0, 2.0),  # momentum_headroom[0] / (wheel_inertia * wheel_speed_limit)
    ("headroom_down", 1.0, 0.0, 2.0),  # momentum_headroom[1] / the same capacity
    ("gravity", 10.0, 0.0, 3.0),  # m/s^2 / 10 m/s^2
    # rad s / 0.05 rad s (0.1 rad held 0.5 s): the paper's ki 50 is then a weight of 0.085, the
    # size of kp's and kd's, so the search steps it as it steps them. Bounds wide: the PID never clips it.
    ("pitch_integral", 0.05, -20.0, 20.0),
)
NAMES = tuple(f[0] for f in FIELDS)
SCALES = np.array([f[1] for f in FIELDS])
LOW = np.array([f[2] for f in FIELDS], dtype=np.float32)
HIGH = np.array([f[3] for f in FIELDS], dtype=np.float32)
SIZE = len(FIELDS)


def layout_hash() -> str:
    """12 hex digits naming the version, the fields, their scales and bounds."""
    text = json.dumps([LAYOUT_VERSION, FIELDS], separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:12]


LAYOUT = {"version": LAYOUT_VERSION, "fields": list(NAMES), "hash": layout_hash()}


class PitchIntegral:
    """The integral of pitch since liftoff, rad s, as the paper's PID keeps it: reset at liftoff,
    no integration while the command is outside the motor's envelope (no windup)."""

    def __init__(self) -> None:
        self.value = 0.0  # rad s

    def reset(self) -> None:
        self.value = 0.0

    def update(self, obs: Observation, command: float) -> None:
        """After the command (N m) chosen on `obs`: integrate obs.pitch over obs.dt unless it saturates."""
        low, high = obs.torque_bounds
        if low <= command <= high:
            self.value += obs.pitch * obs.dt


def features(obs: Observation, integral: float) -> np.ndarray:
    """The observation and the pitch integral (rad s) as a (SIZE,) float64 vector in [LOW, HIGH]."""
    cap = obs.wheel_inertia * obs.wheel_speed_limit  # N m s, the wheel's momentum capacity
    up, down = obs.momentum_headroom
    raw = np.array(
        (
            obs.pitch,
            obs.rate,
            obs.wheel_speed / obs.wheel_speed_limit,
            obs.time_to_touchdown,
            obs.time_since_liftoff,
            up / cap,
            down / cap,
            obs.gravity,
            integral,
        )
    )
    return np.clip(raw / SCALES, LOW, HIGH)
