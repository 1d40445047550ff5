"""The flight's recoverable envelope: pitch kicks of every size, direction and moment, against physics.

A kick of angular impulse h (N m s) at `t` s into a flight with `T` s to go lands within
LANDING_LIMIT_DEG only if two bounds allow it, both computed from the model at that moment:

- Momentum. The wheel can take from the torso I_w w_max less the robot's momentum H that way,
  as far as its torque-speed envelope reaches in the time left: (I_w w_max - s H)
  (1 - exp(-T / T_m)), T_m = I_spin w_max / tau_stall. I_w is the wheel's own spin inertia:
  MuJoCo's mass matrix couples pitch and wheel by it alone, since the armature (the rotor's
  reflected inertia, in I_spin) is the wheel joint's own and only slows the spin-up. What it
  cannot take turns the torso and the legs for the rest of the flight: at touchdown the torso
  may be LANDING_LIMIT_DEG off and the legs LANDING_POSE_TOLERANCE off their landing pose, so
  the rest is at most (I_torso limit + I_legs tolerance) / T.
- Torque. The kick is an impulse: it sets the torso alone (legs free, I_torso) turning at h /
  I_torso, and only finite torques stop it: the wheel's envelope plus both hips at their limit.
  The torso swings out by h^2 / (2 I_torso tau) before it stops and needs as long again (at best)
  to come back; a touchdown before then lands at that error.

`physical_limit` is the largest h both allow; `envelope_cases` makes the grid that
`hopper-sim envelope` flies; hopper.report.envelope draws it.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from hopper.analysis.loop import pitch_inertia
from hopper.config import SimConfig
from hopper.control import Phase
from hopper.control.gait import LANDING_POSE_TOLERANCE
from hopper.experiments.stress import LANDING_LIMIT_DEG, Case, Outcome, Schedule
from hopper.robot import PACKAGED, Robot
from hopper.sim import Simulation
from hopper.state import angular_momentum

KICKED_HOP = 2  # the kick comes in the second flight (the first starts from the standing pose)


@dataclasses.dataclass(frozen=True)
class Moment:
    """One instant of the undisturbed flight: what the physical limit needs of it."""

    t: float  # s since liftoff
    to_go: float  # s until the touchdown
    wheel_speed: float  # rad/s, relative to the torso
    momentum: float  # N m s, the whole robot's pitch angular momentum about its CoM
    locked: float  # kg m^2, the whole robot with the wheel locked
    torso: float  # kg m^2, the torso with the legs free (what an impulse turns)
    robot: Robot = PACKAGED  # the robot flown (its wheel and motors)


def flight_moments(config: SimConfig, every_s: float = 0.01) -> list[Moment]:
    """The undisturbed second flight of `config`, sampled every `every_s` s."""
    sim = Simulation(config)
    while len(sim.hops) < KICKED_HOP - 1 or sim.phase is not Phase.FLIGHT:
        sim.step()
        if sim.fallen or sim.time > 60.0:
            raise RuntimeError("the undisturbed run never reached its second flight")
    start, samples, every = sim.time, [], max(round(every_s / config.timestep), 1)
    tick = 0
    while sim.phase is Phase.FLIGHT:
        if tick % every == 0:
            inertia = pitch_inertia(sim.model, sim.data)
            momentum = angular_momentum(sim.model, sim.data, sim.layout)
            samples.append((sim.time - start, sim.state().wheel_speed, momentum, inertia.locked, inertia.torso))
        sim.step()
        tick += 1
    end = sim.time
    return [Moment(t, end - start - t, *rest, robot=sim.robot) for t, *rest in samples]


def wheel_reach(moment: Moment, sign: float) -> float:
    """Momentum (N m s) of a kick in direction `sign` the wheel can take from the torso by the touchdown.

    At its speed limit the wheel holds I_w w_max (1.41 N m s; momentum_capacity()'s 1.60 counts
    the armature, which holds none of the robot's momentum). Once torso and legs are still the
    wheel holds the whole robot's momentum, so its headroom is that less the robot's momentum
    that way (not less what it spins with now: early in a flight the legs' tuck and the torso's
    own motion hold some of it).
    """
    robot = moment.robot
    headroom = robot.wheel_inertia * robot.wheel_no_load_speed - sign * moment.momentum
    time_constant = robot.momentum_capacity / robot.wheel_torque_limit  # the armature slows the spin-up
    return max(headroom, 0.0) * (1.0 - math.exp(-moment.to_go / time_constant))


def momentum_limit(moment: Moment, sign: float) -> float:
    """Largest kick (N m s) the wheel and a legs' reorientation can leave within the landing limit."""
    # What the wheel leaves turns torso and legs: by touchdown the torso may be LANDING_LIMIT_DEG
    # off and the legs LANDING_POSE_TOLERANCE, so they hold at most this much momentum x time.
    legs = moment.locked - moment.torso
    turned = moment.torso * math.radians(LANDING_LIMIT_DEG) + legs * LANDING_POSE_TOLERANCE
    return wheel_reach(moment, sign) + turned / max(moment.to_go, 1e-3)


def torque_allows(moment: Moment, sign: float, kick: float) -> bool:
    """Whether the actuators' torque can stop a kick of `kick` N m s and bring the torso back in time."""
    robot = moment.robot
    wheel = abs(robot.wheel_torque_bound(moment.wheel_speed, sign * robot.wheel_torque_limit))  # its envelope that way
    torque = wheel + 2.0 * robot.leg_torque_limit  # N m on the torso: wheel and both hips
    limit, i, t = math.radians(LANDING_LIMIT_DEG), moment.torso, moment.to_go
    stop = kick / torque  # s until the torso stops
    if t <= stop:  # the touchdown comes while it still swings out
        return kick * t / i - torque * t * t / (2.0 * i) <= limit
    peak = kick * kick / (2.0 * i * torque)
    back = 2.0 * math.sqrt(max(peak - limit, 0.0) * i / torque)  # bang-bang return to the limit
    return t >= stop + back


def physical_limit(moment: Moment, sign: float) -> float:
    """The largest kick (N m s) in direction `sign` that physics lets land within the limit."""
    high = momentum_limit(moment, sign)
    if torque_allows(moment, sign, high):
        return high
    low = 0.0
    for _ in range(40):  # torque_allows is monotonic in the kick: bisect
        mid = 0.5 * (low + high)
        low, high = (mid, high) if torque_allows(moment, sign, mid) else (low, mid)
    return low


def envelope_cases(config: SimConfig, sizes: list[float], fractions: list[float], flight_s: float) -> list[Case]:
    """A pitch kick of every size (N m s, signed) at every fraction of the undisturbed flight."""
    return [
        Case(
            "flight",
            f"pitch kick {size:+.2f} N m s at {fraction:.0%} of flight",
            config,
            KICKED_HOP + 1,
            Schedule("pitch_kick", size, Phase.FLIGHT, fraction * flight_s, hop=KICKED_HOP),
        )
        for fraction in fractions
        for size in sizes
    ]


@dataclasses.dataclass(frozen=True)
class Row:
    """One moment and direction of the envelope: measured boundary against the physical limit."""

    sign: float
    fraction: float
    t: float  # s since liftoff
    limit: float  # N m s, physical_limit
    recovered: float  # N m s, the largest kick up to which every kick landed within the limit
    stood: float  # N m s, the largest kick up to which no kick fell
    falls_below_limit: int  # kicks under the limit that ended in a fall
    worst_below_limit_deg: float  # worst landing of those under the limit


def rows(outcomes: list[Outcome], moments: list[Moment], fractions: list[float], flight_s: float) -> list[Row]:
    """The table: for each direction and moment, the physical limit and the boundaries flown: every
    kick up to `recovered` landed within the limit, every kick up to `stood` did not fall."""
    out = []
    times = np.array([m.t for m in moments])
    for sign in (1.0, -1.0):
        for fraction in fractions:
            moment = moments[int(np.argmin(abs(times - fraction * flight_s)))]
            limit = physical_limit(moment, sign)
            here = sorted(
                (o for o in outcomes if o.case.disturbance is not None
                 and math.isclose(o.case.disturbance.delay_s, fraction * flight_s)
                 and o.case.disturbance.magnitude * sign > 0),
                key=lambda o: abs(o.case.disturbance.magnitude),  # type: ignore[union-attr]
            )  # fmt: skip
            recovered, stood, landing = 0.0, 0.0, True
            for o in here:
                if o.fell:
                    break
                size = abs(o.case.disturbance.magnitude)  # type: ignore[union-attr]
                landing = landing and o.worst_landing_deg <= LANDING_LIMIT_DEG
                recovered, stood = (size if landing else recovered), size
            below = [o for o in here if abs(o.case.disturbance.magnitude) <= limit]  # type: ignore[union-attr]
            out.append(
                Row(
                    sign,
                    fraction,
                    moment.t,
                    limit,
                    recovered,
                    stood,
                    sum(o.fell for o in below),
                    max((o.worst_landing_deg for o in below), default=0.0),
                )
            )
    return out


def table(rows_: list[Row]) -> list[str]:
    """The envelope as text: one line per direction and moment."""
    lines = [
        f"{'kick':<5} {'moment':>7} {'t':>6} {'limit':>8} {'landed':>8} {'ratio':>6} {'stood':>8} {'ratio':>6} "
        f"{'falls<limit':>11}"
    ]
    for r in rows_:
        sign, limit = ("+" if r.sign > 0 else "-"), max(r.limit, 1e-9)
        lines.append(
            f"{sign:<5} {r.fraction:>7.0%} {r.t:>5.2f}s {r.limit:>5.2f}Nms {r.recovered:>5.2f}Nms "
            f"{r.recovered / limit:>6.2f} {r.stood:>5.2f}Nms {r.stood / limit:>6.2f} {r.falls_below_limit:>11d}"
        )
    return lines
