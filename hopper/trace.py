"""A downsampled time series of a run (the figures' source): a Simulation listener writing columns."""

from __future__ import annotations

import math
from typing import Any

# Light on purpose (no hopper.control, hence no numba): hopper-sim imports this at start-up.
RAD_S_TO_RPM = 60.0 / (2.0 * math.pi)

TRACE_HZ = 100.0  # Hz: a 1.2 s lunar flight gets 120 samples, the wheel's 33 ms loop time is resolved
# Column names with their units, in the order they are written.
TRACE_COLUMNS = ("t_s", "x_m", "z_m", "pitch_deg", "pitch_rate_deg_s", "wheel_rpm", "wheel_torque_nm", "phase")


class TraceRecorder:
    """Samples the robot every 1 / hz s of simulation time into `columns` (TRACE_COLUMNS, lists).

    Add it to `sim.listeners`; it reads `sim.state()` on sampled ticks only (a state read costs a
    few microseconds, a skipped tick a counter). Time restarts at a reset: a trace is of one run.
    """

    def __init__(self, timestep: float, hz: float = TRACE_HZ) -> None:
        self.every = max(1, round(1.0 / (hz * timestep)))  # ticks between samples
        self.hz = 1.0 / (self.every * timestep)
        self.columns: dict[str, list[Any]] = {name: [] for name in TRACE_COLUMNS}
        self._count = 0

    def tick(self, sim: Any) -> None:  # hopper.sim.Simulation (not imported: it imports nothing of ours)
        self._count += 1
        if self._count % self.every:
            return
        s, c = sim.state(), self.columns
        c["t_s"].append(round(s.time, 6))
        c["x_m"].append(round(s.x, 5))
        c["z_m"].append(round(s.z, 5))
        c["pitch_deg"].append(round(math.degrees(s.pitch), 4))
        c["pitch_rate_deg_s"].append(round(math.degrees(s.pitch_rate), 3))
        c["wheel_rpm"].append(round(s.wheel_speed * RAD_S_TO_RPM, 2))
        c["wheel_torque_nm"].append(round(s.wheel_torque, 4))
        c["phase"].append(sim.phase.label)

    def event(self, sim: Any, event: Any) -> None:  # hopper.events.Event
        pass

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: the sampling rate (Hz) and one list per column."""
        return {"hz": self.hz, **self.columns}
