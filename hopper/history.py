"""History: a ring of recent states, the state at every liftoff, and re-flying a flight.

The states are the Simulation's own snapshots (hopper.snapshot: Simulation.snapshot / restore):
restoring one and stepping repeats the original ticks bit for bit.
"""

from __future__ import annotations

import collections
import dataclasses
import math

import numpy as np

from hopper.config import Gains, SimConfig
from hopper.control import EV_FALL
from hopper.events import Event, EventKind
from hopper.metrics import HopMetrics
from hopper.sim import Simulation
from hopper.snapshot import Snapshot

RING_PERIOD_S = 0.1  # s of simulation between ring snapshots
RING_SPAN_S = 40.0  # s of simulation the ring covers (the scrubber shows 30 s or more)
MAX_FLIGHT_TICKS = 20_000  # 20 s at 1 kHz: bounds a recorded or re-flown flight (a lunar hop is ~1 s)
GHOST_EVERY = 10  # ticks between the ghost's stored poses (100 Hz)


@dataclasses.dataclass(frozen=True, eq=False)
class Flight:
    """One flight from the tick after liftoff to the touchdown (or fall), sampled every tick."""

    start: Snapshot  # the state right after the liftoff tick
    gains: Gains  # the flight PID gains it flew with
    pitch: np.ndarray  # rad, torso pitch after each tick
    torque: np.ndarray  # N m, wheel torque applied in each tick
    poses: np.ndarray  # qpos every GHOST_EVERY ticks, for a ghost robot (may be empty)
    hop: HopMetrics | None  # the hop's metrics at its touchdown (None: it did not land)
    controller: str = "pid"  # the controller that flew it (hopper.controllers spec)

    @property
    def label(self) -> str:
        """What flew it, for a table: the PID's gains, or the controller's spec."""
        g = self.gains
        return f"{g.kp:g}/{g.ki:g}/{g.kd:g}" if self.controller == "pid" else self.controller.rpartition("/")[2]

    @property
    def duration(self) -> float:
        return len(self.pitch) * self.start.config.timestep

    def summary(self) -> dict[str, float]:
        """The A/B table's figures: peak pitch (deg), RMS pitch rate (deg/s), landing pitch error (deg), peak torque."""
        hop = self.hop
        nan = math.nan
        return {
            "peak_pitch_deg": hop.peak_pitch_deg if hop else math.degrees(float(np.abs(self.pitch).max(initial=nan))),
            "rms_rate_deg_s": hop.rms_pitch_rate_deg_s if hop else nan,
            "landing_pitch_deg": hop.landing_pitch_deg if hop else nan,
            "peak_torque_nm": float(np.abs(self.torque).max(initial=0.0)),
        }


class History:
    """A simulation listener keeping a ring of snapshots and the last complete flight.

    Per tick it costs a time comparison, plus two stores while in flight; a snapshot (~1.9 KB)
    every RING_PERIOD_S. Resets keep the ring (scrubbing back past a fall is the point); a new
    terrain clears it, as its states belong to the old ground.
    """

    def __init__(self, period: float = RING_PERIOD_S, span: float = RING_SPAN_S) -> None:
        self.period = period
        self.ring: collections.deque[Snapshot] = collections.deque(maxlen=max(int(round(span / period)), 1))
        self.last_flight: Flight | None = None
        self._next = -math.inf
        self._liftoff_due = False
        self._landing = False
        self._start: Snapshot | None = None
        self._pitch = np.empty(MAX_FLIGHT_TICKS)
        self._torque = np.empty(MAX_FLIGHT_TICKS)
        self._count = np.zeros(1, np.int64)  # flight ticks recorded: an array, so compiled ticks add to it
        self._rewound: Snapshot | None = None
        self._q_pitch = self._s_torque = 0  # the model's indices, set at the first liftoff
        # Views of MjData's arrays, made at each liftoff (each access to data.qpos makes a new one).
        self._qpos = self._sensors = np.empty(0)
        self._hop: HopMetrics | None = None

    # -- Listener --------------------------------------------------------------------------
    def idle_until(self, sim: Simulation) -> float:
        """tick() does nothing but record the flight (flight_trace) before the next ring snapshot
        (hopper.sim.Listener), unless a flight begins, ends or the simulation was rewound."""
        if self._liftoff_due or self._landing or self._rewound is not None:
            return -math.inf
        return self._next - 5e-4

    def flight_trace(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int] | None:
        """While a flight is recorded: (pitch, torque, count, qpos index, sensordata index), the arrays
        compiled ticks append each tick's qpos[index] and sensordata[index] to (hopper.stepping)."""
        if self._start is None:
            return None
        return self._pitch, self._torque, self._count, self._q_pitch, self._s_torque

    def tick(self, sim: Simulation) -> None:
        now = sim.data.time
        if self._start is None and now < self._next - 5e-4 and not self._liftoff_due and self._rewound is None:
            return  # most ticks on the ground
        if self._rewound is not None:
            self._resume_from(self._rewound)
        if self._start is not None:
            n = self._count[0]
            if n < MAX_FLIGHT_TICKS:
                self._pitch[n] = self._qpos[self._q_pitch]
                self._torque[n] = self._sensors[self._s_torque]
                self._count[0] = n + 1
            if self._landing:
                self._finish()
        if self._liftoff_due:
            self._liftoff_due = False
            self._q_pitch, self._s_torque = sim.layout.q_pitch, sim.layout.s_wheel_torque
            self._qpos, self._sensors = sim.data.qpos, sim.data.sensordata
            self._start, self._landing, self._hop = sim.snapshot(with_hops=False), False, None
            self._count[0] = 0
        if now >= self._next - 5e-4:  # half a tick early: the float clock drifts around the grid
            self._next = self._next + self.period if now - self._next < self.period else now + self.period
            self.ring.append(sim.snapshot())

    def event(self, sim: Simulation, event: Event) -> None:
        kind = event.kind
        if kind == EventKind.LIFTOFF:
            self._liftoff_due = True
        elif kind == EventKind.TOUCHDOWN and self._start is not None and event.payload.hop is not None:
            self._landing, self._hop = True, event.payload.hop  # the touchdown tick is sampled, then it ends
        elif kind == EventKind.FALL and self._start is not None:
            self._landing, self._hop = True, None
        elif kind == EventKind.RESET:
            self._start, self._liftoff_due, self._next = None, False, -math.inf
        if kind == EventKind.TERRAIN:
            self.ring.clear()
            self.last_flight = None

    def _finish(self) -> None:
        n = int(self._count[0])
        assert self._start is not None
        start = self._start
        self.last_flight = Flight(
            start, start.gains, self._pitch[:n].copy(), self._torque[:n].copy(), np.empty((0, 0)), self._hop,
            start.config.controller,
        )  # fmt: skip
        self._start, self._landing = None, False

    # -- scrubbing -------------------------------------------------------------------------
    def at(self, seconds_back: float) -> Snapshot | None:
        """The ring's snapshot `seconds_back` (s, >= 0) before its newest one; None if the ring is empty."""
        if not self.ring:
            return None
        back = min(max(int(round(seconds_back / self.period)), 0), len(self.ring) - 1)
        return self.ring[len(self.ring) - 1 - back]

    @property
    def span(self) -> float:
        """Seconds of simulation the ring holds now."""
        return max(len(self.ring) - 1, 0) * self.period

    def rewound(self, snap: Snapshot) -> None:
        """The live simulation was restored to `snap` (a ring entry or a keyframe): when it steps
        again, history after that moment is dropped and the flight in progress is forgotten."""
        self._rewound = snap
        self._start, self._liftoff_due, self._landing = None, False, False

    def _resume_from(self, snap: Snapshot) -> None:
        self._rewound = None
        if snap in self.ring:
            while self.ring and self.ring[-1] is not snap:
                self.ring.pop()
        self._next = snap.time + self.period

    def nbytes(self) -> int:
        """Bytes of array data the ring and the last flight hold."""
        flight = self.last_flight
        extra = flight.pitch.nbytes + flight.torque.nbytes + flight.start.nbytes if flight else 0
        return sum(s.nbytes for s in self.ring) + extra + self._pitch.nbytes + self._torque.nbytes


def fly(start: Snapshot, flown: Gains | SimConfig | None = None, max_ticks: int = MAX_FLIGHT_TICKS) -> Flight:
    """Re-fly a flight in a scratch simulation: restore `start`, then fly it with `flown`'s gains
    (a Gains) or gains and controller (a SimConfig; its plant settings are ignored), None: as
    recorded; step until the hop's touchdown or a fall. The live simulation is not touched.

    Another controller starts as attached mid-flight: reset at its first call. The recorded one
    continues from the state the snapshot holds (bit for bit; tests/test_controllers.py)."""
    config = start.config
    if isinstance(flown, Gains):
        config = dataclasses.replace(config, gains=flown)
    elif flown is not None:
        config = dataclasses.replace(
            config, gains=flown.gains, controller=flown.controller, controller_params=flown.controller_params
        )
    sim = Simulation(dataclasses.replace(start.config))
    sim.restore(start)
    if config.gains != start.gains:
        sim.set_gains(config.gains, "re-fly")
    if (config.controller, config.controller_params) != (start.config.controller, start.config.controller_params):
        sim.set_controller(config.controller, config.controller_params)
    assert sim.config == config
    hops = len(sim.hops)
    q_pitch, s_torque = sim.layout.q_pitch, sim.layout.s_wheel_torque
    pitch, torque = np.empty(max_ticks), np.empty(max_ticks)
    poses = []
    qpos, sensors = sim.data.qpos, sim.data.sensordata
    n = 0
    while n < max_ticks:
        events = sim.step()
        pitch[n], torque[n] = qpos[q_pitch], sensors[s_torque]
        if n % GHOST_EVERY == 0:
            poses.append(qpos.copy())
        n += 1
        if len(sim.hops) > hops or events & EV_FALL or sim.fallen:
            break
    hop = sim.hops[hops] if len(sim.hops) > hops and sim.hops[hops].completed else None
    poses.append(qpos.copy())
    return Flight(start, sim.gains, pitch[:n].copy(), torque[:n].copy(), np.asarray(poses), hop, sim.config.controller)
