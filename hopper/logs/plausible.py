"""Physical bounds on a log: a finite value far beyond anything the robot can do is a wrong unit or a
broken logger, refused in one line (column, sample, value) rather than replayed as if it were real.

The bounds are generous on purpose (GENEROUS times a limit of the packaged robot or its sensors): a
user's robot with a stronger motor stays inside them; 1e300 N m or a time column in the wrong unit
does not.
"""

from __future__ import annotations

import math

import numpy as np

from hopper.layout import LEG_JOINTS
from hopper.robot import PACKAGED

GENEROUS = 100.0  # a value beyond this many times a physical limit is no measurement of this robot
RATE_HZ = (10.0, 100_000.0)  # Hz: a hopper log's sample rate lies between these (ours: 1 kHz)
GYRO_RANGE = math.radians(2000.0)  # rad/s, a MEMS gyro's full range (the BMI088's 2000 deg/s)
ACCEL_RANGE = 24.0 * 9.80665  # m/s^2, a MEMS accelerometer's full range (the BMI088's 24 g)
EARTH_WEIGHT = PACKAGED.mass * 9.80665  # N, the robot's weight on Earth

# column -> (the largest |value| a log may hold, SI; what that bound is)
BOUNDS: dict[str, tuple[float, str]] = {
    "wheel_torque_cmd": (GENEROUS * PACKAGED.wheel_torque_limit, "100x the wheel motor's stall torque"),
    **{f"{j}_torque_cmd": (GENEROUS * PACKAGED.leg_torque_limit, "100x a leg motor's limit") for j in LEG_JOINTS},
    "wheel_speed": (GENEROUS * PACKAGED.wheel_no_load_speed, "100x the wheel's no-load speed"),
    "gyro_pitch": (GENEROUS * GYRO_RANGE, "100x a MEMS gyro's range"),
    "pitch_rate": (GENEROUS * GYRO_RANGE, "100x a MEMS gyro's range"),
    "pitch": (GENEROUS * 2.0 * math.pi, "100 turns"),
    **{j: (GENEROUS * 2.0 * math.pi, "100 turns") for j in LEG_JOINTS},
    "foot_L_force": (GENEROUS * EARTH_WEIGHT, "100x the robot's weight on Earth"),
    "foot_R_force": (GENEROUS * EARTH_WEIGHT, "100x the robot's weight on Earth"),
    "accel_x": (GENEROUS * ACCEL_RANGE, "100x a MEMS accelerometer's range"),
    "accel_z": (GENEROUS * ACCEL_RANGE, "100x a MEMS accelerometer's range"),
    "x": (1e6, "1000 km"),
    "z": (1e6, "1000 km"),
    "vx": (1e3, "1 km/s"),
    "vz": (1e3, "1 km/s"),
}


def rate_problem(period: float) -> str | None:
    """Why a median sample period (s) is no hopper log's, or None: its rate outside RATE_HZ."""
    rate = 1.0 / period
    low, high = RATE_HZ
    if low <= rate <= high:
        return None
    return (
        f"its sample rate is {rate:.6g} Hz (median period {period:.3g} s), outside {low:g} Hz..{high:g} Hz: "
        "is its time in the unit it says?"
    )


def beyond(name: str, values: np.ndarray) -> int | None:
    """The first sample of column `name` beyond its bound (BOUNDS), or None."""
    bound = BOUNDS.get(name)
    if bound is None:
        return None
    over = np.flatnonzero(np.abs(values) > bound[0])
    return int(over[0]) if over.size else None


def value_problem(name: str, unit: str, value: float, where: str) -> str:
    """The one-line reason a value of column `name` at `where` (its sample and time) is refused."""
    limit, what = BOUNDS[name]
    return f"column {name} is {value:.6g} {unit} at {where}, beyond {limit:.4g} {unit} ({what}): is its unit right?"
