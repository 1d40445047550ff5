"""Hop controller: wheel PID in flight, impedance / virtual-model legs on the ground, phase logic.

Pure Python floats on purpose: this runs every 1 ms, and scalar numpy calls would cost more than
MuJoCo's own step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from hopper.config import (
    FOOT_RADIUS,
    HIP_OFFSET_Z,
    LEG_TORQUE_LIMIT,
    SATURATION_FRACTION,
    SHANK_LENGTH,
    THIGH_LENGTH,
    TOTAL_MASS,
    WHEEL_INERTIA,
    WHEEL_NO_LOAD_SPEED,
    WHEEL_TORQUE_LIMIT,
    GaitParams,
    Gains,
)
from hopper.model import Physics
from hopper.phases import GROUND_PHASES, ContactDetector, Phase

L1, L2 = THIGH_LENGTH, SHANK_LENGTH
WHEEL_DAMPING = WHEEL_TORQUE_LIMIT / WHEEL_NO_LOAD_SPEED  # N m s/rad, back-EMF slope at the wheel

# Stance: virtual model gains, as natural frequency (rad/s) and damping ratio on the torso.
STANCE_HEIGHT_WN, STANCE_HEIGHT_ZETA = 5.0, 1.0
STANCE_X_WN, STANCE_X_ZETA = 3.0, 1.0
STANCE_PITCH_WN, STANCE_PITCH_ZETA = 8.0, 1.0
STANCE_PITCH_INERTIA = 0.5  # kg m^2, I_locked - I_w (PHYSICS.md)
LANDING_DAMPING = 6.0  # 1/s, vertical velocity damping while absorbing the impact
DESAT_TIME = 0.25  # s, time constant of the stance wheel spin-down
PUSH_MAX_ACCEL = 8.0  # m/s^2, cap on the push-off acceleration
PUSH_X_GAIN = 6.0  # 1/s, horizontal velocity tracking during the push
# Flight: legs swing as a virtual leg (length, angle) with PD gains about the hip.
SWING_K, SWING_D = 15.0, 2.5  # N m/rad, N m s/rad  (wn ~ 10 rad/s for ~0.15 kg m^2)
LENGTH_K, LENGTH_D = 300.0, 12.0  # N/m, N s/m
# Fall: beyond this the body cannot be recovered by the legs.
FALL_PITCH = math.radians(60.0)
FALL_HIP_HEIGHT = 0.35  # m, hip above the feet in stance


def wheel_ctrl(torque: float, wheel_speed: float) -> float:
    """Normalised motor voltage in [-1, 1] that yields `torque` (N m at the wheel) at `wheel_speed`.

    Inverts the model's DC motor: torque = limit * u - damping * speed, clamped to the limit.
    """
    u = (torque + WHEEL_DAMPING * wheel_speed) / WHEEL_TORQUE_LIMIT
    return -1.0 if u < -1.0 else 1.0 if u > 1.0 else u


def wheel_torque_bounds(wheel_speed: float) -> tuple[float, float]:
    """The torque-speed envelope (N m) at `wheel_speed` (rad/s, relative to the torso)."""
    back_emf = WHEEL_DAMPING * wheel_speed
    low = max(-WHEEL_TORQUE_LIMIT, -WHEEL_TORQUE_LIMIT - back_emf)
    high = min(WHEEL_TORQUE_LIMIT, WHEEL_TORQUE_LIMIT - back_emf)
    return low, high


class WheelPID:
    """The paper's flight law on the measured pitch and rate, with anti-windup.

    Sign: the paper's tau_w is the torque on the torso; MuJoCo's motor torque acts on the wheel
    and the torso takes its reaction, so the motor command is the negated law:
    motor torque = kp theta + kd theta_dot + ki int(theta).
    """

    __slots__ = ("gains", "integral", "saturated")

    def __init__(self, gains: Gains) -> None:
        self.gains = gains
        self.integral = 0.0
        self.saturated = False

    def reset(self) -> None:
        self.integral, self.saturated = 0.0, False

    def update(self, pitch: float, pitch_rate: float, wheel_speed: float, dt: float) -> float:
        """Motor torque (N m at the wheel), clamped to the torque-speed envelope."""
        g = self.gains
        # D on the measured rate: no derivative kick when the setpoint or gains change.
        command = g.kp * pitch + g.kd * pitch_rate + g.ki * self.integral
        low, high = wheel_torque_bounds(wheel_speed)
        self.saturated = command <= low or command >= high
        if not self.saturated:  # conditional integration: no windup while saturated
            self.integral += pitch * dt
        return low if command < low else high if command > high else command


@dataclass
class Leg:
    """One leg's kinematics in the sagittal plane, world axes, relative to the hip."""

    px: float = 0.0  # foot centre relative to the hip, m
    pz: float = 0.0
    j_bx: float = 0.0  # d(px)/d(knee); d(px)/d(hip) = pz, d(pz)/d(hip) = -px
    j_bz: float = 0.0  # d(pz)/d(knee)
    length: float = 0.0  # hip-to-foot distance, m
    angle: float = 0.0  # world angle of the virtual leg (0 = straight down, + = foot behind)
    contact: ContactDetector = field(default_factory=ContactDetector)

    def update(self, pitch: float, hip: float, knee: float) -> None:
        a1 = pitch + hip
        a2 = a1 + knee
        s1, c1, s2, c2 = math.sin(a1), math.cos(a1), math.sin(a2), math.cos(a2)
        self.px = -L1 * s1 - L2 * s2
        self.pz = -L1 * c1 - L2 * c2
        self.j_bx, self.j_bz = -L2 * c2, L2 * s2
        self.length = math.hypot(self.px, self.pz)
        self.angle = math.atan2(-self.px, -self.pz)

    def force_torques(self, fx: float, fz: float) -> tuple[float, float]:
        """Hip and knee torques that make the ground push on the foot with (fx, fz): tau = -J^T f."""
        return -(self.pz * fx - self.px * fz), -(self.j_bx * fx + self.j_bz * fz)

    def swing_torques(
        self, length: float, angle: float, hip_rate: float, knee_rate: float, knee: float
    ) -> tuple[float, float]:
        """PD on the virtual leg (length, world angle); damping on joint rates, not the torso's."""
        # For equal links, length = 2 L cos(knee / 2) and the leg bisects the knee.
        dl_dknee = -L1 * math.sin(knee / 2)
        torque_angle = SWING_K * (angle - self.angle) - SWING_D * (hip_rate + knee_rate / 2)
        force = LENGTH_K * (length - self.length) - LENGTH_D * dl_dknee * knee_rate
        return torque_angle, torque_angle / 2 + force * dl_dknee


def clamp(value: float, limit: float) -> float:
    return -limit if value < -limit else limit if value > limit else value


class HopController:
    """Runs the hop cycle one control tick at a time; gains may change between ticks."""

    def __init__(self, gains: Gains, gait: GaitParams, gravity: float, wheel: bool = True) -> None:
        self.gains, self.gait, self.gravity, self.wheel_enabled = gains, gait, gravity, wheel
        self.pid = WheelPID(gains)
        self.left, self.right = Leg(), Leg()
        self.phase = Phase.STANCE
        self.phase_start = 0.0
        self.push_done = False
        self.wheel_command = 0.0  # N m at the wheel, what was asked this tick
        self.ctrl = [0.0] * 5  # wheel, hip_L, knee_L, hip_R, knee_R
        self.events: list[tuple[str, float]] = []  # (kind, time), drained by the simulation

    def set_gains(self, gains: Gains) -> None:
        self.gains = gains
        self.pid.gains = gains

    def reset(self, time: float = 0.0, standing: bool = True) -> None:
        self.pid.reset()
        self.left.contact.reset(standing)
        self.right.contact.reset(standing)
        self.phase, self.phase_start, self.push_done = Phase.STANCE, time, False
        self.events.clear()

    @property
    def liftoff_speed(self) -> float:
        """Vertical speed at liftoff for the apex height: v_z = sqrt(2 g h)."""
        return math.sqrt(2.0 * self.gravity * self.gait.apex_height)

    def _enter(self, phase: Phase, time: float) -> None:
        self.phase, self.phase_start = phase, time

    def update(self, s: Physics, dt: float) -> list[float]:
        """One control tick: read `s`, advance the phase, return ctrl for the 5 actuators."""
        t = s.time
        self.left.update(s.pitch, s.hip_L, s.knee_L)
        self.right.update(s.pitch, s.hip_R, s.knee_R)
        on_l = self.left.contact.update(s.foot_force_L, t)
        on_r = self.right.contact.update(s.foot_force_R, t)
        self._advance(s, t, on_l or on_r)

        if self.phase is Phase.FLIGHT or self.phase is Phase.FALLEN or (self.phase is Phase.PUSH and self.push_done):
            wheel = self._flight(s, dt)
        else:
            wheel = self._stance(s, t, on_l, on_r)
        if not self.wheel_enabled:
            wheel = 0.0
        self.wheel_command = wheel
        self.ctrl[0] = wheel_ctrl(wheel, s.wheel_speed)
        return self.ctrl

    def _advance(self, s: Physics, t: float, contact: bool) -> None:
        """Phase transitions; events are queued for the simulation to stamp and publish."""
        phase, elapsed, gait = self.phase, t - self.phase_start, self.gait
        if phase is Phase.FALLEN:
            return
        if abs(s.pitch) > FALL_PITCH:
            self._enter(Phase.FALLEN, t)
            self.events.append(("fall", t))
            return
        if phase in GROUND_PHASES and contact:
            legs = [leg for leg in (self.left, self.right) if leg.contact.on]
            height = -sum(leg.pz for leg in legs) / len(legs)
            if height < FALL_HIP_HEIGHT:
                self._enter(Phase.FALLEN, t)
                self.events.append(("fall", t))
                return
        if phase is Phase.FLIGHT:
            if contact:
                self._enter(Phase.LANDING, t)
                self.events.append(("touchdown", t))
            return
        if not contact and (phase is Phase.PUSH or elapsed > 0.05):
            # Feet off the ground: liftoff (or a bounce off a crater rim, also ballistic).
            self._enter(Phase.FLIGHT, t)
            self.push_done = False
            self.pid.reset()  # integral reset at liftoff
            self.events.append(("liftoff", t))
            return
        if phase is Phase.LANDING and elapsed > 0.1 and abs(s.vz) < 0.1:
            self._enter(Phase.STANCE, t)
        elif phase is Phase.STANCE and elapsed > gait.stance_time:
            settled = abs(s.vx) < 0.08 and abs(s.vz) < 0.08 and abs(s.pitch) < 0.05 and abs(s.pitch_rate) < 0.15
            if settled or elapsed > 2.0:
                self._enter(Phase.CROUCH, t)
        elif phase is Phase.CROUCH:
            height = -(self.left.pz + self.right.pz) / 2
            if (abs(height - gait.crouch_height) < 0.02 and abs(s.vz) < 0.05 and elapsed > 0.15) or elapsed > 1.0:
                self._enter(Phase.PUSH, t)
                self.push_done = False
        elif phase is Phase.PUSH and self.push_done and elapsed > 1.0:
            self._enter(Phase.STANCE, t)  # the feet never left: stand and try again

    def _flight(self, s: Physics, dt: float) -> float:
        """Legs swing to the landing pose; the wheel PID holds the pitch. Returns wheel torque."""
        gait, ctrl = self.gait, self.ctrl
        mid = gait.placement_gain * s.vx
        length = gait.flight_length
        for i, (leg, offset, hip, knee, hip_rate, knee_rate) in enumerate(
            (
                (self.left, gait.foot_spread / 2, s.hip_L, s.knee_L, s.hip_L_rate, s.knee_L_rate),
                (self.right, -gait.foot_spread / 2, s.hip_R, s.knee_R, s.hip_R_rate, s.knee_R_rate),
            )
        ):
            # Foot ahead of the hip by x: world angle -asin(x / length).
            angle = -math.asin(clamp((mid + offset) / length, 0.9))
            tau_hip, tau_knee = leg.swing_torques(length, angle, hip_rate, knee_rate, knee)
            ctrl[1 + 2 * i] = clamp(tau_hip, LEG_TORQUE_LIMIT)
            ctrl[2 + 2 * i] = clamp(tau_knee, LEG_TORQUE_LIMIT)
        if self.phase is Phase.FALLEN:
            return 0.0
        return self.pid.update(s.pitch, s.pitch_rate, s.wheel_speed, dt)

    def _stance(self, s: Physics, t: float, on_l: bool, on_r: bool) -> float:
        """Virtual model control of the torso through the feet on the ground. Returns wheel torque."""
        gait, g, m = self.gait, self.gravity, TOTAL_MASS
        legs = [leg for leg, on in ((self.left, on_l), (self.right, on_r)) if on]
        if not legs:  # touchdown not yet debounced on either foot: keep the flight posture
            return self._flight(s, 0.0)
        height = -sum(leg.pz for leg in legs) / len(legs)  # hip above the feet' centres
        # Torso CoM relative to the feet midpoint, horizontally (hip is below the CoM).
        hip_x = HIP_OFFSET_Z * math.sin(s.pitch)
        offset_x = -(hip_x + sum(leg.px for leg in legs) / len(legs))

        kz, dz = STANCE_HEIGHT_WN**2, 2 * STANCE_HEIGHT_ZETA * STANCE_HEIGHT_WN
        kx, dx = STANCE_X_WN**2, 2 * STANCE_X_ZETA * STANCE_X_WN
        phase = self.phase
        if phase is Phase.LANDING:
            az = kz * (gait.stand_height - height) - LANDING_DAMPING * s.vz
            ax = -dx * s.vx
        elif phase is Phase.PUSH:
            vz_lo = self.liftoff_speed
            remaining = max(gait.push_length - height, 0.02)
            az = min(max((vz_lo * vz_lo - s.vz * abs(s.vz)) / (2 * remaining), 0.0), PUSH_MAX_ACCEL)
            ax = clamp(PUSH_X_GAIN * (gait.forward_speed - s.vx), 3.0)
            if s.vz >= vz_lo or height >= gait.push_length:
                self.push_done = True
        else:
            target = gait.crouch_height if phase is Phase.CROUCH else gait.stand_height
            # Crouch leaning ahead of the feet midpoint: the push's ground force must point from the
            # (rear) feet through the CoM, so the lean sets how much forward speed it can add.
            lean = gait.crouch_lean if phase is Phase.CROUCH else 0.0
            az = kz * (target - height) - dz * s.vz
            ax = kx * (lean - offset_x) - dx * s.vx
        fz_total = max(m * (g + az), 0.0)
        fx_total = m * ax

        # Wheel: spin down (desaturate); the legs take its reaction through the ground.
        wheel = 0.0
        if self.wheel_enabled:
            low, high = wheel_torque_bounds(s.wheel_speed)
            wheel = min(max(-WHEEL_INERTIA * s.wheel_speed / DESAT_TIME, low), high)
        kp_s = STANCE_PITCH_INERTIA * STANCE_PITCH_WN**2
        kd_s = 2 * STANCE_PITCH_ZETA * STANCE_PITCH_WN * STANCE_PITCH_INERTIA
        moment = -kp_s * s.pitch - kd_s * s.pitch_rate + wheel  # torso takes -wheel from the motor

        # Distribute (fx, fz, moment about the torso CoM) over the feet in contact.
        hip_z = HIP_OFFSET_Z * math.cos(s.pitch)
        mu = gait.friction
        forces: list[tuple[float, float]]
        if len(legs) == 2 and abs(legs[0].px - legs[1].px) > 0.05:
            a, b = legs
            rax, raz, rbx, rbz = hip_x + a.px, hip_z + a.pz, hip_x + b.px, hip_z + b.pz
            # Pitch first: keep the horizontal force within what the vertical split can balance
            # (all weight on one foot at the extremes), with a margin.
            fx_a = 2 * (moment + rax * fz_total) / (raz + rbz)
            fx_b = 2 * (moment + rbx * fz_total) / (raz + rbz)
            low, high = min(fx_a, fx_b), max(fx_a, fx_b)
            margin = 0.1 * (high - low)
            fx_total = min(max(fx_total, low + margin), high - margin)
            fx = fx_total / 2
            # sum(rz fx - rx fz) = moment, fza + fzb = fz_total
            rhs = (raz + rbz) * fx - moment
            fza = (rhs - rbx * fz_total) / (rax - rbx)
            fza = min(max(fza, 0.0), fz_total)
            forces = [(fx, fza), (fx, fz_total - fza)]
        else:
            # One support point: the pitch moment has to come from the horizontal force.
            rx = hip_x + sum(leg.px for leg in legs) / len(legs)
            rz = hip_z - height
            fx = (moment + rx * fz_total) / rz
            forces = [(fx / len(legs), fz_total / len(legs))] * len(legs)

        ctrl = self.ctrl
        for leg, (fx, fz) in zip(legs, forces):
            fx = clamp(fx, mu * fz)  # stay inside the friction cone
            tau_hip, tau_knee = leg.force_torques(fx, fz)
            i = 0 if leg is self.left else 1
            ctrl[1 + 2 * i] = clamp(tau_hip, LEG_TORQUE_LIMIT)
            ctrl[2 + 2 * i] = clamp(tau_knee, LEG_TORQUE_LIMIT)
        if len(legs) == 1:  # the other foot keeps swinging toward the ground
            self._swing_free_leg(s, on_l)
        return wheel

    def _swing_free_leg(self, s: Physics, left_on: bool) -> None:
        gait, ctrl = self.gait, self.ctrl
        if left_on:
            leg, i, knee, hip_rate, knee_rate, offset = self.right, 1, s.knee_R, s.hip_R_rate, s.knee_R_rate, -1
        else:
            leg, i, knee, hip_rate, knee_rate, offset = self.left, 0, s.knee_L, s.hip_L_rate, s.knee_L_rate, 1
        angle = -math.asin(clamp(offset * gait.foot_spread / 2 / gait.stand_height, 0.9))
        # Reach a little longer than the stance leg so the foot finds the ground.
        tau_hip, tau_knee = leg.swing_torques(min(gait.push_length, gait.stand_height + 0.1), angle, hip_rate, knee_rate, knee)
        ctrl[1 + 2 * i] = clamp(tau_hip, LEG_TORQUE_LIMIT)
        ctrl[2 + 2 * i] = clamp(tau_knee, LEG_TORQUE_LIMIT)


SATURATION_TORQUE = SATURATION_FRACTION * WHEEL_TORQUE_LIMIT  # N m
__all__ = ["HopController", "WheelPID", "wheel_ctrl", "wheel_torque_bounds", "SATURATION_TORQUE", "FOOT_RADIUS"]
