"""The 1 kHz control tick: advance the phase, write the actuator commands, accumulate the hop metrics.

One numba-compiled kernel reads MuJoCo's arrays in place and writes `data.ctrl` directly. In
plain Python the same logic cost ~25 us a tick, more than MuJoCo's step itself; compiled it
costs ~1 us. Set NUMBA_DISABLE_JIT=1 to step through it in a Python debugger.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from hopper.control.contact import debounce
from hopper.control.energy import spend
from hopper.control.legs import Leg, clamp, leg_angle, leg_state, swing_to_angle, swing_torques
from hopper.control.phases import FALL_HIP_HEIGHT, FALL_PITCH, FallCause, Phase
from hopper.control.sensing import delayed, sense
from hopper.control.stance import Body, stance
from hopper.control.wheel import wheel_ctrl, wheel_pid, wheel_torque_bound

LANDING, STANCE, CROUCH, PUSH, FLIGHT, FALLEN = (int(p) for p in Phase)
PITCH_LIMIT, HIP_HEIGHT = int(FallCause.PITCH_LIMIT), int(FallCause.HIP_HEIGHT)
LIFTOFF_CONFIRM_S = 0.01  # s both feet off after a push before the flight counts
BOUNCE_CONFIRM_S = 0.08  # s both feet off in any other ground phase before it is a flight
CAPTURE_SLACK = 0.03  # m beyond the outer foot that the capture point may be before a recovery hop
ASCENT_FRACTION = 0.3  # of the liftoff speed: a contact while rising faster than this is a graze
LIMP_DAMPING = 0.5  # N m s/rad on each leg joint between the end of the push and the liftoff
# A leg that starts a push within this of its push length (stretched down a crater wall) cannot
# push: it sits the push out and the other leg pushes alone. Ending the push when that leg is
# "done" would end it at once and leave the body on limp legs.
PUSH_MIN_STROKE = 0.03  # m
# A robot that keeps landing back where it was (a crater wall it cannot hop onto: the hop lands
# on the wall, the stance slides off it and a recovery hop takes it back) hops out harder: the
# forward speed and the apex gait.BOOST_SPEED and BOOST_APEX times (the apex within the legs' margin).
STALL_PROGRESS = 0.1  # m along the forward speed's direction: a liftoff beyond the furthest by this is progress
STALL_HOPS = 4  # liftoffs without progress before a hop is boosted
PUSH_ATTEMPTS = 2  # pushes that ended on the ground from the same feet before a recovery hop re-places them
# A leg sweep runs at constant speed between ramps of this share of its time: a steady reaction on
# the torso, its momentum above the wheel's capacity for most of the sweep (a minimum-jerk path
# peaks briefly and gives a sharper, shorter excursion for the same peak deviation).
SWEEP_RAMP = 0.25
WHEEL_FULL = 0.9  # of the no-load speed: the wheel has next to no torque left that way
# Event bits returned by the kernel.
EV_LIFTOFF, EV_TOUCHDOWN, EV_FALL, EV_APEX = 1, 2, 4, 8
# The flight's wheel law is a Python controller's this tick (m.external): the caller computes the
# torque and finishes the tick with finish_wheel (hopper.sim; hopper.controllers is the API).
EV_WHEEL = 16
RESPONSE_THRESHOLD = math.radians(0.25)  # rad: a smaller pitch starts no excursion (hopper.metrics)
SETTLE_BAND = math.radians(1.0)  # rad: settled within 1 deg


@njit(cache=True)
def enter(m, phase: int, time: float) -> None:  # noqa: ANN001 (a MEMORY record)
    m.phase, m.phase_start, m.push_done = phase, time, False
    if phase != PUSH and phase != FLIGHT:
        m.recovering = m.boost = False


@njit(cache=True)
def minimum_jerk(s: float) -> float:
    """The minimum-jerk path's share of the way at `s` of its time (clamped to [0, 1])."""
    s = min(max(s, 0.0), 1.0)
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


@njit(cache=True)
def trapezoid(s: float, ramp: float) -> float:
    """Share of the way at `s` of the time on a path whose speed ramps up linearly over `ramp` of
    the time, holds, and ramps down as long (0 < ramp <= 0.5)."""
    s = min(max(s, 0.0), 1.0)
    if s < ramp:
        done = 0.5 * s * s / ramp
    elif s > 1.0 - ramp:
        done = 1.0 - ramp - 0.5 * (1.0 - s) * (1.0 - s) / ramp
    else:
        done = s - 0.5 * ramp
    return done / (1.0 - ramp)


@njit(cache=True)
def captured(m, vx: float, hip_x: float, left: Leg, right: Leg) -> bool:  # noqa: ANN001
    """Whether the capture point (vx / w0 ahead of the CoM) lies over the feet on the ground.

    `hip_x` is the hip ahead of the CoM (m); the feet are measured from the hip.
    """
    front, back = -1e9, 1e9
    if left.on:
        front, back = max(front, hip_x + left.px), min(back, hip_x + left.px)
    if right.on:
        front, back = max(front, hip_x + right.px), min(back, hip_x + right.px)
    capture = vx * m.capture_time
    return back - CAPTURE_SLACK <= capture <= front + CAPTURE_SLACK


# A torso turning faster than this has been kicked: the wheel alone (about 20 N m) would let it
# turn a degree further before it stopped (sqrt(2 tau theta / I_torso), I_torso 0.116 kg m^2).
KICK_RATE = 2.5  # rad/s
# While a kicked torso still turns away, the legs' rate follows this times the share of its rate:
# the hips stay at their limit and stop it sooner. On the 0.7-capacity map 1.5 to 2 land every
# moment within 3.5 deg; 3 and more drive the legs to their stroke, and braking them there
# turns the torso back out.
KICK_BRAKE = 2.0


@njit(cache=True)
def share_attitude(m, pitch: float, rate: float, wheel_speed: float, kicked: bool) -> tuple[float, float, float]:  # noqa: ANN001
    """The legs' part in the flight attitude: (offset of their world angle, rad; of its rate, rad/s;
    how much shorter they reach for the landing, m).

    The legs are the other reaction mass (1.2 kg up to 1 m from the hip, twice the torso's
    inertia about the CoM). Their world angle follows leg_share times the torso's pitch error
    (and its rate): the hips turn them with the error, and their reaction turns the torso back,
    momentum-free, while the wheel takes the momentum; a kick's momentum goes into torso and legs
    together instead of the light torso alone. Beyond share_max the legs go back to holding the
    landing pose. A torso already turning back holds its legs shorter: the touchdown waits
    (a few tens of ms) for the error to close, instead of landing mid-correction. A torso still
    turning away with the wheel full reaches longer instead (a negative wait): the ground comes
    sooner, and the stance takes the momentum the wheel cannot. A `kicked` torso (turning faster
    than KICK_RATE) still turning away is braked harder (KICK_BRAKE).
    """
    share = m.leg_share * pitch
    wait = m.wait_gain * max(abs(pitch) - m.wait_from, 0.0)  # m
    if pitch * rate < 0.0:
        wait = min(wait, m.wait_max)
    elif abs(wheel_speed) > WHEEL_FULL * m.wheel_top:
        # The wheel is full and the torso still turns away: reach for the ground, which can take
        # the momentum, rather than turn on to the fall limit in the air.
        wait = -min(wait, m.push - m.flight_length)
    else:
        wait = 0.0
    if abs(share) >= m.share_max:
        return clamp(share, m.share_max), 0.0, min(wait, 0.0)
    # The swing servo already damps the hips' rate, i.e. holds the legs' world rate to the
    # torso's: a share of c adds (c - 1) times the torso's rate.
    gain = m.leg_share * (KICK_BRAKE if kicked and pitch * rate > 0.0 else 1.0)
    return share, (gain - 1.0) * rate, wait


@njit(cache=True)
def respond(m, time: float, torque: float, wheel_speed: float) -> None:  # noqa: ANN001 (a MEMORY record)
    """Accumulate one flight tick of the pitch response (hopper.metrics.ResponseMetrics defines it)."""
    pitch = m.pitch_true
    if m.acc_lobe == 0.0:
        if abs(pitch) > RESPONSE_THRESHOLD:
            m.acc_lobe = 1.0 if pitch > 0.0 else -1.0
            m.acc_first_peak = abs(pitch)
    elif m.acc_crossed == 0.0:
        along = m.acc_lobe * pitch
        if along <= 0.0:
            m.acc_crossed, m.acc_overshoot = 1.0, -along
        else:
            m.acc_first_peak = max(m.acc_first_peak, along)
    else:
        m.acc_overshoot = max(m.acc_overshoot, -m.acc_lobe * pitch)
    if abs(pitch) > SETTLE_BAND:
        m.acc_last_out = time
    m.acc_peak_torque = max(m.acc_peak_torque, abs(torque))
    m.acc_resp_wheel = max(m.acc_resp_wheel, abs(wheel_speed))


@njit(cache=True)
def command_wheel(m, ctrl: np.ndarray, wheel: float, wheel_speed: float) -> None:  # noqa: ANN001
    """Send `wheel` (N m, within the envelope) to the motor through the delay line."""
    if not m.wheel_on:
        wheel = 0.0
    m.wheel_command = wheel
    ctrl[m.a_wheel] = wheel_ctrl(m, delayed(m, wheel), wheel_speed)


@njit(cache=True)
def inject(m, law: float, wheel_speed: float) -> float:  # noqa: ANN001 (a MEMORY record)
    """The flight law's torque `law` (N m) plus this tick's injected torque, within the envelope."""
    m.law_command = law
    if m.inject_torque == 0.0:
        return law
    asked = law + m.inject_torque
    torque = wheel_torque_bound(m, wheel_speed, asked)
    m.saturated = m.saturated or torque != asked
    return torque


@njit(cache=True)
def finish_wheel(qvel: np.ndarray, ctrl: np.ndarray, mem: np.ndarray, command: float) -> float:
    """End a tick that returned EV_WHEEL: clamp an external law's `command` (N m) to the motor's
    envelope, mark saturation as wheel_pid does, add the injection and send it. Returns the torque
    sent (N m)."""
    m = mem[0]
    wheel_speed = qvel[m.v_wheel]
    torque = wheel_torque_bound(m, wheel_speed, command)
    m.saturated = torque != command
    torque = inject(m, torque, wheel_speed)
    command_wheel(m, ctrl, torque, wheel_speed)
    return torque


@njit(cache=True)
def control_tick(qpos: np.ndarray, qvel: np.ndarray, sensors: np.ndarray, ctrl: np.ndarray, mem: np.ndarray) -> int:
    """One tick on MjData's qpos, qvel, sensordata and ctrl and the MEMORY record `mem` (shape (1,)).

    Returns the EV_* bits of what happened. The kernel keeps its own copy of the clock,
    advanced exactly as mj_step advances data.time.
    """
    m = mem[0]
    time, dt = m.clock, m.dt
    pitch, rate = sense(m, qpos, sensors)  # the truth, or the IMU's estimate (SimConfig.sensing)
    m.law_pitch = pitch - m.pitch_ref - m.inject_ref  # what the flight's attitude law holds to zero
    vx, vz, wheel_speed = qvel[m.v_x], qvel[m.v_z], qvel[m.v_wheel]
    on_l, m.pending_l = debounce(sensors[m.s_foot_l], time, m.contact_l, m.pending_l, m.contact_on, m.contact_off)
    on_r, m.pending_r = debounce(sensors[m.s_foot_r], time, m.contact_r, m.pending_r, m.contact_on, m.contact_off)
    m.contact_l, m.contact_r = on_l, on_r
    left = leg_state(m, pitch, qpos[m.q_hip_l], qpos[m.q_knee_l], qvel[m.v_hip_l], qvel[m.v_knee_l], on_l)
    right = leg_state(m, pitch, qpos[m.q_hip_r], qpos[m.q_knee_r], qvel[m.v_hip_r], qvel[m.v_knee_r], on_r)
    contact = on_l or on_r
    # The whole robot's CoM relative to the torso's (the legs are 15 % of the mass).
    com_dx = sensors[m.s_com] - (qpos[m.q_x] + m.x0)
    com_dz = sensors[m.s_com + 2] - (qpos[m.q_z] + m.z0)
    com_vz = sensors[m.s_com_vel + 2]  # ballistic in flight, unlike the torso's (the legs swing)
    lean = m.hip_z * math.sin(pitch)  # hip ahead of the torso's CoM
    hip_x, hip_z = lean - com_dx, m.hip_z * math.cos(pitch) - com_dz  # hip relative to the robot's CoM
    # Support geometry: hip above the feet' centres, the robot's CoM ahead of the feet's midpoint.
    if on_l and on_r:
        height, px = -0.5 * (left.pz + right.pz), 0.5 * (left.px + right.px)
    elif contact:
        height, px = (-left.pz, left.px) if on_l else (-right.pz, right.px)
    else:
        height, px = 0.0, 0.0
    if contact:
        m.last_contact = time
    if on_l and on_r:
        m.last_both = time
    offset_x = com_dx - (lean + px)

    # -- phase transitions --
    events = 0
    phase = m.phase
    elapsed = time - m.phase_start
    if phase != FALLEN:
        if not -FALL_PITCH < pitch < FALL_PITCH:
            enter(m, FALLEN, time)
            m.fall_cause, m.fall_height = PITCH_LIMIT, height
            events |= EV_FALL
        elif m.on_stand:
            # The stand holds the torso up: its attitude loop is the flight's, for as long as it runs.
            if phase != FLIGHT:
                enter(m, FLIGHT, time)
                m.integral = 0.0
                m.land_l = m.land_r = m.flight_length
        elif contact and phase != FLIGHT and height < FALL_HIP_HEIGHT:
            enter(m, FALLEN, time)
            m.fall_cause, m.fall_height = HIP_HEIGHT, height
            events |= EV_FALL
        elif phase == FLIGHT:
            # A foot that grazes a crater rim on the way up is not a landing: the body is still
            # rising, the legs are tucked and keep swinging, the wheel keeps the attitude.
            if contact and com_vz < ASCENT_FRACTION * m.vz_liftoff:
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
                m.failed_pushes = 0
                ahead = (qpos[m.q_x] - m.progress_x) * (1.0 if m.forward_speed >= 0.0 else -1.0)
                if ahead > STALL_PROGRESS:
                    m.progress_x, m.stalled = qpos[m.q_x], 0
                else:
                    m.stalled += 1
                m.land_l = m.land_r = m.flight_length  # until the apex plans the landing
                m.sweep_from_l, m.sweep_from_r = leg_angle(left), leg_angle(right)  # a sweep starts here
                m.sweep_len_l, m.sweep_len_r = math.hypot(left.px, left.pz), math.hypot(right.px, right.pz)
                events |= EV_LIFTOFF
        elif (
            phase in (STANCE, CROUCH)
            and (on_l and on_r or time - m.last_both > m.landing_min)
            and not captured(m, vx, hip_x, left, right)
        ):
            # A push carried the capture point off the feet, or the robot stands on one foot (the
            # other, given a landing's time to find the ground, is over a crater) and topples off
            # it: hop to catch it (Raibert's recovery; in low gravity a step is a hop anyway).
            # The landing places the feet around it.
            enter(m, PUSH, time)
            m.recovering = True
        elif phase == LANDING:
            if elapsed > m.landing_min and abs(vz) < 1.25 * m.settled_speed:
                enter(m, STANCE, time)
        elif phase == STANCE:
            slow = m.settled_speed
            settled = abs(vx) < slow and abs(vz) < slow and abs(pitch) < 0.05 and abs(rate) < 0.15
            # No push with a wheel that has no room left for the flight: wait for the spin-down.
            ready = abs(wheel_speed) < m.wheel_ready or elapsed > m.stance_max + m.wheel_wait
            if elapsed > m.stance_min and ready and (settled or elapsed > m.stance_max):
                enter(m, CROUCH, time)
        elif phase == CROUCH:
            # Push off both feet only: one foot (the other over a crater) cannot push through
            # the CoM and would start the flight spinning. Without both, stand and settle again.
            both = on_l and on_r
            loaded = abs(height - m.crouch) < 0.03 and abs(offset_x - m.lean) < 0.04 and elapsed > m.crouch_min
            if both and (loaded or elapsed > m.crouch_max):
                enter(m, PUSH, time)
                # The same push failed from these feet before: a small recovery hop re-places them
                # (a foot that unloads as the push begins would abort every push from here on).
                m.recovering = m.failed_pushes >= PUSH_ATTEMPTS
                m.boost = not m.recovering and m.stalled >= STALL_HOPS and m.forward_speed != 0.0
            elif elapsed > m.crouch_max:
                enter(m, STANCE, time)
        elif phase == PUSH and (
            elapsed > m.push_max
            or (on_l != on_r and not m.push_done and not m.recovering and vz < 0.5 * m.vz_liftoff)
            or (m.push_done and vz < 0.0)
        ):
            # The feet never left, or one lost the ground early in the push (a rim crumbling
            # under it): stand and try again rather than leave spinning off one foot. A push that
            # ran out of leg with the body sinking (a leg already long over a crater floor) has
            # failed too: limp legs would let the body fall onto the feet.
            if not m.recovering:
                m.failed_pushes += 1
            enter(m, STANCE, time)
    if m.phase == PUSH and phase != PUSH:
        m.push_skip_l = left.on and math.hypot(left.px, left.pz) > m.push - PUSH_MIN_STROKE
        m.push_skip_r = right.on and math.hypot(right.px, right.pz) > m.push - PUSH_MIN_STROKE
    phase = m.phase

    # -- actuation --
    wheel = 0.0
    if phase == PUSH and not contact and not m.push_done:
        # A foot bouncing off the ground during the push, for less than the liftoff's confirmation:
        # the legs keep pushing rather than swing for a landing between two contacts.
        hl, kl, hr, kr = ctrl[m.a_hip_l], ctrl[m.a_knee_l], ctrl[m.a_hip_r], ctrl[m.a_knee_r]
    elif phase in (FLIGHT, FALLEN) or not contact:
        # Legs swing to the landing pose: the feet's midpoint goes where the capture point lands
        # inside the front half of the support (Raibert's placement, from the linear inverted
        # pendulum), measured from the hip.
        capture = vx * m.capture_time
        mid = capture - min(max(capture, -m.capture_margin), m.capture_margin)
        mid = min(max(mid, -m.reach_limit), m.reach_limit)
        mid += com_dx - lean
        m.feet_mid = mid  # the landing planner reads where the swing puts the feet
        half = 0.5 * m.spread
        # Tucked while rising, for clearance over rims ahead; reaching for the landing after the apex.
        tucked = phase == FLIGHT and com_vz >= 0.0 and not m.on_stand
        if phase == FLIGHT and m.sweep_angle > 0.0 and not m.on_stand:
            # The paper's flight: both legs swing back hard from their liftoff angle (world frame) at
            # their liftoff length (extending them could drive a foot back into the ground), then
            # forward to the landing pose along a minimum-jerk path. The torso takes the legs'
            # reaction; the wheel must take it from the torso.
            scale, flown = m.swing_scale * m.sweep_scale, time - m.phase_start
            if flown < m.sweep_time:
                s = trapezoid(flown / m.sweep_time, SWEEP_RAMP)
                hl, kl = swing_to_angle(m, left, m.sweep_len_l, m.sweep_from_l + m.sweep_angle * s, scale)
                hr, kr = swing_to_angle(m, right, m.sweep_len_r, m.sweep_from_r + m.sweep_angle * s, scale)
            else:
                s = minimum_jerk((flown - m.sweep_time) / m.sweep_return if m.sweep_return > 0.0 else 1.0)
                held_l, held_r = m.sweep_from_l + m.sweep_angle, m.sweep_from_r + m.sweep_angle
                land_l = -math.asin(clamp((mid + half) / m.land_l, 0.9))
                land_r = -math.asin(clamp((mid - half) / m.land_r, 0.9))
                hl, kl = swing_to_angle(m, left, m.land_l, held_l + (land_l - held_l) * s, scale)
                hr, kr = swing_to_angle(m, right, m.land_r, held_r + (land_r - held_r) * s, scale)
        else:
            kicked = abs(rate) > KICK_RATE
            share, share_rate, wait = 0.0, 0.0, 0.0
            if phase == FLIGHT:
                share, share_rate, wait = share_attitude(m, pitch, rate, wheel_speed, kicked)
            len_l, len_r = (m.tuck_length, m.tuck_length) if tucked else (m.land_l - wait, m.land_r - wait)
            hl, kl = swing_torques(m, left, len_l, mid + half, m.swing_scale, share, share_rate, rigid=kicked)
            hr, kr = swing_torques(m, right, len_r, mid - half, m.swing_scale, share, share_rate, rigid=kicked)
        if phase == FLIGHT and not m.external:
            wheel = inject(m, wheel_pid(m, m.law_pitch, rate, wheel_speed), wheel_speed)
    elif m.push_done:
        # The push is over but a foot still touches: limp legs until it leaves, since swinging
        # them against the ground now would push the body into a spin; the wheel holds the torso.
        hl, kl = -LIMP_DAMPING * left.hip_rate, -LIMP_DAMPING * left.knee_rate
        hr, kr = -LIMP_DAMPING * right.hip_rate, -LIMP_DAMPING * right.knee_rate
        wheel = wheel_torque_bound(m, wheel_speed, m.hold_kp * pitch + m.hold_kd * rate)
    else:
        body = Body(pitch, rate, vx, vz, wheel_speed, height, offset_x, sensors[m.s_angmom], hip_x, hip_z)
        skip_l, skip_r = phase == PUSH and m.push_skip_l, phase == PUSH and m.push_skip_r
        if skip_l != skip_r:  # the other leg pushes alone; the stretched one rests on the ground, limp
            rest_l = Leg(left.px, left.pz, left.jx, left.jz, left.knee, left.hip_rate, left.knee_rate, False)
            rest_r = Leg(right.px, right.pz, right.jx, right.jz, right.knee, right.hip_rate, right.knee_rate, False)
            wheel, hl, kl, hr, kr = stance(m, phase, body, left if skip_r else rest_l, right if skip_l else rest_r)
            if skip_l:
                hl, kl = -LIMP_DAMPING * left.hip_rate, -LIMP_DAMPING * left.knee_rate
            else:
                hr, kr = -LIMP_DAMPING * right.hip_rate, -LIMP_DAMPING * right.knee_rate
        else:
            wheel, hl, kl, hr, kr = stance(m, phase, body, left, right)
    if m.legs_locked:  # the stand holds them: a torque would only load its constraints
        hl = kl = hr = kr = 0.0
    ctrl[m.a_hip_l], ctrl[m.a_knee_l], ctrl[m.a_hip_r], ctrl[m.a_knee_r] = hl, kl, hr, kr
    if phase == FLIGHT and m.external:
        events |= EV_WHEEL  # its obs reads m.pitch_est and m.rate_est, which sense() wrote
    else:
        command_wheel(m, ctrl, wheel, wheel_speed)

    # -- metrics of the hop in progress --
    torque = sensors[m.s_wheel_torque] * m.wheel_gear  # motor-side actuator force through the gear
    if torque >= m.saturation_torque or torque <= -m.saturation_torque:
        m.acc_saturation += dt
    m.acc_peak_wheel = max(m.acc_peak_wheel, abs(wheel_speed))
    spend(m, qvel, sensors)  # every tick: the energy of a hop covers its ground phase and its flight
    if phase == FLIGHT:
        m.acc_peak_pitch = max(m.acc_peak_pitch, abs(m.pitch_true))  # the metrics are of the truth
        m.acc_rate_sq += m.rate_true * m.rate_true
        m.acc_flight_ticks += 1.0
        m.acc_apex_z = max(m.acc_apex_z, qpos[m.q_z] + m.z0)
        respond(m, time, torque, wheel_speed)
        if m.prev_vz > 0.0 >= com_vz and not m.on_stand:
            events |= EV_APEX
    m.prev_vz = com_vz
    m.clock = time + dt
    return events
