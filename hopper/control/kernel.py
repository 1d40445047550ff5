"""The 1 kHz control tick: advance the phase, write the actuator commands, accumulate the hop metrics.

One numba-compiled kernel reads MuJoCo's arrays in place and writes `data.ctrl` directly. In
plain Python the same logic cost ~25 us a tick, more than MuJoCo's step itself; compiled it
costs ~1 us. Set NUMBA_DISABLE_JIT=1 to step through it in a Python debugger.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from hopper.config import HIP_OFFSET_Z
from hopper.control.contact import debounce
from hopper.control.legs import leg_state, swing_torques
from hopper.control.phases import FALL_HIP_HEIGHT, FALL_PITCH, FallCause, Phase
from hopper.control.sensing import delayed, sense
from hopper.control.stance import Body, stance
from hopper.control.wheel import SATURATION_TORQUE, wheel_ctrl, wheel_pid

LANDING, STANCE, CROUCH, PUSH, FLIGHT, FALLEN = (int(p) for p in Phase)
PITCH_LIMIT, HIP_HEIGHT = int(FallCause.PITCH_LIMIT), int(FallCause.HIP_HEIGHT)
# Phase timing, s.
LANDING_MIN_S, STANCE_MAX_S, CROUCH_MIN_S, CROUCH_MAX_S, PUSH_MAX_S = 0.1, 2.0, 0.15, 1.2, 1.0
LIFTOFF_CONFIRM_S = 0.01  # s both feet off after a push before the flight counts
BOUNCE_CONFIRM_S = 0.08  # s both feet off in any other ground phase before it is a flight
# Event bits returned by the kernel.
EV_LIFTOFF, EV_TOUCHDOWN, EV_FALL, EV_APEX = 1, 2, 4, 8


@njit(cache=True)
def enter(m, phase: int, time: float) -> None:  # noqa: ANN001 (a MEMORY record)
    m.phase, m.phase_start, m.push_done = phase, time, False


@njit(cache=True)
def control_tick(qpos: np.ndarray, qvel: np.ndarray, sensors: np.ndarray, ctrl: np.ndarray, mem: np.ndarray) -> int:
    """One tick on MjData's qpos, qvel, sensordata and ctrl and the MEMORY record `mem` (shape (1,)).

    Returns the EV_* bits of what happened. The kernel keeps its own copy of the clock,
    advanced exactly as mj_step advances data.time.
    """
    m = mem[0]
    time, dt = m.clock, m.dt
    pitch, rate = sense(m, qpos, sensors)  # the truth, or the IMU's estimate (SimConfig.sensing)
    vx, vz, wheel_speed = qvel[m.v_x], qvel[m.v_z], qvel[m.v_wheel]
    on_l, m.pending_l = debounce(sensors[m.s_foot_l], time, m.contact_l, m.pending_l)
    on_r, m.pending_r = debounce(sensors[m.s_foot_r], time, m.contact_r, m.pending_r)
    m.contact_l, m.contact_r = on_l, on_r
    left = leg_state(pitch, qpos[m.q_hip_l], qpos[m.q_knee_l], qvel[m.v_hip_l], qvel[m.v_knee_l], on_l)
    right = leg_state(pitch, qpos[m.q_hip_r], qpos[m.q_knee_r], qvel[m.v_hip_r], qvel[m.v_knee_r], on_r)
    contact = on_l or on_r
    # Support geometry: hip above the feet' centres, torso CoM ahead of the feet's midpoint.
    if on_l and on_r:
        height, px = -0.5 * (left.pz + right.pz), 0.5 * (left.px + right.px)
    elif contact:
        height, px = (-left.pz, left.px) if on_l else (-right.pz, right.px)
    else:
        height, px = 0.0, 0.0
    if contact:
        m.last_contact = time
    offset_x = -(HIP_OFFSET_Z * math.sin(pitch) + px)

    # -- phase transitions --
    events = 0
    phase = m.phase
    elapsed = time - m.phase_start
    if phase != FALLEN:
        if not -FALL_PITCH < pitch < FALL_PITCH:
            enter(m, FALLEN, time)
            m.fall_cause, m.fall_height = PITCH_LIMIT, height
            events |= EV_FALL
        elif contact and phase != FLIGHT and height < FALL_HIP_HEIGHT:
            enter(m, FALLEN, time)
            m.fall_cause, m.fall_height = HIP_HEIGHT, height
            events |= EV_FALL
        elif phase == FLIGHT:
            if contact:
                enter(m, LANDING, time)
                events |= EV_TOUCHDOWN
        elif not contact:
            # Liftoff once both feet have been off for a while: a foot skipping over a crater
            # rim for a few ms during the push is not a hop, nor is a stumble off a rim while
            # standing unless it lasts long enough to need the wheel's flight control.
            confirm = LIFTOFF_CONFIRM_S if phase == PUSH else BOUNCE_CONFIRM_S
            if time - m.last_contact >= confirm:
                enter(m, FLIGHT, time)
                m.integral = 0.0  # integral reset at liftoff
                events |= EV_LIFTOFF
        elif phase == LANDING:
            if elapsed > LANDING_MIN_S and -0.1 < vz < 0.1:
                enter(m, STANCE, time)
        elif phase == STANCE:
            settled = abs(vx) < 0.08 and abs(vz) < 0.08 and abs(pitch) < 0.05 and abs(rate) < 0.15
            if elapsed > m.stance_time and (settled or elapsed > STANCE_MAX_S):
                enter(m, CROUCH, time)
        elif phase == CROUCH:
            loaded = abs(height - m.crouch) < 0.03 and abs(offset_x - m.lean) < 0.04 and elapsed > CROUCH_MIN_S
            if loaded or elapsed > CROUCH_MAX_S:
                enter(m, PUSH, time)
        elif phase == PUSH and m.push_done and elapsed > PUSH_MAX_S:
            enter(m, STANCE, time)  # the feet never left: stand and try again
    phase = m.phase

    # -- actuation --
    wheel = 0.0
    if phase in (FLIGHT, FALLEN) or m.push_done or not contact:
        # Legs swing to the landing pose, feet placed ahead by the Raibert term.
        mid = m.placement * vx
        half = 0.5 * m.spread
        hl, kl = swing_torques(left, m.flight_length, mid + half)
        hr, kr = swing_torques(right, m.flight_length, mid - half)
        if phase == FLIGHT:
            wheel = wheel_pid(m, pitch, rate, wheel_speed)
    else:
        body = Body(pitch, rate, vx, vz, wheel_speed, height, offset_x)
        wheel, hl, kl, hr, kr = stance(m, phase, body, left, right)
    ctrl[m.a_hip_l], ctrl[m.a_knee_l], ctrl[m.a_hip_r], ctrl[m.a_knee_r] = hl, kl, hr, kr
    if not m.wheel_on:
        wheel = 0.0
    m.wheel_command = wheel
    ctrl[m.a_wheel] = wheel_ctrl(delayed(m, wheel), wheel_speed)

    # -- metrics of the hop in progress --
    torque = sensors[m.s_wheel_torque] * m.wheel_gear  # motor-side actuator force through the gear
    if torque >= SATURATION_TORQUE or torque <= -SATURATION_TORQUE:
        m.acc_saturation += dt
    m.acc_peak_wheel = max(m.acc_peak_wheel, abs(wheel_speed))
    if phase == FLIGHT:
        m.acc_peak_pitch = max(m.acc_peak_pitch, abs(m.pitch_true))  # the metrics are of the truth
        m.acc_rate_sq += m.rate_true * m.rate_true
        m.acc_flight_ticks += 1.0
        m.acc_apex_z = max(m.acc_apex_z, qpos[m.q_z] + m.z0)
        if m.prev_vz > 0.0 >= vz:
            events |= EV_APEX
    m.prev_vz = vz
    m.clock = time + dt
    return events
