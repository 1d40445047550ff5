"""Virtual-model control of the torso through the feet on the ground (LANDING, STANCE, CROUCH, PUSH)."""

from __future__ import annotations

import math
from typing import NamedTuple

from numba import njit

from hopper.config import HIP_OFFSET_Z, TOTAL_MASS, WHEEL_INERTIA
from hopper.control.legs import L2, Leg, clamp, push_torques, swing_torques
from hopper.control.phases import Phase
from hopper.control.wheel import wheel_torque_bound

LANDING, STANCE, CROUCH, PUSH = int(Phase.LANDING), int(Phase.STANCE), int(Phase.CROUCH), int(Phase.PUSH)

# Virtual model gains, from natural frequency (rad/s) and damping ratio.
STANCE_HEIGHT_WN, STANCE_HEIGHT_ZETA = 5.0, 1.0
STANCE_X_WN, STANCE_X_ZETA = 4.0, 1.0
STANCE_PITCH_WN, STANCE_PITCH_ZETA = 8.0, 1.0
STANCE_PITCH_INERTIA = 0.5  # kg m^2, I_locked - I_w (PHYSICS.md)
KZ, DZ = STANCE_HEIGHT_WN**2, 2 * STANCE_HEIGHT_ZETA * STANCE_HEIGHT_WN
KX, DX = STANCE_X_WN**2, 2 * STANCE_X_ZETA * STANCE_X_WN
KP_STANCE = STANCE_PITCH_INERTIA * STANCE_PITCH_WN**2
KD_STANCE = 2 * STANCE_PITCH_ZETA * STANCE_PITCH_WN * STANCE_PITCH_INERTIA
LANDING_DAMPING = 6.0  # 1/s, vertical velocity damping while absorbing the impact
DESAT_TIME = 0.25  # s, time constant of the stance wheel spin-down
MIN_SUPPORT = 0.4  # fraction of the weight the stance legs always carry
SINGLE_SUPPORT_WHEEL = 8.0  # N m of wheel torque the legs may leave for balance on one foot
REACH_FORCE = 0.2  # fraction of the weight a free leg may push with while it reaches for the ground
PUSH_MAX_ACCEL = 8.0  # m/s^2, cap on the push-off acceleration
PUSH_X_GAIN = 6.0  # 1/s, horizontal velocity tracking during the push


class Body(NamedTuple):
    """The torso this tick and its support: pitch (rad), rate (rad/s), velocity (m/s), wheel speed
    (rad/s), hip height above the supporting feet (m) and torso CoM ahead of them (m)."""

    pitch: float
    rate: float
    vx: float
    vz: float
    wheel_speed: float
    height: float
    offset_x: float


@njit(cache=True)
def stance(m, phase: int, body: Body, left: Leg, right: Leg) -> tuple[float, float, float, float, float]:  # noqa: ANN001
    """Returns (wheel, hip_L, knee_L, hip_R, knee_R) torques (N m) for the feet in contact.

    A desired force (fx, fz) and pitch moment on the torso are distributed over the feet in
    contact and mapped to joint torques by tau = -J^T f (the legs are light: 1.2 of 8.2 kg).
    `m` is the kernel's MEMORY record (parameters; `push_done` is set here).
    """
    pitch, rate, vx, vz, wheel_speed = body.pitch, body.rate, body.vx, body.vz, body.wheel_speed
    height, offset_x = body.height, body.offset_x
    both = left.on and right.on
    hip_x, hip_z = HIP_OFFSET_Z * math.sin(pitch), HIP_OFFSET_Z * math.cos(pitch)  # hip rel. torso CoM

    if phase == LANDING:
        az = KZ * (m.stand - height) - LANDING_DAMPING * vz
        ax = -DX * vx
    elif phase == PUSH:
        vz_lo = m.vz_liftoff
        remaining = max(m.push - height, 0.02)
        az = min(max((vz_lo * vz_lo - vz * abs(vz)) / (2 * remaining), 0.0), PUSH_MAX_ACCEL)
        ax = clamp(PUSH_X_GAIN * (m.forward_speed - vx), 3.0)
        if vz >= vz_lo or height >= m.push:
            m.push_done = True
    elif phase == CROUCH:
        # Crouch leaning ahead of the feet midpoint: the push's ground force must point from the
        # (rear) foot through the CoM, so the lean sets how much forward speed the push can add.
        az = KZ * (m.crouch - height) - DZ * vz
        ax = KX * (m.lean - offset_x) - DX * vx
    else:
        az = KZ * (m.stand - height) - DZ * vz
        ax = -KX * offset_x - DX * vx
    # Never ask the ground for less than MIN_SUPPORT of the weight: a limp leg loses its foot, and
    # in low gravity the body sinks slowly enough that a crouch needs no faster drop.
    fz = TOTAL_MASS * m.gravity * max(1.0 + az / m.gravity, MIN_SUPPORT)
    fx = TOTAL_MASS * ax

    # Priorities: the pitch moment, then the horizontal force, then spinning the wheel down.
    # The torso's moment is what the feet give (sum of rz fx - rx fz) minus the wheel torque.
    wheel_on = m.wheel_on
    wheel = wheel_torque_bound(wheel_speed, -WHEEL_INERTIA * wheel_speed / DESAT_TIME) if wheel_on else 0.0
    moment = -KP_STANCE * pitch - KD_STANCE * rate  # wanted on the torso

    mu = m.friction
    rax, rbx = hip_x + left.px, hip_x + right.px
    if both and abs(rax - rbx) > 0.05:
        # Two feet: split fz so that the feet give moment + wheel. The split can balance fx only
        # between the two extremes of all the weight on one foot; beyond them (with a margin)
        # the wheel takes the rest of the moment while it can when balancing, else fx yields
        # (a push that spun the wheel up would start the flight with the wheel half full).
        rz2 = 2 * hip_z + left.pz + right.pz
        fx_a, fx_b = 2 * (moment + wheel + rax * fz) / rz2, 2 * (moment + wheel + rbx * fz) / rz2
        low, high = min(fx_a, fx_b), max(fx_a, fx_b)
        margin = 0.1 * (high - low)
        if not low + margin <= fx <= high - margin:
            if wheel_on and (phase in (LANDING, STANCE)):  # balance, not the push's thrust
                at_low = fx < low + margin
                edge_x = rax if (fx_a < fx_b) == at_low else rbx  # the foot carrying all the weight
                wheel = wheel_torque_bound(wheel_speed, rz2 * fx / 2 - edge_x * fz - moment)
                fx = 2 * (moment + wheel + edge_x * fz) / rz2
            else:
                fx = min(max(fx, low + margin), high - margin)
        fx /= 2
        fz_l = min(max((rz2 * fx - moment - wheel - rbx * fz) / (rax - rbx), 0.0), fz)
        fz_r = fz - fz_l
        hl, kl = push_torques(left, clamp(fx, mu * fz_l), fz_l)  # friction cone
        hr, kr = push_torques(right, clamp(fx, mu * fz_r), fz_r)
        return wheel, hl, kl, hr, kr
    # One support point: the feet's moment is rz fx + offset_x fz, so the pitch moment sets fx.
    # With the wheel, fx may stray from that toward keeping the CoM over the foot by as much as
    # the wheel can make up within SINGLE_SUPPORT_WHEEL (N m) of torque.
    rz = hip_z - height
    fx_pitch = (moment - offset_x * fz) / rz
    if wheel_on:
        stray = SINGLE_SUPPORT_WHEEL / -rz
        fx = clamp(min(max(fx, fx_pitch - stray), fx_pitch + stray), mu * fz)
        wheel = wheel_torque_bound(wheel_speed, rz * fx + offset_x * fz - moment)
    else:
        fx = fx_pitch
    if both:
        hl, kl = push_torques(left, clamp(fx / 2, mu * fz / 2), fz / 2)
        hr, kr = push_torques(right, clamp(fx / 2, mu * fz / 2), fz / 2)
        return wheel, hl, kl, hr, kr
    # The free foot reaches a little below the stance foot to find the ground, gently: a leg
    # that keeps extending into the ground launches the robot in lunar gravity.
    half = 0.5 * m.spread
    gentle = REACH_FORCE * TOTAL_MASS * m.gravity * 0.5 * L2  # knee torque, ~0.5 L2 lever
    if left.on:
        hl, kl = push_torques(left, clamp(fx, mu * fz), fz)
        hr, kr = swing_torques(right, m.push, -half, gentle)
    else:
        hr, kr = push_torques(right, clamp(fx, mu * fz), fz)
        hl, kl = swing_torques(left, m.push, half, gentle)
    return wheel, hl, kl, hr, kr
