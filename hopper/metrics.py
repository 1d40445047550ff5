"""Per-hop metrics, as defined in PHYSICS.md, accumulated tick by tick."""

from __future__ import annotations

import dataclasses
import math

from hopper.controller import SATURATION_TORQUE

RAD_S_TO_RPM = 60.0 / (2.0 * math.pi)


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
    """Accumulates one hop at a time; `update` runs every tick and must stay cheap."""

    def __init__(self, x0: float = 0.0) -> None:
        self.hops: list[HopMetrics] = []
        self.reset(x0)

    def reset(self, x0: float, time: float = 0.0) -> None:
        self.hops.clear()
        self._last_touchdown_x = x0
        self._start_hop(time)

    def _start_hop(self, time: float) -> None:
        self._ground_start = time
        self._liftoff_time: float | None = None
        self._liftoff_z = 0.0
        self._liftoff_momentum = 0.0
        self._apex_z = -math.inf
        self._peak_pitch = 0.0
        self._rate_sq_sum = 0.0
        self._flight_ticks = 0
        self._saturation = 0.0
        self._peak_wheel = 0.0

    def update(self, flying: bool, pitch: float, pitch_rate: float, wheel_torque: float,
               wheel_speed: float, z: float, dt: float) -> None:
        """Accumulate one tick (SI units)."""
        if wheel_torque >= SATURATION_TORQUE or wheel_torque <= -SATURATION_TORQUE:
            self._saturation += dt
        w = abs(wheel_speed)
        if w > self._peak_wheel:
            self._peak_wheel = w
        if flying:
            p = abs(pitch)
            if p > self._peak_pitch:
                self._peak_pitch = p
            self._rate_sq_sum += pitch_rate * pitch_rate
            self._flight_ticks += 1
            if z > self._apex_z:
                self._apex_z = z

    def liftoff(self, time: float, z: float, momentum: float) -> None:
        self._liftoff_time, self._liftoff_z, self._liftoff_momentum = time, z, momentum
        self._apex_z = z

    @property
    def in_flight(self) -> bool:
        return self._liftoff_time is not None

    def touchdown(self, time: float, x: float, pitch: float, completed: bool = True) -> HopMetrics | None:
        """Close the hop at a touchdown (or a fall in flight); None if no liftoff preceded it."""
        if self._liftoff_time is None:
            return None
        n = max(self._flight_ticks, 1)
        hop = HopMetrics(
            index=len(self.hops) + 1,
            distance_m=x - self._last_touchdown_x,
            apex_height_m=self._apex_z - self._liftoff_z,
            flight_time_s=time - self._liftoff_time,
            stance_time_s=self._liftoff_time - self._ground_start,
            peak_pitch_deg=math.degrees(self._peak_pitch),
            rms_pitch_rate_deg_s=math.degrees(math.sqrt(self._rate_sq_sum / n)),
            landing_pitch_deg=math.degrees(abs(pitch)),
            saturation_time_s=self._saturation,
            peak_wheel_rpm=self._peak_wheel * RAD_S_TO_RPM,
            liftoff_momentum=self._liftoff_momentum,
            touchdown_time_s=time,
            completed=completed,
        )
        self.hops.append(hop)
        self._last_touchdown_x = x
        self._start_hop(time)
        return hop
