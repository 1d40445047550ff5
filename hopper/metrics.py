"""Per-hop metrics, as defined in PHYSICS.md, accumulated tick by tick."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from hopper.controller import A_APEX_Z, A_FLIGHT_TICKS, A_PEAK_PITCH, A_PEAK_WHEEL, A_RATE_SQ, A_SATURATION, N_ACC

RAD_S_TO_RPM = 60.0 / (2.0 * math.pi)
MIN_HOP_FLIGHT_S = 0.05  # s; a shorter flight (a foot skipping after a weak push) is no hop


@dataclasses.dataclass(frozen=True, kw_only=True)
class HopMetrics:
    """One hop. Flight metrics cover liftoff to touchdown; saturation and stance time cover the
    ground phase before the liftoff too, so that every tick belongs to exactly one hop and the
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

    def as_dict(self) -> dict[str, float | int | bool]:
        return dataclasses.asdict(self)


class MetricsTracker:
    """The hop in progress: the control kernel accumulates into `acc` every tick (cheap), and
    liftoff / touchdown turn it into a HopMetrics."""

    def __init__(self, acc: np.ndarray | None = None, x0: float = 0.0) -> None:
        self.hops: list[HopMetrics] = []
        self.acc = np.zeros(N_ACC) if acc is None else acc  # shared with the control kernel
        self.reset(x0)

    def reset(self, x0: float, time: float = 0.0) -> None:
        self.hops.clear()
        self._last_touchdown_x = x0
        self._start_hop(time)

    def _start_hop(self, time: float) -> None:
        self.acc[:] = 0.0
        self.acc[A_APEX_Z] = -math.inf
        self._ground_start = time
        self._liftoff_time: float | None = None
        self._liftoff_z = 0.0
        self._liftoff_momentum = 0.0

    def liftoff(self, time: float, z: float, momentum: float) -> None:
        self._liftoff_time, self._liftoff_z, self._liftoff_momentum = time, z, momentum
        self.acc[A_APEX_Z] = z

    def touchdown(self, time: float, x: float, pitch: float, completed: bool = True) -> HopMetrics | None:
        """Close the hop at a touchdown (or a fall in flight); None if no liftoff preceded it."""
        if self._liftoff_time is None:
            return None
        if completed and time - self._liftoff_time < MIN_HOP_FLIGHT_S:
            self._liftoff_time = None  # a skip off a rim, not a hop: the hop goes on
            return None
        acc = self.acc
        ticks = max(acc[A_FLIGHT_TICKS], 1.0)
        hop = HopMetrics(
            index=len(self.hops) + 1,
            distance_m=x - self._last_touchdown_x,
            apex_height_m=float(acc[A_APEX_Z]) - self._liftoff_z,
            flight_time_s=time - self._liftoff_time,
            stance_time_s=self._liftoff_time - self._ground_start,
            peak_pitch_deg=math.degrees(acc[A_PEAK_PITCH]),
            rms_pitch_rate_deg_s=math.degrees(math.sqrt(acc[A_RATE_SQ] / ticks)),
            landing_pitch_deg=math.degrees(abs(pitch)),
            saturation_time_s=float(acc[A_SATURATION]),
            peak_wheel_rpm=float(acc[A_PEAK_WHEEL]) * RAD_S_TO_RPM,
            liftoff_momentum=self._liftoff_momentum,
            touchdown_time_s=time,
            completed=completed,
        )
        self.hops.append(hop)
        self._last_touchdown_x = x
        self._start_hop(time)
        return hop
