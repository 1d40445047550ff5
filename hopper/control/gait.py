"""The gait at any gravity: every gain, threshold and time of the hop cycle derived from g and the robot.

Nothing here is tuned per body. The ground controller was designed on the Moon; each quantity
is carried to another gravity by the physics that sets it:

- Weight and ground forces scale with g, so contact thresholds, the ground moment the feet can
  give, and accelerations (asked as fractions of g) scale with g.
- The stance is an inverted pendulum whose time scale is 1/w0, w0 = sqrt(g / z): stance gains
  keep their damping ratio and move their natural frequency with w0 (then the error at which the
  feet's moment saturates, M_max / (I wn^2) with M_max ~ m g d, is the same at every g), and
  phase times scale with 1/w0, speeds with w0 z.
- The forward speed scales with w0 z too (dynamic similarity: the same Froude number), so the
  capture point, vx / w0 ahead of the CoM, lands as far ahead at every g; the feet land around it.
- The legs' strength does not scale: the hop is capped where landing from it would ask the legs
  for more than LEG_MARGIN of what their 30 N m motors can hold (a robot sized for the gravity,
  hopper.similarity, has legs that scale, and flies the Moon's hop).
- The wheel's momentum capacity does not scale either, but the ground moment that takes the
  wheel's momentum out does (a fraction of m g d): the stance waits for the wheel before the next
  push as long as that takes.
"""

from __future__ import annotations

import dataclasses
import math

from hopper.config import MOON_GRAVITY, GaitParams
from hopper.robot import PACKAGED, Robot

# Designed on the Moon (Moon values; see the module docstring for how they move with g).
STANCE_HEIGHT_WN, STANCE_HEIGHT_ZETA = 5.0, 1.0  # rad/s, hip height over the feet
STANCE_X_WN, STANCE_X_ZETA = 4.0, 1.0  # rad/s, CoM over the feet
STANCE_PITCH_WN, STANCE_PITCH_ZETA = 8.0, 1.0  # rad/s, torso pitch
STANCE_PITCH_INERTIA = 0.5  # kg m^2, I_locked - I_w (PHYSICS.md)
LANDING_DAMPING = 6.0  # 1/s, vertical velocity damping while absorbing the impact
PUSH_X_GAIN = 6.0  # 1/s, horizontal velocity tracking during the push
PUSH_ACCEL_G = 4.9  # g, cap on the vertical push acceleration (8 m/s^2 on the Moon) ...
LEG_MARGIN = 0.5  # ... and never more than this fraction of the legs' strength, nor the landing
# The horizontal push acceleration is this share of the vertical one (1.85 g of 4.9 g on the Moon):
# the push's force keeps its direction, from the rear foot through the CoM and inside the friction
# cone, where the legs' strength caps the vertical push (a horizontal cap of its own in g asked
# Earth's legs for 18 m/s^2 forward while they could give 5 up: the push ran the body forward
# over a straightening leg and never lifted it).
PUSH_X_SHARE = 1.85 / PUSH_ACCEL_G
SETTLED_SPEED = 0.08  # m/s on the Moon: the stance is settled below this
CONTACT_ON_WEIGHT = 0.075  # of the robot's weight: a foot touches above this (1 N on the Moon) ...
CONTACT_OFF_WEIGHT = 0.015  # ... and leaves below this (0.2 N), hysteresis
DRAIN_MOMENT = 0.3  # of the moment the feet can hold (m g spread / 2): the rate they empty the wheel at
WHEEL_READY = 0.1  # of the momentum capacity: the wheel must be below this before a push
# The push drives the whole robot's pitch angular momentum to zero through the feet, so the
# flight starts with the wheel's whole capacity free (Salto's finding, PHYSICS.md): 0.1 s on
# the Moon, well inside the ~0.6 s push.
MOMENTUM_GAIN = 10.0  # 1/s on the Moon
# A push that carries the capture point off the feet is caught by a small hop that lands around
# it: low (leg clearance, not speed, sets it), quick, through the CoM.
RECOVERY_APEX = 0.08  # m
# A hop out of a place the robot keeps landing back in (hopper.control.kernel, STALL_HOPS) goes
# BOOST_APEX times as high, as far as the legs' margin allows (at Earth it does not: the apex is at
# it already), and BOOST_SPEED times as fast (hopper.control.stance).
BOOST_APEX, BOOST_SPEED = 2.0, 2.0
# On the ground the wheel holds the torso's attitude: an internal torque whose loop does not
# depend on g, stiff enough to catch a 1.5 N m s kick within a few degrees.
HOLD_WN, HOLD_ZETA = 20.0, 1.0  # rad/s
# Feet land so that the capture point falls inside the front half of the support: the stance
# can then stop the CoM over the feet with the ground force alone, without a moment.
CAPTURE_MARGIN = 0.5  # of the half spread, behind the front foot
# ... but never further from the CoM than the ground can push through it: a landing force from
# the feet to the CoM must stay inside the friction cone, with this share of it to spare. A fast
# robot (after a 6 N s push) whose feet reach for the whole capture point lands with its legs
# near flat, and the braking force, passing far below the CoM, pitches it over backwards past
# what the wheel holds; it takes two hops to stop instead of one.
PLACEMENT_CONE = 0.5
# Flight attitude beyond the wheel (hopper.control.kernel.share_attitude); geometry, not g.
LEG_SHARE = 3.0  # the legs' world angle follows this times the torso's pitch error ...
LANDING_POSE_TOLERANCE = math.radians(15.0)  # ... up to this offset (rad) from the landing pose
# A torso turning back from beyond WAIT_FROM holds its legs WAIT_GAIN m/rad shorter (up to
# WAIT_MAX): each 10 ms of the touchdown's wait closes about a degree after a hard kick.
WAIT_FROM, WAIT_GAIN, WAIT_MAX = math.radians(1.0), 2.0, 0.06  # rad, m/rad, m
# Phase times on the Moon, s.
LANDING_MIN_S, STANCE_MAX_S, CROUCH_MIN_S, CROUCH_MAX_S, PUSH_MAX_S = 0.1, 2.0, 0.15, 1.2, 1.0


def standing_com_height(gait: GaitParams, robot: Robot = PACKAGED) -> float:
    """Torso CoM above the ground when standing, m (the pendulum length of the stance)."""
    return gait.stand_height - robot.hip_z + robot.foot_radius


def leg_force_limit(height: float, robot: Robot = PACKAGED) -> float:
    """Largest vertical force (N) both legs hold with the feet under the hip at hip `height` (m).

    With the foot below the hip the knee takes f * L sin(b), where cos(b) = h / (L1 + L2) for equal
    links: the knee motor's limit sets the force.
    """
    reach = robot.thigh + robot.shank
    bend = math.sqrt(max(1.0 - (height / reach) ** 2, 1e-6))
    return 2.0 * robot.leg_torque_limit / (robot.thigh * bend)


def held_gravity(gait: GaitParams, robot: Robot = PACKAGED) -> float:
    """The gravity (m/s^2) at which the legs, crouched, just hold the robot: `derive` refuses it and above."""
    return leg_force_limit(gait.crouch_height, robot) / robot.mass


def momentum_capacity(robot: Robot = PACKAGED) -> float:
    """The wheel's momentum capacity, N m s: (I_w + armature) * no-load speed (PHYSICS.md)."""
    return robot.momentum_capacity


@dataclasses.dataclass(frozen=True)
class Gait:
    """The hop cycle at one gravity; field names are those of the kernel's memory record."""

    vz_liftoff: float  # m/s, push-off vertical speed
    recovery_vz: float  # m/s, push-off speed of a recovery hop (to catch the capture point)
    vz_boost: float  # m/s, push-off speed of a hop out of a place the robot keeps landing back in
    apex: float  # m, the hop's apex above the liftoff height
    push_accel: float  # m/s^2, cap on the vertical push acceleration
    push_x_gain: float  # 1/s
    push_x_accel: float  # m/s^2
    kz: float  # 1/s^2, stance height stiffness per unit mass
    dz: float  # 1/s
    kx: float  # 1/s^2
    dx: float  # 1/s
    kp_stance: float  # N m/rad, torso pitch on the ground
    kd_stance: float  # N m s/rad
    landing_damping: float  # 1/s
    contact_on: float  # N
    contact_off: float  # N
    settled_speed: float  # m/s
    stance_min: float  # s
    landing_min: float  # s
    stance_max: float  # s
    crouch_min: float  # s
    crouch_max: float  # s
    push_max: float  # s
    wheel_ready: float  # rad/s, |wheel speed| below which a push may start
    wheel_wait: float  # s, longest extra stance to empty a full wheel at DRAIN_MOMENT
    swing_scale: float  # >= 1, leg swing stiffness multiplier for short flights
    momentum_gain: float  # 1/s, rate at which the push drives the pitch momentum to zero
    hold_kp: float  # N m/rad, the wheel holding the torso on the ground
    hold_kd: float  # N m s/rad
    forward_speed: float  # m/s at liftoff
    capture_time: float  # s, 1 / w0: the capture point is vx * capture_time ahead of the CoM
    capture_margin: float  # m, how far inside the front foot the capture point may land
    reach_limit: float  # m, the farthest the feet's midpoint lands from the CoM, either way
    leg_share: float  # the legs' share of the torso's attitude error in flight
    share_max: float  # rad
    wait_gain: float  # m/rad
    wait_from: float  # rad
    wait_max: float  # m

    def record(self) -> dict[str, float]:
        return dataclasses.asdict(self)

    def hop_time_bound(self, gravity: float) -> float:
        """A generous bound on one hop's duration, s (flight plus the longest ground phases)."""
        return 2.0 * self.vz_liftoff / gravity + self.stance_max + self.crouch_max + self.push_max


def derive(gravity: float, gait: GaitParams, robot: Robot = PACKAGED) -> Gait:
    """The gait for `gravity` (m/s^2, magnitude) from the Moon design and the robot's constants."""
    g, weight = gravity, robot.mass * gravity
    z = standing_com_height(gait, robot)
    r = math.sqrt(g / z) / math.sqrt(MOON_GRAVITY / z)  # w0 / w0_moon = sqrt(g / g_moon)
    # Net upward acceleration the legs can give, and the hop a landing can absorb with it over the
    # stroke from the flight length down to the crouch (v^2 = 2 a d, v^2 = 2 g h).
    strength = held_gravity(gait, robot) - g
    if strength <= 0.0:
        raise ValueError(f"the legs cannot hold the robot at {g:g} m/s^2 (crouched, {robot.leg_torque_limit:g} N m)")
    stroke = gait.flight_length - gait.crouch_height
    apex = min(gait.apex_height, LEG_MARGIN * strength * stroke / g)
    wn_z, wn_x, wn_p = STANCE_HEIGHT_WN * r, STANCE_X_WN * r, STANCE_PITCH_WN * r
    i = STANCE_PITCH_INERTIA
    ground_moment = weight * gait.foot_spread / 2  # N m, all the weight on one foot
    return Gait(
        vz_liftoff=math.sqrt(2.0 * g * apex),
        recovery_vz=math.sqrt(2.0 * g * min(RECOVERY_APEX, apex)),
        vz_boost=math.sqrt(2.0 * g * max(apex, min(BOOST_APEX * apex, LEG_MARGIN * strength * stroke / g))),
        apex=apex,
        push_accel=min(PUSH_ACCEL_G * g, LEG_MARGIN * strength),
        push_x_gain=PUSH_X_GAIN * r,
        push_x_accel=PUSH_X_SHARE * min(PUSH_ACCEL_G * g, LEG_MARGIN * strength),
        kz=wn_z**2,
        dz=2 * STANCE_HEIGHT_ZETA * wn_z,
        kx=wn_x**2,
        dx=2 * STANCE_X_ZETA * wn_x,
        kp_stance=i * wn_p**2,
        kd_stance=2 * STANCE_PITCH_ZETA * wn_p * i,
        landing_damping=LANDING_DAMPING * r,
        contact_on=CONTACT_ON_WEIGHT * weight,
        contact_off=CONTACT_OFF_WEIGHT * weight,
        settled_speed=SETTLED_SPEED * r,
        stance_min=gait.stance_time / r,
        landing_min=LANDING_MIN_S / r,
        stance_max=STANCE_MAX_S / r,
        crouch_min=CROUCH_MIN_S / r,
        crouch_max=CROUCH_MAX_S / r,
        push_max=PUSH_MAX_S / r,
        wheel_ready=WHEEL_READY * robot.wheel_no_load_speed,
        wheel_wait=robot.momentum_capacity / (DRAIN_MOMENT * ground_moment),
        swing_scale=max(1.0, r),
        momentum_gain=MOMENTUM_GAIN * r,
        hold_kp=i * HOLD_WN**2,
        hold_kd=2 * HOLD_ZETA * HOLD_WN * i,
        forward_speed=gait.forward_speed * r,
        capture_time=1.0 / (r * math.sqrt(MOON_GRAVITY / z)),
        capture_margin=CAPTURE_MARGIN * gait.foot_spread / 2,
        reach_limit=PLACEMENT_CONE * gait.friction * z,
        leg_share=LEG_SHARE,
        share_max=LANDING_POSE_TOLERANCE,
        wait_gain=WAIT_GAIN,
        wait_from=WAIT_FROM,
        wait_max=WAIT_MAX,
    )


def legs_cap(gravity: float, gait: GaitParams, robot: Robot = PACKAGED) -> tuple[float, float] | None:
    """(apex, asked), m: the hop the robot's legs cap at `gravity` (m/s^2), sized for less, and the one
    the gait asks; None when they do not cap it."""
    apex, asked = derive(gravity, gait, robot).apex, gait.apex_height
    return None if apex >= asked - 1e-9 else (apex, asked)
