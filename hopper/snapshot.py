"""What a Simulation is between two ticks: the Snapshot its snapshot() returns and restore() takes.

A snapshot holds everything the next tick reads: MuJoCo's integration state (mj_getState with
mjSTATE_INTEGRATION: time, qpos, qvel, act, warm start, ctrl and applied forces), the sensor
values the kernel reads before mj_step recomputes them, the control kernel's memory record (phase,
PID integral, contact debounce, IMU noise RNG, motor delay line), the loop's pending disturbances,
the metrics tracker's hop in progress, a Python controller's state (a deep copy) and where the
terrain window stood (its heights follow from the field; hopper.terrain.window). Restoring it
and stepping repeats the original ticks bit for bit (the command queue is empty between ticks).
"""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np

from hopper.config import Gains, SimConfig
from hopper.errors import HopperError
from hopper.metrics import HopInProgress, HopMetrics
from hopper.schedule import KickSchedule

STATE_SPEC = mujoco.mjtState.mjSTATE_INTEGRATION


@dataclasses.dataclass(slots=True)
class Pending:
    """The disturbances the loop has under way; a Snapshot copies it whole, new fields included."""

    pulse_armed: float = 0.0  # N m, a torque pulse armed on the ground for the next flight
    pulse_magnitude: float = 0.0  # N m, the pulse that starts at pulse_at (0: pulse_at ends one)
    pulse_at: float = math.inf  # s, when the pending pulse starts or the running one ends
    kick_at: float = math.inf  # s, the scheduled kick's time (hopper.schedule)
    liftoff_at: float = 0.0  # s, the last liftoff's time (a kick is timed from it)
    touchdown_at: float = math.inf  # s, the flight's predicted touchdown (an API controller's obs)


@dataclasses.dataclass(frozen=True, eq=False)
class Snapshot:
    """The simulation between two ticks. Arrays are private copies; treat them as read-only."""

    time: float  # s of simulation
    physics: np.ndarray  # float64, mj_getState(STATE_SPEC)
    sensors: np.ndarray  # float64, data.sensordata (what the next control tick reads)
    memory: np.ndarray  # shape (1,), dtype MEMORY: the control kernel's record
    pending: Pending  # the loop's torque pulse and scheduled kick
    progress: HopInProgress  # the hop in progress (hopper.metrics.MetricsTracker)
    hops: tuple[HopMetrics, ...] | None  # hops completed so far; None: keep the target's
    config: SimConfig  # gains, gravity, terrain, sensing, ... at that moment
    schedule: KickSchedule | None = None  # the repeatable test's kick (hopper.schedule)
    law: object | None = None  # an API controller's state (hopper.controllers.law.FlightLaw.state)
    terrain_first: int | None = None  # the terrain window's first grid column; None: the start window's

    @property
    def gains(self) -> Gains:
        return self.config.gains

    @property
    def nbytes(self) -> int:
        """Bytes of array data held (the rest is a few small Python objects)."""
        return self.physics.nbytes + self.sensors.nbytes + self.memory.nbytes


class SnapshotMismatch(HopperError, ValueError):
    """A snapshot that does not fit this model (another model size or controller memory layout)."""
