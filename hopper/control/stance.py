"""Virtual-model control of the torso through the feet on the ground (LANDING, STANCE, CROUCH, PUSH)."""

from __future__ import annotations

import math
from typing import NamedTuple

from numba import njit

from hopper.control.gait import BOOST_SPEED
from hopper.control.legs import Leg, clamp, push_torques, swing_torques
from hopper.control.phases import Phase
from hopper.control.wheel import wheel_torque_bound

LANDING, STANCE, CROUCH, PUSH = int(Phase.LANDING), int(Phase.STANCE), int(Phase.CROUCH), int(Phase.PUSH)

# Gains, damping and times come from the gait at this gravity (hopper.control.gait, in `m`).
MIN_SUPPORT = 0.4  # fraction of the weight the stance legs always carry
BALANCE_MOMENT = 8.0  # N m, of the wheel's 29.5: the most the feet may stray from the momentum's wish
SUPPORT_MARGIN = 0.05  # least share of the vertical force on either of two feet: both stay loaded
CONTACT_LOAD = 2.0  # x the contact threshold: the least force either of two feet is asked for
# When one direction for both feet misses the horizontal force by FORCE_MISS (per N of the vertical
# one) where a foot's own cone reaches further, each foot gets its own, the moment within MOMENT_MISS.
FORCE_MISS = 0.05
MOMENT_MISS = 0.2  # N m
REACH_FORCE = 0.2  # fraction of the weight a free leg may push with while it reaches for the ground


class Body(NamedTuple):
    """The robot this tick and its support: torso pitch (rad), rate (rad/s), velocity (m/s),
    wheel speed (rad/s), hip height above the supporting feet (m), the whole robot's CoM ahead of
    them (m), its pitch angular momentum about that CoM (N m s), and the hip relative to that CoM
    (m): the feet's moments are taken about it."""

    pitch: float
    rate: float
    vx: float
    vz: float
    wheel_speed: float
    height: float
    offset_x: float
    momentum: float
    hip_x: float
    hip_z: float


@njit(cache=True)
def leg_capacity(m, leg: Leg, k: float) -> float:  # noqa: ANN001 (a MEMORY record)
    """Largest vertical force (N) the foot can push with, the horizontal one k times it, before a
    hip or knee motor reaches its limit (push_torques' tau = -J^T f, here per newton)."""
    hip, knee = push_torques(m, leg, k, 1.0)
    return m.leg_limit / max(abs(hip), abs(knee), 1e-6)


@njit(cache=True)
def cone(slope: float, mu: float) -> tuple[float, float]:
    """The horizontal-to-vertical force ratios (fx / fz) a foot on ground rising at `slope` (rad)
    holds without slipping: the friction cone turned with the ground's normal.

    A vertical force is always allowed: on a wall steeper than the friction angle the foot slides
    whatever it is asked, and pushing off the wall instead would throw the body back.
    """
    half = math.atan(mu)
    lo = math.tan(max(-slope - half, -1.4))  # 80 deg: tan stays finite
    hi = math.tan(min(-slope + half, 1.4))
    return min(lo, 0.0), max(hi, 0.0)


SPLIT_STEPS = 20  # shares of the weight the per-foot split tries between its bounds
SPLIT_MOMENTS = 3  # moments it tries across that band


@njit(cache=True)
def _directions(s, want, fx_share, rax, rza, rbx, rzb, lo_l, hi_l, lo_r, hi_r):  # noqa: ANN001, ANN202
    """For the left foot's share s of the vertical force: each foot's fx / fz (k_l, k_r), each in its
    own cone, making the moment `want` (N m per N of vertical force) or coming nearest it, then the
    horizontal force nearest fx_share (per N)."""
    # moment per N: s (rza k_l - rax) + (1 - s) (rzb k_r - rbx); a k_l + b k_r = rhs
    a, b = s * rza, (1.0 - s) * rzb
    rhs = want + s * rax + (1.0 - s) * rbx
    # a, b <= 0 (the feet are below the CoM): the moment falls as either k rises
    top, bottom = a * lo_l + b * lo_r, a * hi_l + b * hi_r
    if rhs >= top or rhs <= bottom:  # out of reach: the nearest corner
        return (lo_l, lo_r) if rhs >= top else (hi_l, hi_r)
    if abs(a) < 1e-9 or abs(b) < 1e-9:  # one foot carries nothing: the other makes the moment
        return (rhs / a, lo_r) if abs(b) < 1e-9 else (lo_l, rhs / b)
    # k_r = (rhs - a k_l) / b within [lo_r, hi_r] bounds k_l
    e1, e2 = (rhs - b * lo_r) / a, (rhs - b * hi_r) / a
    k_min, k_max = max(lo_l, min(e1, e2)), min(hi_l, max(e1, e2))
    # fx per N = s k_l + (1 - s) k_r, linear in k_l along the segment with the slope
    # s (1 - rza / rzb): about 0 with the feet at one height, and then equal directions
    slope = s - (1.0 - s) * a / b
    k_l = (fx_share - (1.0 - s) * rhs / b) / slope if abs(slope) > 1e-6 else rhs / (a + b)
    k_l = min(max(k_l, k_min), k_max)
    return k_l, (rhs - a * k_l) / b


@njit(cache=True)
def _score(s, k_l, k_r, want, fx_share, slack, rax, rza, rbx, rzb):  # noqa: ANN001, ANN202
    """(moment miss beyond `slack`, horizontal miss), both per N of vertical force, of the left
    foot's share s with directions k_l, k_r."""
    got = s * (rza * k_l - rax) + (1.0 - s) * (rzb * k_r - rbx)
    return max(abs(got - want) - slack, 0.0), abs(s * k_l + (1.0 - s) * k_r - fx_share)


@njit(cache=True)
def split(m, left, right, fz, want, fx_share, slack, rax, rza, rbx, rzb, lo_l, hi_l, lo_r, hi_r, s_lo, s_hi):  # noqa: ANN001, ANN201
    """The feet's shares and directions for the horizontal force nearest fx_share (per N of the
    vertical force `fz`, N) when each foot pushes inside its own friction cone (a foot on a wall and
    one on level ground hold different directions), the moment within `slack` of `want` (N m per N),
    and neither leg asked for more than its motors push in its own direction; positions of each
    foot relative to the CoM (m). The moment comes first: where no share reaches it, the nearest.
    Returns (s, k_l, k_r, moment miss, horizontal miss): the left foot's share of the vertical
    force, each foot's fx / fz, and what it misses by (per N; both 1e9 if no share is in reach)."""
    best_s, best_l, best_r, best_m, best_x = s_lo, lo_l, lo_r, 1e9, 1e9
    for i in range(SPLIT_STEPS + 1):
        s = s_lo + (s_hi - s_lo) * i / SPLIT_STEPS
        for j in range(SPLIT_MOMENTS):
            target = want + slack * (2.0 * j / (SPLIT_MOMENTS - 1) - 1.0)
            k_l, k_r = _directions(s, target, fx_share, rax, rza, rbx, rzb, lo_l, hi_l, lo_r, hi_r)
            miss, off = _score(s, k_l, k_r, want, fx_share, slack, rax, rza, rbx, rzb)
            # A leg past its motors' limit in the new direction would not deliver its share, nor
            # the moment (Mars seed 27: the rear leg asked to push forward off a 37 deg wall sat at
            # 30 N m in both joints, and the feet pitched the robot back past the wheel).
            strong = s * fz <= leg_capacity(m, left, k_l) and (1.0 - s) * fz <= leg_capacity(m, right, k_r)
            if strong and (miss < best_m - 1e-9 or (miss <= best_m + 1e-9 and off < best_x)):
                best_s, best_l, best_r, best_m, best_x = s, k_l, k_r, miss, off
    return best_s, best_l, best_r, best_m, best_x


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
    hip_x, hip_z = body.hip_x, body.hip_z

    if phase == LANDING:
        az = m.kz * (m.stand - height) - m.landing_damping * vz
        ax = -m.dx * vx
    elif phase == PUSH:
        # The push ends when the longest supporting leg reaches the push length: the rear leg,
        # further from the hip, straightens first, and a straight leg can no longer push, which
        # would leave the last of the push (and its moment) to the front foot alone.
        reach = 0.0
        if left.on:
            reach = math.hypot(left.px, left.pz)
        if right.on:
            reach = max(reach, math.hypot(right.px, right.pz))
        vz_lo = m.recovery_vz if m.recovering else (m.vz_boost if m.boost else m.vz_liftoff)
        remaining = max(m.push - reach, 0.02)
        az = min(max((vz_lo * vz_lo - vz * abs(vz)) / (2 * remaining), 0.0), m.push_accel)
        if m.recovering and left.on != right.on and vz < vz_lo:
            # A recovery hop from one foot leaves as quickly as the legs allow: the CoM falls away
            # from the foot (an inverted pendulum), whose cone leaves it little moment, and every
            # extra ms of push is ground impulse off the CoM that the wheel takes; spread over the
            # whole stroke, the push filled it before the flight. Two feet can take the moment
            # (and a kick's momentum) out while they push, and take their time.
            az = m.push_accel
        # A recovery hop keeps the speed it has: the landing, not the push, takes it out.
        speed = m.forward_speed * (BOOST_SPEED if m.boost else 1.0)
        ax = 0.0 if m.recovering else clamp(m.push_x_gain * (speed - vx), m.push_x_accel)
        if vz >= vz_lo or reach >= m.push:
            m.push_done = True
    elif phase == CROUCH:
        # Crouch leaning ahead of the feet midpoint: the push's ground force must point from the
        # (rear) foot through the CoM, so the lean sets how much forward speed the push can add.
        az = m.kz * (m.crouch - height) - m.dz * vz
        ax = m.kx * (m.lean - offset_x) - m.dx * vx
    else:
        az = m.kz * (m.stand - height) - m.dz * vz
        ax = -m.kx * offset_x - m.dx * vx
    # Never ask the ground for less than MIN_SUPPORT of the weight: a limp leg loses its foot, and
    # in low gravity the body sinks slowly enough that a crouch needs no faster drop.
    fz = m.mass * m.gravity * max(1.0 + az / m.gravity, MIN_SUPPORT)
    fx = m.mass * ax

    # Moments. With the wheel, the feet drive the whole robot's pitch momentum to zero (only
    # they can change it) while the wheel holds the torso's attitude (an internal torque). With
    # zero total momentum a still torso means a still wheel: the wheel spins down by itself, as
    # fast as the feet can take the momentum out, and every flight starts with its whole
    # capacity free. What the wheel cannot give (its envelope) falls back on the feet. Without
    # the wheel, the feet hold the torso's attitude themselves.
    wheel_on = m.wheel_on
    if wheel_on:
        torso = m.hold_kp * pitch + m.hold_kd * rate  # torque the torso needs, as a wheel command
        wheel = wheel_torque_bound(m, wheel_speed, torso)
        feet = -m.momentum_gain * body.momentum - (torso - wheel)
    else:
        wheel = 0.0
        feet = -(m.kp_stance * pitch + m.kd_stance * rate)

    # Each foot's friction cone, turned with the ground under it: on a slope the same force that
    # holds on level ground slides the foot (a world-frame cone let landings on crater walls slip
    # at the full friction ratio). Two feet share one direction, so inside both cones (never
    # empty: each holds the vertical).
    lo_l, hi_l = cone(m.slope_l, m.friction)
    lo_r, hi_r = cone(m.slope_r, m.friction)
    if left.on and right.on:
        k_lo, k_hi = max(lo_l, lo_r), min(hi_l, hi_r)
    elif left.on:
        k_lo, k_hi = lo_l, hi_l
    else:
        k_lo, k_hi = lo_r, hi_r
    # Balancing (not pushing), the CoM comes first: the feet may make up to `stray` N m more or
    # less than the momentum asks; the wheel keeps the torso upright and holds the difference
    # until both feet can take it out again.
    balance = wheel_on and phase != PUSH
    stray = BALANCE_MOMENT
    rax, rbx = hip_x + left.px, hip_x + right.px
    if both and abs(rax - rbx) > 0.05:
        # Two feet, each pushing in the same direction (fx_i = k fz_i, so both meet friction
        # alike): the share s of the weight on the left foot sets the feet's moment,
        # feet = fz (c0 + s c1). The share can only go from SUPPORT_MARGIN to 1 - SUPPORT_MARGIN;
        # beyond, the horizontal force yields to the moment.
        rza, rzb = hip_z + left.pz, hip_z + right.pz
        k = min(max(fx / fz, k_lo), k_hi)
        want = feet / fz
        c0, c1 = rzb * k - rbx, (rza - rzb) * k - (rax - rbx)
        s = (want - c0) / c1
        # Each foot keeps well above the contact threshold too: a foot unloaded to near it in a
        # light crouch chattered on and off, each "off" swinging its leg as a free one.
        low = min(max(SUPPORT_MARGIN, CONTACT_LOAD * m.contact_on / fz), 0.5)
        # Nor more on a foot than its leg's motors can push: a leg bent deep (its foot high on a
        # crater wall) saturates its knee, and the force asked of it never reaches the ground.
        top_l, top_r = leg_capacity(m, left, k) / fz, leg_capacity(m, right, k) / fz
        lo, hi = max(low, 1.0 - top_r), min(1.0 - low, top_l)
        if lo > hi:  # the legs together cannot carry fz: each carries its share of what they can
            lo = hi = min(max(top_l / (top_l + top_r), low), 1.0 - low)
        wish, band = want, stray / fz if balance else 0.0  # the moment asked (per N), and its slack
        if not lo <= s <= hi:
            s = min(max(s, lo), hi)
            if balance:  # keep the force the CoM needs, within `stray` of the moment wanted
                want = min(max(c0 + s * c1, want - stray / fz), want + stray / fz)
            k = min(max((want + rbx + s * (rax - rbx)) / (rzb + s * (rza - rzb)), k_lo), k_hi)
        k_l = k_r = k
        short = fx / fz - k  # the horizontal force one direction misses, per N
        # ... because the narrower cone binds, where the other foot's reaches further
        ahead = short > FORCE_MISS and k >= k_hi - 1e-9 and max(hi_l, hi_r) > k_hi + FORCE_MISS
        back = -short > FORCE_MISS and k <= k_lo + 1e-9 and min(lo_l, lo_r) < k_lo - FORCE_MISS
        got = rzb * k - rbx + s * ((rza - rzb) * k - (rax - rbx))  # the moment per N it makes
        gap = max(abs(got - wish) - band, 0.0)  # ... and what it misses beyond the slack
        cones = (lo_l, hi_l, lo_r, hi_r)
        if gap > MOMENT_MISS / fz:
            # One direction cannot make the moment: with its rear foot on a wall falling at 37 deg,
            # whose cone holds no braking, a landing robot could not brake with its front foot,
            # and both feet ahead of the CoM pitched it back past the wheel (Mars seed 27). Each
            # foot in its own cone, the moment first, then the horizontal force.
            s2, k_l2, k_r2, miss2, _ = split(
                m, left, right, fz, wish, fx / fz, band, rax, rza, rbx, rzb, *cones, lo, hi
            )
            if miss2 < gap - MOMENT_MISS / fz:
                s, k_l, k_r = s2, k_l2, k_r2
        elif ahead or back:
            # One direction for both feet falls short of the horizontal force, held to the narrower
            # cone (of a foot on a wall): each foot in its own cone, the share chosen again, for
            # the same moment. With its front foot on a 35 deg wall, whose cone holds next to no
            # forward force, a robot could not move its CoM forward and hopped back into the
            # crater it was climbing out of, hundreds of times (Mars seed 0).
            s2, k_l2, k_r2, miss2, off2 = split(
                m, left, right, fz, got, fx / fz, MOMENT_MISS / fz, rax, rza, rbx, rzb, *cones, lo, hi
            )
            if miss2 <= 1e-9 and off2 < abs(k - fx / fz) - 1e-6:
                s, k_l, k_r = s2, k_l2, k_r2
        fz_l = s * fz
        fz_r = fz - fz_l
        hl, kl = push_torques(m, left, k_l * fz_l, fz_l)
        hr, kr = push_torques(m, right, k_r * fz_r, fz_r)
        return wheel, hl, kl, hr, kr
    # One support point: the feet's moment is rz fx + offset_x fz, so the moment sets fx, but
    # while balancing fx may stray from it toward the force the CoM needs by `stray` N m.
    rz = hip_z - height
    fx_moment = (feet - offset_x * fz) / rz
    fx = min(max(fx, fx_moment - stray / -rz), fx_moment + stray / -rz) if balance else fx_moment
    fx = min(max(fx, k_lo * fz), k_hi * fz)
    if both:
        hl, kl = push_torques(m, left, fx / 2, fz / 2)
        hr, kr = push_torques(m, right, fx / 2, fz / 2)
        return wheel, hl, kl, hr, kr
    # The free foot reaches a little below the stance foot to find the ground, gently: a leg
    # that keeps extending into the ground launches the robot in lunar gravity.
    half = 0.5 * m.spread
    gentle = REACH_FORCE * m.mass * m.gravity * 0.5 * m.shank  # knee torque, ~0.5 L2 lever
    if left.on:
        hl, kl = push_torques(m, left, fx, fz)
        hr, kr = swing_torques(m, right, m.push, -half, 1.0, max_knee_torque=gentle)
    else:
        hr, kr = push_torques(m, right, fx, fz)
        hl, kl = swing_torques(m, left, m.push, half, 1.0, max_knee_torque=gentle)
    return wheel, hl, kl, hr, kr
