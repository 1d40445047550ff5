"""Per-hop metrics, as defined in PHYSICS.md, accumulated tick by tick."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from hopper.control.kernel import RESPONSE_THRESHOLD, SETTLE_BAND
from hopper.control.memory import ACC, FLIGHT_ACC, RESPONSE_ACC
from hopper.robot import PACKAGED, Robot

RAD_S_TO_RPM = 60.0 / (2.0 * math.pi)
MIN_HOP_FLIGHT_S = 0.05  # s; a shorter flight (a foot skipping after a weak push) is no hop
MIN_TRANSPORT_DISTANCE_M = 0.01  # m; a shorter hop transported nothing: its cost of transport is NaN
# A robot whose TRAP_HOPS hops got it less than TRAP_M further is trapped (in a crater it cannot climb
# out of, hopping back and forth): it neither falls nor stops, so only its distance tells. Mars
# seed 0 hopped 800 times in one crater, 0.14 m a hop over its 1000.
TRAP_HOPS, TRAP_M = 50, 2.0  # hops, m (a hop is 0.4-0.8 m at every body)


def cost_of_transport(energy: float, mass: float, gravity: float, distance: float) -> float:
    """Dimensionless energy / (m g |d|) from J, kg, m/s^2 and m; NaN when |d| < MIN_TRANSPORT_DISTANCE_M
    (or without weight)."""
    weight_distance = mass * gravity * abs(distance)
    return energy / weight_distance if abs(distance) >= MIN_TRANSPORT_DISTANCE_M and weight_distance > 0 else math.nan


def trapped_at(distances: list[float]) -> int | None:
    """The first hop (0-based) of the first TRAP_HOPS hops that got less than TRAP_M further, if any
    (`distances`: each hop's, m, signed)."""
    ahead = np.concatenate(([0.0], np.cumsum(distances)))
    gained = ahead[TRAP_HOPS:] - ahead[:-TRAP_HOPS]
    stalled = np.flatnonzero(gained < TRAP_M)
    return int(stalled[0]) if stalled.size else None


@dataclasses.dataclass(frozen=True, kw_only=True)
class HopMetrics:
    """One hop. Flight metrics cover liftoff to touchdown; saturation, stance time and energy cover
    the ground phase before the liftoff too, so that every tick belongs to exactly one hop and the
    hop is final at its touchdown."""

    index: int
    distance_m: float  # torso x at this touchdown minus at the previous one (or the start)
    apex_height_m: float  # torso apex above its liftoff height
    flight_time_s: float
    stance_time_s: float  # ground time before this liftoff
    peak_pitch_deg: float  # max |pitch| in flight
    rms_pitch_rate_deg_s: float  # RMS pitch rate in flight
    landing_pitch_deg: float  # |pitch| at the first touchdown sample
    saturation_time_s: float  # time with |wheel torque| >= 98 % of the limit
    peak_wheel_rpm: float  # max |wheel speed| relative to the torso
    liftoff_momentum: float  # total pitch angular momentum at liftoff, kg m^2/s
    touchdown_time_s: float  # simulation time of the touchdown (or the fall)
    completed: bool = True  # False: the flight ended in a fall, not a touchdown
    # The flight's pitch response, from the scheduled kick or else from liftoff (see ResponseMetrics).
    kicked: bool = False  # a scheduled disturbance hit this flight (hopper.schedule)
    response_start_s: float = 0.0  # s after liftoff the response is measured from: the kick, or 0
    response_peak_deg: float = 0.0
    overshoot_deg: float = 0.0
    settling_time_s: float = 0.0
    settled: bool = True
    peak_wheel_torque_nm: float = 0.0
    peak_momentum_pct: float = 0.0
    landing_error_deg: float = 0.0
    # Electrical energy over the hop, ground phase and flight (hopper.control.energy: copper loss plus
    # mechanical work; braking energy is not recovered unless hopper.config.REGENERATIVE_DRIVES).
    wheel_energy_j: float = 0.0
    leg_energy_j: float = 0.0  # the four leg motors together
    cost_of_transport: float = 0.0  # (wheel + leg energy) / (m g |distance|); NaN for a hop in place

    def as_dict(self) -> dict[str, float | int | bool]:
        return dataclasses.asdict(self)


class ResponseMetrics:
    """How the flight PID answered, measured from t0 = the scheduled kick's tick (or the liftoff)
    to the touchdown, over flight ticks, on the true pitch (HopMetrics fields):

    - response_peak_deg: the first excursion's peak |pitch|. The first excursion starts at the
      first tick after t0 with |pitch| > 0.25 deg (RESPONSE_THRESHOLD; smaller wobbles start none)
      and ends at the first zero crossing.
    - overshoot_deg: the largest pitch beyond zero on the side opposite the first excursion,
      after that crossing (>= 0; 0 when it never crossed). overshoot / response_peak is the
      classic overshoot ratio of a regulator's disturbance response.
    - settling_time_s: from t0 to the end of the last tick with |pitch| > 1 deg (0 if none).
      settled is False when |pitch| was still beyond 1 deg at the touchdown: the value is then
      the time to the touchdown, a lower bound.
    - peak_wheel_torque_nm: largest |wheel torque| (the actuator's, at the motor side, against
      the 29.5 N m limit).
    - peak_momentum_pct: largest |wheel momentum| relative to the torso, (I_w + armature) * speed,
      in % of hopper.control.gait.momentum_capacity().
    - landing_error_deg: signed pitch at the touchdown (upright is 0); landing_pitch_deg is its size.
    """

    THRESHOLD_DEG = math.degrees(RESPONSE_THRESHOLD)  # the kernel accumulates with these (control/kernel.py)
    BAND_DEG = math.degrees(SETTLE_BAND)


@dataclasses.dataclass(slots=True)
class HopInProgress:
    """The tracker's own state between a hop's start and its touchdown (the kernel holds the rest).

    Snapshots copy it whole (Simulation.snapshot), so a field added here is restored with no more code.
    """

    last_touchdown_x: float = 0.0  # m, world x of the last touchdown: the hop's distance starts there
    ground_start: float = 0.0  # s, when this hop's ground phase began
    liftoff_time: float | None = None  # s; None until the liftoff (or after a skip off a rim)
    liftoff_z: float = 0.0  # m, CoM height at the liftoff
    liftoff_momentum: float = 0.0  # N m s, the robot's angular momentum at the liftoff
    response_start: float | None = None  # s, simulation time of the scheduled kick; None: from liftoff


class MetricsTracker:
    """The hop in progress: the control kernel accumulates into the `acc_*` fields of its memory
    record every tick (cheap), and liftoff / touchdown turn them into a HopMetrics."""

    def __init__(self, mem: np.ndarray, x0: float = 0.0, robot: Robot = PACKAGED) -> None:
        self.hops: list[HopMetrics] = []
        self.mem = mem  # the control kernel's MEMORY record, shared
        self.robot = robot  # its mass and wheel, for the cost of transport and the momentum's share
        self.dt = float(mem["dt"][0])  # s, a control tick
        self.progress = HopInProgress()
        self.reset(x0)

    def reset(self, x0: float, time: float = 0.0) -> None:
        self.hops.clear()
        self.progress.last_touchdown_x = x0
        self._start_hop(time)

    def _start_hop(self, time: float) -> None:
        self._clear(ACC)
        self.progress = HopInProgress(last_touchdown_x=self.progress.last_touchdown_x, ground_start=time)

    def _clear(self, fields: tuple[str, ...]) -> None:
        for name in fields:
            self.mem[name] = -math.inf if name in ("acc_apex_z", "acc_last_out") else 0.0

    def liftoff(self, time: float, z: float, momentum: float) -> None:
        p = self.progress
        p.liftoff_time, p.liftoff_z, p.liftoff_momentum = time, z, momentum
        p.response_start = None
        self._clear(RESPONSE_ACC)
        self.mem["acc_apex_z"] = z

    def kicked(self, time: float) -> None:
        """A scheduled disturbance hit now (s): the flight's response is measured from here."""
        if self.progress.liftoff_time is not None:
            self.progress.response_start = time
            self._clear(RESPONSE_ACC)

    def _acc(self, name: str) -> float:
        return float(self.mem[name][0])

    def momentum_pct(self, wheel_speed: float) -> float:
        """A wheel speed (rad/s, relative to the torso) as its momentum's share of the wheel's capacity, %."""
        return 100.0 * self.robot.spin_inertia * abs(wheel_speed) / self.robot.momentum_capacity

    def flight_momentum_pct(self) -> float:
        """The largest share of the wheel's momentum capacity a flight has used so far, %: every hop's
        peak_momentum_pct and the flight in progress's. The ground phases are left out: the stance
        spins the wheel to 57 to 59 % on the Moon whatever the flight gains, which hid what they use."""
        return max([h.peak_momentum_pct for h in self.hops] + [self.momentum_pct(self._acc("acc_resp_wheel"))])

    def touchdown(self, time: float, x: float, pitch: float, completed: bool = True) -> HopMetrics | None:
        """Close the hop at a touchdown (or a fall in flight); None if no liftoff preceded it."""
        p = self.progress
        if p.liftoff_time is None:
            return None
        if completed and time - p.liftoff_time < MIN_HOP_FLIGHT_S:
            # A skip off a rim, not a hop: the hop goes on, and the skip's flight ticks must not
            # count toward the real flight's peak pitch and RMS rate.
            p.liftoff_time = None
            self._clear(FLIGHT_ACC)
            return None
        acc = self._acc
        ticks = max(acc("acc_flight_ticks"), 1.0)
        kicked = p.response_start is not None
        start = p.response_start if p.response_start is not None else p.liftoff_time
        settled = abs(pitch) <= SETTLE_BAND
        last_out = acc("acc_last_out")
        settling = (last_out + self.dt - start if last_out > -math.inf else 0.0) if settled else time - start
        distance, wheel_energy, leg_energy = x - p.last_touchdown_x, acc("acc_wheel_energy"), acc("acc_leg_energy")
        gravity = acc("gravity")  # the config's, m/s^2
        hop = HopMetrics(
            index=len(self.hops) + 1,
            distance_m=distance,
            apex_height_m=acc("acc_apex_z") - p.liftoff_z,
            flight_time_s=time - p.liftoff_time,
            stance_time_s=p.liftoff_time - p.ground_start,
            peak_pitch_deg=math.degrees(acc("acc_peak_pitch")),
            rms_pitch_rate_deg_s=math.degrees(math.sqrt(acc("acc_rate_sq") / ticks)),
            landing_pitch_deg=math.degrees(abs(pitch)),
            saturation_time_s=acc("acc_saturation"),
            peak_wheel_rpm=acc("acc_peak_wheel") * RAD_S_TO_RPM,
            liftoff_momentum=p.liftoff_momentum,
            touchdown_time_s=time,
            completed=completed,
            kicked=kicked,
            response_start_s=start - p.liftoff_time,
            response_peak_deg=math.degrees(acc("acc_first_peak")),
            overshoot_deg=math.degrees(acc("acc_overshoot")),
            settling_time_s=max(settling, 0.0),
            settled=settled,
            peak_wheel_torque_nm=acc("acc_peak_torque"),
            peak_momentum_pct=self.momentum_pct(acc("acc_resp_wheel")),
            landing_error_deg=math.degrees(pitch),
            wheel_energy_j=wheel_energy,
            leg_energy_j=leg_energy,
            cost_of_transport=cost_of_transport(wheel_energy + leg_energy, self.robot.mass, gravity, distance),
        )
        self.hops.append(hop)
        p.last_touchdown_x = x
        self._start_hop(time)
        return hop
