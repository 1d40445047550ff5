"""Landing that looks at the terrain: at the apex, each leg's reach is set so both feet meet the ground.

The heightfield is known. A foot over a crater floor and the other on a rim would touch down
tens of milliseconds apart; the first foot then takes the whole landing on its own and the
robot pivots over it (the crater landings that made the Moon's 20-hop runs fall). Once per
flight, at the apex, the ballistic arc gives where and when the feet come down; the leg over
the lower ground is lengthened by the difference (within its reach), so both land together.
Pure functions of the state and the terrain; the kernel only reads the two lengths.
"""

from __future__ import annotations

import math

from hopper.robot import PACKAGED, Robot

FOOT_Y = PACKAGED.foot_y  # m, the packaged robot's feet's lateral offset (the flown one's: Robot.foot_y)


def plan_reach(
    hip: tuple[float, float],
    velocity: tuple[float, float],
    gravity: float,
    feet_ahead: tuple[float, float],
    length: float,
    longest: float,
    ground: callable,  # type: ignore[valid-type]
    foot_radius: float = PACKAGED.foot_radius,
) -> tuple[float, float]:
    """Leg lengths (m) for the left and right foot so that both touch down together.

    hip: (x, z) of the hip now (m); velocity: (vx, vz) (m/s), ballistic from here on;
    feet_ahead: where each foot will be ahead of the hip (m); length: the nominal landing leg
    length; longest: the most a leg may reach; ground(x, foot) -> terrain height under it;
    foot_radius: the feet's (m).
    """
    (x, z), (vx, vz) = hip, velocity
    lengths, t = (length, length), 0.0
    for _ in range(3):  # where the feet land depends on when, which depends on the ground there
        hip_x = x + vx * t
        floors = [ground(hip_x + feet_ahead[k], k) for k in range(2)]
        high = max(floors)
        # The foot over the higher ground keeps the nominal length and sets the touchdown time;
        # the other reaches down by the difference.
        lengths = tuple(min(length + (high - floor), longest) for floor in floors)
        t = _fall_time(z - length - foot_radius - high, vz, gravity)
    return lengths  # type: ignore[return-value]


def _fall_time(height: float, vz: float, gravity: float) -> float:
    """Time (s) until a point `height` (m) above the ground, rising at vz (m/s), reaches it."""
    return (vz + math.sqrt(max(vz * vz + 2.0 * gravity * height, 0.0))) / gravity


def hip_position(torso: tuple[float, float], pitch: float, robot: Robot = PACKAGED) -> tuple[float, float]:
    """The hip's world (x, z) from the torso frame's origin and the pitch (rad)."""
    x, z = torso
    return x + robot.hip_z * math.sin(pitch), z + robot.hip_z * math.cos(pitch)
