"""Hop controller: wheel PID in flight, virtual-model legs on the ground, the phase machine.

The per-tick work is one numba-compiled kernel, `control_tick`, reading MuJoCo's arrays in place
and writing `data.ctrl` directly. In plain Python the same logic cost ~25 us a tick, more than
MuJoCo's step itself; compiled it costs ~1 us. The kernel reads the model's coordinates through
the named indices of `hopper.model` (the layout `Physics` checks) and keeps its state in small
float arrays whose slots are named below; `HopController` is the Python face of it.
Set NUMBA_DISABLE_JIT=1 to step through the kernel in a Python debugger.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from hopper.config import (
    HIP_OFFSET_Z,
    LEG_TORQUE_LIMIT,
    SATURATION_FRACTION,
    SHANK_LENGTH,
    THIGH_LENGTH,
    TOTAL_MASS,
    WHEEL_GEAR,
    WHEEL_INERTIA,
    WHEEL_NO_LOAD_SPEED,
    WHEEL_TORQUE_LIMIT,
    Gains,
    GaitParams,
)
from hopper.model import (
    Q_HIP_L,
    Q_HIP_R,
    Q_KNEE_L,
    Q_KNEE_R,
    Q_PITCH,
    Q_WHEEL,
    Q_X,
    Q_Z,
    S_FOOT_L,
    S_FOOT_R,
    S_GYRO_Y,
    S_WHEEL_TORQUE,
)
from hopper.phases import CONTACT_OFF_N, CONTACT_ON_N, DEBOUNCE_OFF_S, DEBOUNCE_ON_S, Phase

L1, L2 = THIGH_LENGTH, SHANK_LENGTH
WHEEL_DAMPING = WHEEL_TORQUE_LIMIT / WHEEL_NO_LOAD_SPEED  # N m s/rad, back-EMF slope at the wheel
SATURATION_TORQUE = SATURATION_FRACTION * WHEEL_TORQUE_LIMIT  # N m

# Stance: virtual model gains, from natural frequency (rad/s) and damping ratio.
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
# Flight: the legs swing as a virtual leg (length, angle) with PD gains about the hip.
SWING_K, SWING_D = 15.0, 2.5  # N m/rad, N m s/rad  (wn ~ 10 rad/s for ~0.15 kg m^2)
KNEE_K, KNEE_D = 20.0, 1.5  # N m/rad, N m s/rad (wn ~ 10 rad/s for the shank about the knee)
# Fall: beyond these the legs cannot recover the body.
FALL_PITCH = math.radians(60.0)
FALL_HIP_HEIGHT = 0.35  # m, hip above the feet in stance
# Phase timing, s.
LANDING_MIN_S, STANCE_MAX_S, CROUCH_MIN_S, CROUCH_MAX_S, PUSH_MAX_S = 0.1, 2.0, 0.15, 1.2, 1.0
LIFTOFF_CONFIRM_S = 0.01  # s both feet off after a push before the flight counts
BOUNCE_CONFIRM_S = 0.08  # s both feet off in any other ground phase before it is a flight

LANDING, STANCE, CROUCH, PUSH, FLIGHT, FALLEN = (int(p) for p in Phase)

# Parameter slots (written from Python when gains or gait change).
(
    P_KP,
    P_KI,
    P_KD,
    P_GRAVITY,
    P_WHEEL_ON,
    P_VZ_LIFTOFF,
    P_FORWARD_SPEED,
    P_STAND,
    P_CROUCH,
    P_PUSH,
    P_FLIGHT_LENGTH,
    P_SPREAD,
    P_PLACEMENT,
    P_LEAN,
    P_STANCE_TIME,
    P_FRICTION,
    P_X0,
    P_Z0,
    P_DT,
    N_PARAMS,
) = range(20)
# State slots (the kernel's memory between ticks).
(
    K_PHASE,
    K_PHASE_START,
    K_PUSH_DONE,
    K_INTEGRAL,
    K_SATURATED,
    K_CONTACT_L,
    K_PENDING_L,
    K_CONTACT_R,
    K_PENDING_R,
    K_WHEEL_COMMAND,
    K_PREV_VZ,
    K_LAST_CONTACT,
    K_CLOCK,
    N_STATE,
) = range(14)
# Metric accumulators for the hop in progress (hopper.metrics reads and clears them).
(A_SATURATION, A_PEAK_PITCH, A_RATE_SQ, A_FLIGHT_TICKS, A_APEX_Z, A_PEAK_WHEEL, N_ACC) = range(7)
MEM_STATE, MEM_ACC = N_PARAMS, N_PARAMS + N_STATE  # offsets in the kernel's one memory array
N_MEM = MEM_ACC + N_ACC
# Event bits returned by the kernel.
EV_LIFTOFF, EV_TOUCHDOWN, EV_FALL, EV_APEX = 1, 2, 4, 8


@njit(cache=True)
def clamp(value: float, limit: float) -> float:
    return value if -limit < value < limit else (limit if value > 0 else -limit)


@njit(cache=True)
def leg_kinematics(pitch: float, hip: float, knee: float) -> tuple[float, float, float, float]:
    """Foot centre relative to the hip in world axes (px, pz) and d(px, pz)/d(knee).

    d(px)/d(hip) = pz and d(pz)/d(hip) = -px, so they need no return slot.
    """
    a1 = pitch + hip
    a2 = a1 + knee
    s2, c2 = math.sin(a2), math.cos(a2)
    return -L1 * math.sin(a1) - L2 * s2, -L1 * math.cos(a1) - L2 * c2, -L2 * c2, L2 * s2


@njit(cache=True)
def push_torques(px: float, pz: float, jx: float, jz: float, fx: float, fz: float) -> tuple[float, float]:
    """Hip and knee torques that make the ground push on the foot with (fx, fz): tau = -J^T f."""
    return clamp(px * fz - pz * fx, LEG_TORQUE_LIMIT), clamp(-(jx * fx + jz * fz), LEG_TORQUE_LIMIT)


@njit(cache=True)
def swing_torques(
    px: float,
    pz: float,
    knee: float,
    hip_rate: float,
    knee_rate: float,
    length: float,
    foot_x: float,
    max_knee_torque: float = LEG_TORQUE_LIMIT,
) -> tuple[float, float]:
    """PD toward a foot `foot_x` ahead of the hip, `length` from it (a swing, not a support).

    The virtual leg (hip to foot) bisects the knee, so its world angle is servoed by the hip
    (the knee takes half of that torque to keep the bisection) and its length by the knee, in
    joint space: length = 2 L cos(knee / 2) has no gradient at a straight knee, where a
    Cartesian length servo would lock the leg straight. Damping acts on the joint rates so the
    legs do not fight the torso's rotation. `max_knee_torque` caps the length servo (N m).
    """
    angle = -math.asin(clamp(foot_x / length, 0.9))  # world angle, + = foot behind the hip
    torque = SWING_K * (angle - math.atan2(-px, -pz)) - SWING_D * (hip_rate + knee_rate / 2)
    knee_target = -2.0 * math.acos(min(length / (L1 + L2), 0.999))
    bend = clamp(KNEE_K * (knee_target - knee) - KNEE_D * knee_rate, max_knee_torque)
    return clamp(torque, LEG_TORQUE_LIMIT), clamp(torque / 2 + bend, LEG_TORQUE_LIMIT)


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
def wheel_pid(pitch: float, rate: float, wheel_speed: float, dt: float, p: np.ndarray, k: np.ndarray) -> float:
    """The paper's flight law on the measured pitch and rate, clamped to the envelope, anti-windup.

    Sign: the paper's tau_w is the torque on the torso; MuJoCo's motor torque acts on the wheel
    and the torso takes its reaction, so the motor command is kp theta + kd theta_dot + ki int.
    D acts on the measured rate, so a gain change causes no derivative kick.
    """
    command = p[P_KP] * pitch + p[P_KD] * rate + p[P_KI] * k[K_INTEGRAL]
    torque = wheel_torque_bound(wheel_speed, command)
    saturated = torque != command
    k[K_SATURATED] = 1.0 if saturated else 0.0
    if not saturated:  # conditional integration: no windup while saturated
        k[K_INTEGRAL] += pitch * dt
    return torque


@njit(cache=True)
def debounce(force: float, time: float, k: np.ndarray, on_slot: int, pending_slot: int) -> bool:
    """One foot's contact with hysteresis (on above CONTACT_ON_N, off below CONTACT_OFF_N) and
    a hold of DEBOUNCE_ON_S / DEBOUNCE_OFF_S before a change is believed. pending < 0 means no
    change is pending."""
    on = k[on_slot] > 0.5
    changing = force < CONTACT_OFF_N if on else force > CONTACT_ON_N
    if not changing:
        k[pending_slot] = -1.0
    elif k[pending_slot] < 0.0:
        k[pending_slot] = time
    elif time - k[pending_slot] >= (DEBOUNCE_OFF_S if on else DEBOUNCE_ON_S) - 1e-9:
        on = not on
        k[on_slot] = 1.0 if on else 0.0
        k[pending_slot] = -1.0
    return on


@njit(cache=True)
def enter(k: np.ndarray, phase: int, time: float) -> None:
    k[K_PHASE], k[K_PHASE_START], k[K_PUSH_DONE] = phase, time, 0.0


@njit(cache=True)
def control_tick(qpos: np.ndarray, qvel: np.ndarray, sensors: np.ndarray, ctrl: np.ndarray, mem: np.ndarray) -> int:
    """One 1 kHz tick: advance the phase, write the 5 actuator commands into `ctrl`, accumulate
    the hop metrics. Returns the EV_* bits of what happened this tick.

    `mem` holds the parameters, the state and the metric accumulators back to back (one array
    argument: each costs ~0.3 us of dispatch). The kernel keeps its own copy of the clock,
    advanced exactly as mj_step advances data.time.
    """
    p, k, acc = mem[:N_PARAMS], mem[MEM_STATE:MEM_ACC], mem[MEM_ACC:]
    time, dt = k[K_CLOCK], p[P_DT]
    pitch, rate = qpos[Q_PITCH], sensors[S_GYRO_Y]
    vx, vz, wheel_speed = qvel[Q_X], qvel[Q_Z], qvel[Q_WHEEL]
    pxl, pzl, jxl, jzl = leg_kinematics(pitch, qpos[Q_HIP_L], qpos[Q_KNEE_L])
    pxr, pzr, jxr, jzr = leg_kinematics(pitch, qpos[Q_HIP_R], qpos[Q_KNEE_R])
    on_l = debounce(sensors[S_FOOT_L], time, k, K_CONTACT_L, K_PENDING_L)
    on_r = debounce(sensors[S_FOOT_R], time, k, K_CONTACT_R, K_PENDING_R)
    contact = on_l or on_r
    # Support geometry: hip above the feet' centres, torso CoM ahead of the feet's midpoint.
    if on_l and on_r:
        height, px = -0.5 * (pzl + pzr), 0.5 * (pxl + pxr)
    elif contact:
        height, px = (-pzl, pxl) if on_l else (-pzr, pxr)
    else:
        height, px = 0.0, 0.0
    if contact:
        k[K_LAST_CONTACT] = time
    offset_x = -(HIP_OFFSET_Z * math.sin(pitch) + px)

    # -- phase transitions --
    events = 0
    phase = int(k[K_PHASE])
    elapsed = time - k[K_PHASE_START]
    if phase != FALLEN:
        if not -FALL_PITCH < pitch < FALL_PITCH or (contact and phase != FLIGHT and height < FALL_HIP_HEIGHT):
            enter(k, FALLEN, time)
            events |= EV_FALL
        elif phase == FLIGHT:
            if contact:
                enter(k, LANDING, time)
                events |= EV_TOUCHDOWN
        elif not contact:
            # Liftoff once both feet have been off for a while: a foot skipping over a crater
            # rim for a few ms during the push is not a hop, nor is a stumble off a rim while
            # standing unless it lasts long enough to need the wheel's flight control.
            confirm = LIFTOFF_CONFIRM_S if phase == PUSH else BOUNCE_CONFIRM_S
            if time - k[K_LAST_CONTACT] >= confirm:
                enter(k, FLIGHT, time)
                k[K_INTEGRAL] = 0.0  # integral reset at liftoff
                events |= EV_LIFTOFF
        elif phase == LANDING:
            if elapsed > LANDING_MIN_S and -0.1 < vz < 0.1:
                enter(k, STANCE, time)
        elif phase == STANCE:
            settled = abs(vx) < 0.08 and abs(vz) < 0.08 and abs(pitch) < 0.05 and abs(rate) < 0.15
            if elapsed > p[P_STANCE_TIME] and (settled or elapsed > STANCE_MAX_S):
                enter(k, CROUCH, time)
        elif phase == CROUCH:
            loaded = abs(height - p[P_CROUCH]) < 0.03 and abs(offset_x - p[P_LEAN]) < 0.04 and elapsed > CROUCH_MIN_S
            if loaded or elapsed > CROUCH_MAX_S:
                enter(k, PUSH, time)
        elif phase == PUSH and k[K_PUSH_DONE] > 0.5 and elapsed > PUSH_MAX_S:
            enter(k, STANCE, time)  # the feet never left: stand and try again
    phase = int(k[K_PHASE])

    # -- actuation --
    wheel = 0.0
    if phase in (FLIGHT, FALLEN) or k[K_PUSH_DONE] > 0.5 or not contact:
        # Legs swing to the landing pose, feet placed ahead by the Raibert term.
        mid = p[P_PLACEMENT] * vx
        half = 0.5 * p[P_SPREAD]
        length = p[P_FLIGHT_LENGTH]
        ctrl[1], ctrl[2] = swing_torques(pxl, pzl, qpos[Q_KNEE_L], qvel[Q_HIP_L], qvel[Q_KNEE_L], length, mid + half)
        ctrl[3], ctrl[4] = swing_torques(pxr, pzr, qpos[Q_KNEE_R], qvel[Q_HIP_R], qvel[Q_KNEE_R], length, mid - half)
        if phase == FLIGHT:
            wheel = wheel_pid(pitch, rate, wheel_speed, dt, p, k)
    else:
        wheel = stance(
            pitch,
            rate,
            vx,
            vz,
            wheel_speed,
            phase,
            height,
            offset_x,
            on_l,
            on_r,
            pxl,
            pzl,
            jxl,
            jzl,
            pxr,
            pzr,
            jxr,
            jzr,
            qpos,
            qvel,
            p,
            k,
            ctrl,
        )
    if p[P_WHEEL_ON] < 0.5:
        wheel = 0.0
    k[K_WHEEL_COMMAND] = wheel
    ctrl[0] = wheel_ctrl(wheel, wheel_speed)

    # -- metrics of the hop in progress --
    torque = sensors[S_WHEEL_TORQUE] * WHEEL_GEAR  # motor-side actuator force through the gear
    if torque >= SATURATION_TORQUE or torque <= -SATURATION_TORQUE:
        acc[A_SATURATION] += dt
    acc[A_PEAK_WHEEL] = max(acc[A_PEAK_WHEEL], abs(wheel_speed))
    if phase == FLIGHT:
        acc[A_PEAK_PITCH] = max(acc[A_PEAK_PITCH], abs(pitch))
        acc[A_RATE_SQ] += rate * rate
        acc[A_FLIGHT_TICKS] += 1.0
        acc[A_APEX_Z] = max(acc[A_APEX_Z], qpos[Q_Z] + p[P_Z0])
        if k[K_PREV_VZ] > 0.0 >= vz:
            events |= EV_APEX
    k[K_PREV_VZ] = vz
    k[K_CLOCK] = time + dt
    return events


@njit(cache=True)
def stance(
    pitch: float,
    rate: float,
    vx: float,
    vz: float,
    wheel_speed: float,
    phase: int,
    height: float,
    offset_x: float,
    on_l: bool,
    on_r: bool,
    pxl: float,
    pzl: float,
    jxl: float,
    jzl: float,
    pxr: float,
    pzr: float,
    jxr: float,
    jzr: float,
    qpos: np.ndarray,
    qvel: np.ndarray,
    p: np.ndarray,
    k: np.ndarray,
    ctrl: np.ndarray,
) -> float:
    """Virtual model control of the torso through the feet on the ground. Returns wheel torque.

    A desired force (fx, fz) and pitch moment on the torso are distributed over the feet in
    contact and mapped to joint torques by tau = -J^T f (the legs are light: 1.2 of 8.2 kg).
    """
    both = on_l and on_r
    hip_x, hip_z = HIP_OFFSET_Z * math.sin(pitch), HIP_OFFSET_Z * math.cos(pitch)  # hip rel. torso CoM

    if phase == LANDING:
        az = KZ * (p[P_STAND] - height) - LANDING_DAMPING * vz
        ax = -DX * vx
    elif phase == PUSH:
        vz_lo = p[P_VZ_LIFTOFF]
        remaining = max(p[P_PUSH] - height, 0.02)
        az = min(max((vz_lo * vz_lo - vz * abs(vz)) / (2 * remaining), 0.0), PUSH_MAX_ACCEL)
        ax = clamp(PUSH_X_GAIN * (p[P_FORWARD_SPEED] - vx), 3.0)
        if vz >= vz_lo or height >= p[P_PUSH]:
            k[K_PUSH_DONE] = 1.0
    elif phase == CROUCH:
        # Crouch leaning ahead of the feet midpoint: the push's ground force must point from the
        # (rear) foot through the CoM, so the lean sets how much forward speed the push can add.
        az = KZ * (p[P_CROUCH] - height) - DZ * vz
        ax = KX * (p[P_LEAN] - offset_x) - DX * vx
    else:
        az = KZ * (p[P_STAND] - height) - DZ * vz
        ax = -KX * offset_x - DX * vx
    # Never ask the ground for less than MIN_SUPPORT of the weight: a limp leg loses its foot, and
    # in low gravity the body sinks slowly enough that a crouch needs no faster drop.
    fz = TOTAL_MASS * p[P_GRAVITY] * max(1.0 + az / p[P_GRAVITY], MIN_SUPPORT)
    fx = TOTAL_MASS * ax

    # Priorities: the pitch moment, then the horizontal force, then spinning the wheel down.
    # The torso's moment is what the feet give (sum of rz fx - rx fz) minus the wheel torque.
    wheel_on = p[P_WHEEL_ON] > 0.5
    wheel = wheel_torque_bound(wheel_speed, -WHEEL_INERTIA * wheel_speed / DESAT_TIME) if wheel_on else 0.0
    moment = -KP_STANCE * pitch - KD_STANCE * rate  # wanted on the torso

    mu = p[P_FRICTION]
    rax, rbx = hip_x + pxl, hip_x + pxr
    if both and abs(rax - rbx) > 0.05:
        # Two feet: split fz so that the feet give moment + wheel. The split can balance fx only
        # between the two extremes of all the weight on one foot; beyond them (with a margin)
        # the wheel takes the rest of the moment while it can when balancing, else fx yields
        # (a push that spun the wheel up would start the flight with the wheel half full).
        rz2 = 2 * hip_z + pzl + pzr
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
        ctrl[1], ctrl[2] = push_torques(pxl, pzl, jxl, jzl, clamp(fx, mu * fz_l), fz_l)  # friction cone
        ctrl[3], ctrl[4] = push_torques(pxr, pzr, jxr, jzr, clamp(fx, mu * fz_r), fz_r)
    else:
        # One support point: the feet's moment is rz fx + offset_x fz, so the pitch moment sets
        # fx. With the wheel, fx may stray from that toward keeping the CoM over the foot by as
        # much as the wheel can make up within SINGLE_SUPPORT_WHEEL (N m) of torque.
        rz = hip_z - height
        fx_pitch = (moment - offset_x * fz) / rz
        if wheel_on:
            stray = SINGLE_SUPPORT_WHEEL / -rz
            fx = clamp(min(max(fx, fx_pitch - stray), fx_pitch + stray), mu * fz)
            wheel = wheel_torque_bound(wheel_speed, rz * fx + offset_x * fz - moment)
        else:
            fx = fx_pitch
        if both:
            ctrl[1], ctrl[2] = push_torques(pxl, pzl, jxl, jzl, clamp(fx / 2, mu * fz / 2), fz / 2)
            ctrl[3], ctrl[4] = push_torques(pxr, pzr, jxr, jzr, clamp(fx / 2, mu * fz / 2), fz / 2)
        else:
            # The free foot reaches a little below the stance foot to find the ground, gently: a
            # leg that keeps extending into the ground launches the robot in lunar gravity.
            half = 0.5 * p[P_SPREAD]
            reach = p[P_PUSH]
            gentle = REACH_FORCE * TOTAL_MASS * p[P_GRAVITY] * 0.5 * L2  # knee torque, ~0.5 L2 lever
            if on_l:
                ctrl[1], ctrl[2] = push_torques(pxl, pzl, jxl, jzl, clamp(fx, mu * fz), fz)
                ctrl[3], ctrl[4] = swing_torques(
                    pxr, pzr, qpos[Q_KNEE_R], qvel[Q_HIP_R], qvel[Q_KNEE_R], reach, -half, gentle
                )
            else:
                ctrl[3], ctrl[4] = push_torques(pxr, pzr, jxr, jzr, clamp(fx, mu * fz), fz)
                ctrl[1], ctrl[2] = swing_torques(
                    pxl, pzl, qpos[Q_KNEE_L], qvel[Q_HIP_L], qvel[Q_KNEE_L], reach, half, gentle
                )
    return wheel


class HopController:
    """The Python face of the kernel: parameters, phase, events. Gains may change between ticks."""

    def __init__(
        self,
        gains: Gains,
        gait: GaitParams,
        gravity: float,
        wheel: bool = True,
        x0: float = 0.0,
        z0: float = 0.0,
        dt: float = 0.001,
    ) -> None:
        self.mem = np.zeros(N_MEM)  # the kernel's memory; the three views below name its parts
        self.params, self.state, self.acc = self.mem[:N_PARAMS], self.mem[MEM_STATE:MEM_ACC], self.mem[MEM_ACC:]
        self.gains, self.gait, self.gravity, self.wheel_enabled = gains, gait, gravity, wheel
        self.params[P_X0], self.params[P_Z0], self.params[P_DT] = x0, z0, dt
        self._write_params()
        self.reset()

    def _write_params(self) -> None:
        p, g, gait = self.params, self.gains, self.gait
        p[P_KP], p[P_KI], p[P_KD] = g.kp, g.ki, g.kd
        p[P_GRAVITY], p[P_WHEEL_ON] = self.gravity, float(self.wheel_enabled)
        p[P_VZ_LIFTOFF] = math.sqrt(2.0 * self.gravity * gait.apex_height)  # v_z = sqrt(2 g h)
        p[P_FORWARD_SPEED], p[P_STAND], p[P_CROUCH] = gait.forward_speed, gait.stand_height, gait.crouch_height
        p[P_PUSH], p[P_FLIGHT_LENGTH], p[P_SPREAD] = gait.push_length, gait.flight_length, gait.foot_spread
        p[P_PLACEMENT], p[P_LEAN] = gait.placement_gain, gait.crouch_lean
        p[P_STANCE_TIME], p[P_FRICTION] = gait.stance_time, gait.friction

    def set_gains(self, gains: Gains) -> None:
        self.gains = gains
        self._write_params()

    def set_gravity(self, gravity: float) -> None:
        self.gravity = gravity
        self._write_params()

    def set_wheel(self, enabled: bool) -> None:
        self.wheel_enabled = enabled
        self._write_params()

    def reset(self, time: float = 0.0, standing: bool = True) -> None:
        """Start in stance (feet believed on the ground when `standing`)."""
        k = self.state
        k[:] = 0.0
        k[K_PHASE], k[K_PHASE_START], k[K_CLOCK] = STANCE, time, time
        k[K_CONTACT_L] = k[K_CONTACT_R] = 1.0 if standing else 0.0
        k[K_PENDING_L] = k[K_PENDING_R] = -1.0

    @property
    def phase(self) -> Phase:
        return Phase(int(self.state[K_PHASE]))

    @property
    def wheel_command(self) -> float:
        """Wheel torque asked this tick, N m."""
        return float(self.state[K_WHEEL_COMMAND])
