"""Leg kinematics in the sagittal plane and the torques that support or swing a leg."""

from __future__ import annotations

import math
from typing import NamedTuple

from numba import njit

# Flight: the legs swing as a virtual leg (length, angle) with PD gains about the hip.
SWING_K, SWING_D = 15.0, 2.5  # N m/rad, N m s/rad  (wn ~ 10 rad/s for ~0.15 kg m^2)
KNEE_K, KNEE_D = 20.0, 1.5  # N m/rad, N m s/rad (wn ~ 10 rad/s for the shank about the knee)
# The knee's part of the hip torque that turns a leg as one rigid body: 0.30-0.33 from MuJoCo's
# joint-space inertia of the model at the landing pose (tests/test_controller.py). The
# bisection's half overdrives the shank in a hard turn, and the foot swings down to the ground.
RIGID_KNEE = 0.3


class Leg(NamedTuple):
    """One leg this tick: foot centre relative to the hip in world axes (m), d(px, pz)/d(knee),
    the joint angles and rates, and whether the foot is (debounced) on the ground.

    d(px)/d(hip) = pz and d(pz)/d(hip) = -px, so they need no field.
    """

    px: float
    pz: float
    jx: float
    jz: float
    knee: float
    hip_rate: float
    knee_rate: float
    on: bool


@njit(cache=True)
def clamp(value: float, limit: float) -> float:
    return value if -limit < value < limit else (limit if value > 0 else -limit)


@njit(cache=True)
def leg_state(m, pitch: float, hip: float, knee: float, hip_rate: float, knee_rate: float, on: bool) -> Leg:  # noqa: ANN001
    """The leg's kinematics at torso `pitch` and joint angles `hip`, `knee` (rad); the links' lengths
    are the MEMORY record `m`'s (hopper.robot.Robot's thigh and shank)."""
    L1, L2 = m.thigh, m.shank  # noqa: N806 (the links' usual names)
    a1 = pitch + hip
    a2 = a1 + knee
    s2, c2 = math.sin(a2), math.cos(a2)
    return Leg(
        -L1 * math.sin(a1) - L2 * s2, -L1 * math.cos(a1) - L2 * c2, -L2 * c2, L2 * s2, knee, hip_rate, knee_rate, on
    )


@njit(cache=True)
def push_torques(m, leg: Leg, fx: float, fz: float) -> tuple[float, float]:  # noqa: ANN001
    """Hip and knee torques that make the ground push on the foot with (fx, fz): tau = -J^T f,
    within the leg motors' limit (m.leg_limit, N m)."""
    return (
        clamp(leg.px * fz - leg.pz * fx, m.leg_limit),
        clamp(-(leg.jx * fx + leg.jz * fz), m.leg_limit),
    )


@njit(cache=True)
def swing_torques(
    m,  # noqa: ANN001 (a MEMORY record)
    leg: Leg,
    length: float,
    foot_x: float,
    scale: float = 1.0,
    offset: float = 0.0,
    rate: float = 0.0,
    max_knee_torque: float = -1.0,
    rigid: bool = False,
) -> tuple[float, float]:
    """PD toward a foot `foot_x` ahead of the hip, `length` from it (a swing, not a support).

    The virtual leg (hip to foot) bisects the knee, so its world angle is servoed by the hip
    (the knee takes half of that torque to keep the bisection) and its length by the knee, in
    joint space: length = 2 L cos(knee / 2) has no gradient at a straight knee, where a
    Cartesian length servo would lock the leg straight. Damping acts on the joint rates so the
    legs do not fight the torso's rotation. `scale` (>= 1) multiplies the natural frequency for
    short flights; `offset` (rad) shifts the world angle and `rate` (rad/s) the world rate the
    damping holds, relative to the torso's (hopper.control.kernel.share_attitude);
    `max_knee_torque` caps the length servo (N m; negative: the motor's limit). `rigid`: the knee takes
    RIGID_KNEE, not half, of the hip's torque, so a hard turn moves each leg as one body and its foot keeps its height.
    """
    angle = -math.asin(clamp(foot_x / length, 0.9)) + offset  # world angle, + = foot behind the hip
    return swing_to_angle(m, leg, length, angle, scale, rate, max_knee_torque, rigid)


@njit(cache=True)
def leg_angle(leg: Leg) -> float:
    """The virtual leg's (hip to foot) world angle, rad, + = foot behind the hip."""
    return math.atan2(-leg.px, -leg.pz)


@njit(cache=True)
def swing_to_angle(
    m,  # noqa: ANN001 (a MEMORY record)
    leg: Leg,
    length: float,
    angle: float,
    scale: float = 1.0,
    rate: float = 0.0,
    max_knee_torque: float = -1.0,
    rigid: bool = False,
) -> tuple[float, float]:
    """PD of the virtual leg toward world `angle` (rad, + = foot behind the hip) and `length` (m);
    see swing_torques."""
    k, d = scale * scale, scale
    torque = k * SWING_K * (angle - leg_angle(leg)) - d * SWING_D * (leg.hip_rate + leg.knee_rate / 2 - rate)
    knee_target = -2.0 * math.acos(min(length / (m.thigh + m.shank), 0.999))
    cap = m.leg_limit if max_knee_torque < 0.0 else max_knee_torque
    bend = clamp(k * KNEE_K * (knee_target - leg.knee) - d * KNEE_D * leg.knee_rate, cap)
    hip = clamp(torque, m.leg_limit)
    follow = RIGID_KNEE * hip if rigid else torque / 2  # the knee's part of the turn
    return hip, clamp(follow + bend, m.leg_limit)
