"""Typed simulation events: a kind, a small payload dataclass each, and one describe() for every log."""

from __future__ import annotations

import dataclasses
import enum
import math
from typing import ClassVar, Literal

from hopper.config import Gains
from hopper.control.phases import FallCause
from hopper.disturbances import DISTURBANCE_NAMES, DisturbanceKind
from hopper.metrics import HopMetrics
from hopper.schedule import KickSchedule


class EventKind(enum.StrEnum):
    LIFTOFF = "liftoff"
    APEX = "apex"
    TOUCHDOWN = "touchdown"
    FALL = "fall"
    RESET = "reset"
    GAINS = "gains"
    WHEEL = "wheel"
    GRAVITY = "gravity"
    TERRAIN = "terrain"
    DISTURBANCE = "disturbance"
    DISTURBANCE_ARMED = "disturbance_armed"
    DIVERGED = "diverged"
    COMMAND_FAILED = "command_failed"
    RECORDING = "recording"
    SENSING = "sensing"
    OPERATOR = "operator"
    SCHEDULE = "schedule"
    CONTROLLER = "controller"
    CONTROLLER_FAILED = "controller_failed"
    RESTORE = "restore"
    RESUME = "resume"
    INJECTION = "injection"


def _hop_text(hop: HopMetrics) -> str:
    return (
        f"hop {hop.index}{'' if hop.completed else ' (fell)'}, distance {hop.distance_m:.3f} m, "
        f"apex {hop.apex_height_m:.3f} m, flight {hop.flight_time_s:.3f} s, peak pitch {hop.peak_pitch_deg:.2f}°, "
        f"landing pitch {hop.landing_pitch_deg:.2f}°, saturation {hop.saturation_time_s:.3f} s, "
        f"peak wheel {hop.peak_wheel_rpm:.0f} rpm"
    )


@dataclasses.dataclass(frozen=True)
class Liftoff:
    kind: ClassVar[EventKind] = EventKind.LIFTOFF
    momentum: float  # kg m^2/s, total pitch angular momentum

    def describe(self) -> str:
        return f"liftoff, pitch momentum {self.momentum:+.3f} N m s"


@dataclasses.dataclass(frozen=True)
class Apex:
    kind: ClassVar[EventKind] = EventKind.APEX
    height_m: float  # torso z

    def describe(self) -> str:
        return f"apex at {self.height_m:.3f} m"


@dataclasses.dataclass(frozen=True)
class Touchdown:
    kind: ClassVar[EventKind] = EventKind.TOUCHDOWN
    hop: HopMetrics | None  # None: a skip too short to be a hop

    def describe(self) -> str:
        return f"touchdown: {_hop_text(self.hop)}" if self.hop else "touchdown (a skip, not a hop)"


@dataclasses.dataclass(frozen=True)
class Fall:
    kind: ClassVar[EventKind] = EventKind.FALL
    cause: FallCause
    pitch_deg: float
    hip_height_m: float  # hip above the feet, m (0 in flight)
    hop: HopMetrics | None  # the flight that ended in the fall, if any

    def describe(self) -> str:
        pitch = f"{self.pitch_deg:+.0f}°" if math.isfinite(self.pitch_deg) else "?"
        return f"fell: {self.cause.describe()} (pitch {pitch}, hip {self.hip_height_m:.2f} m above the feet)"


@dataclasses.dataclass(frozen=True)
class Reset:
    kind: ClassVar[EventKind] = EventKind.RESET
    reason: str  # start, user, terrain, diverged, after fall, off the terrain, error

    def describe(self) -> str:
        return f"reset ({self.reason})"


@dataclasses.dataclass(frozen=True)
class GainsChanged:
    kind: ClassVar[EventKind] = EventKind.GAINS
    gains: Gains
    source: str = ""  # what chose them, when a design helper did

    def describe(self) -> str:
        g = self.gains
        by = f", by {self.source}" if self.source else ""
        return f"gains Kp {g.kp:.4g} N m/rad, Ki {g.ki:.4g} N m/(rad s), Kd {g.kd:.4g} N m s/rad{by}"


@dataclasses.dataclass(frozen=True)
class WheelChanged:
    kind: ClassVar[EventKind] = EventKind.WHEEL
    enabled: bool

    def describe(self) -> str:
        return "wheel on" if self.enabled else "wheel off (zero torque, free to spin)"


@dataclasses.dataclass(frozen=True)
class SensingChanged:
    kind: ClassVar[EventKind] = EventKind.SENSING
    sensing: str  # ideal | realistic

    def describe(self) -> str:
        return "sensing realistic (IMU estimate, motor delay)" if self.sensing == "realistic" else "sensing ideal"


@dataclasses.dataclass(frozen=True)
class GravityChanged:
    kind: ClassVar[EventKind] = EventKind.GRAVITY
    gravity: float  # m/s^2

    def describe(self) -> str:
        return f"gravity {self.gravity:g} m/s²"


@dataclasses.dataclass(frozen=True)
class TerrainChanged:
    kind: ClassVar[EventKind] = EventKind.TERRAIN
    terrain: str  # crater | flat
    seed: int

    def describe(self) -> str:
        return f"terrain {self.terrain}, seed {self.seed}"


@dataclasses.dataclass(frozen=True)
class Disturbance:
    kind: ClassVar[EventKind] = EventKind.DISTURBANCE
    disturbance: DisturbanceKind
    magnitude: float
    unit: str
    duration_s: float = 0.0  # 0: an impulse
    after_liftoff_s: float | None = None  # set when a schedule (hopper.schedule) applied it

    def describe(self) -> str:
        extra = f" for {self.duration_s:g} s" if self.duration_s else ""
        if self.after_liftoff_s is not None:
            extra += f" (scheduled, {self.after_liftoff_s * 1000:.0f} ms after liftoff)"
        return f"{DISTURBANCE_NAMES[self.disturbance]} {self.magnitude:+g} {self.unit}{extra}"


@dataclasses.dataclass(frozen=True)
class Dragged:
    """The mouse pulled the robot (hopper.perturb): one event on release, with what the pull added up to."""

    kind: ClassVar[EventKind] = EventKind.DISTURBANCE
    disturbance: ClassVar[str] = "drag"
    impulse_x: float  # N s, world x (+ forward)
    impulse_z: float  # N s, world z (+ up)
    peak_force_n: float  # N
    duration_s: float  # s, grab to release

    def describe(self) -> str:
        return (
            f"drag {self.impulse_x:+.2f} N s forward, {self.impulse_z:+.2f} N s up over {self.duration_s:.2f} s "
            f"(peak {self.peak_force_n:.0f} N)"
        )


@dataclasses.dataclass(frozen=True)
class ScheduleChanged:
    kind: ClassVar[EventKind] = EventKind.SCHEDULE
    schedule: KickSchedule | None  # None: cleared

    def describe(self) -> str:
        return f"schedule: {self.schedule.describe()}" if self.schedule else "schedule cleared"


@dataclasses.dataclass(frozen=True)
class DisturbanceArmed:
    kind: ClassVar[EventKind] = EventKind.DISTURBANCE_ARMED
    disturbance: DisturbanceKind
    magnitude: float
    unit: str

    def describe(self) -> str:
        return f"{DISTURBANCE_NAMES[self.disturbance]} {self.magnitude:+g} {self.unit} armed for the next flight"


@dataclasses.dataclass(frozen=True)
class Diverged:
    kind: ClassVar[EventKind] = EventKind.DIVERGED
    reason: str

    def describe(self) -> str:
        return f"diverged ({self.reason}), reset"


@dataclasses.dataclass(frozen=True)
class CommandFailed:
    kind: ClassVar[EventKind] = EventKind.COMMAND_FAILED
    command: str
    message: str

    def describe(self) -> str:
        return f"{self.command} failed: {self.message}"


@dataclasses.dataclass(frozen=True)
class Recording:
    kind: ClassVar[EventKind] = EventKind.RECORDING
    state: Literal["started", "stopped", "failed"]
    path: str | None  # None: a viewer only
    message: str = ""

    def describe(self) -> str:
        where = self.path or "the rerun viewer"
        if self.state == "failed":
            return f"recording failed: {self.message}"
        return f"recording {'started' if self.state == 'started' else 'saved'}: {where}"


@dataclasses.dataclass(frozen=True)
class ControllerChanged:
    """The flight's wheel law now (hopper.controllers): its spec, class and param values."""

    kind: ClassVar[EventKind] = EventKind.CONTROLLER
    spec: str  # pid, lqr, mpc, FILE.py:Class, module:Class, tcp://...
    name: str  # the class
    params: tuple[tuple[str, float], ...] = ()

    def describe(self) -> str:
        values = ", ".join(f"{k} {v:.4g}" for k, v in self.params)
        return f"controller {self.spec} ({self.name}{': ' + values if values else ''})"


@dataclasses.dataclass(frozen=True)
class ControllerFailed:
    """A controller misbehaved in a run; the built-in PID flies from this tick on."""

    kind: ClassVar[EventKind] = EventKind.CONTROLLER_FAILED
    spec: str
    cause: str

    def describe(self) -> str:
        return f"controller {self.spec} failed, the PID flies on: {self.cause}"


@dataclasses.dataclass(frozen=True)
class Restored:
    """The simulation was put back to an earlier moment (a front end's history, a keyframe); the
    event's time is that moment's."""

    kind: ClassVar[EventKind] = EventKind.RESTORE
    what: str  # "the moment 5.0 s back", "keyframe 'mid hop'"

    def describe(self) -> str:
        return f"restored {self.what}"


@dataclasses.dataclass(frozen=True)
class Resumed:
    """The simulation steps on from a moment it was restored to while paused."""

    kind: ClassVar[EventKind] = EventKind.RESUME

    def describe(self) -> str:
        return "resumed from the moment restored"


@dataclasses.dataclass(frozen=True)
class Injected:
    """A signal played into the stand's loop (hopper.stand.Injection): one event as it starts, one as
    it ends."""

    kind: ClassVar[EventKind] = EventKind.INJECTION
    what: str  # "a 20 s logarithmic chirp, 0.5-40 Hz, 2 N m"
    at: Literal["input", "reference"]  # added to the wheel torque, or to the pitch reference
    played_s: float | None = None  # None as it starts; then the seconds it played
    stopped: str = ""  # why it ended before its last sample ("" if it did not)

    def describe(self) -> str:
        where = "the wheel torque" if self.at == "input" else "the pitch reference"
        if self.played_s is None:
            return f"injecting {self.what} at {where}"
        if self.stopped:
            return f"injection stopped after {self.played_s:.1f} s: {self.stopped}"
        return f"injection played: {self.what} at {where}"


OperatorReason = Literal["first", "handed over", "disconnected", "idle"]


@dataclasses.dataclass(frozen=True)
class OperatorChanged:
    """Who may change the settings of a shared live session (front ends with several viewers)."""

    kind: ClassVar[EventKind] = EventKind.OPERATOR
    operator: str | None  # who operates now, e.g. "client 3 (127.0.0.1)"; None: nobody
    previous: str | None  # who operated before, e.g. "client 1"; None: nobody
    reason: OperatorReason

    def describe(self) -> str:
        now = f"operator {self.operator}" if self.operator else "no operator"
        if self.reason == "first" or self.previous is None:
            return f"{now} (first to connect)" if self.operator else now
        why = {
            "handed over": f"handed over by {self.previous}",
            "disconnected": f"{self.previous} left",
            "idle": f"{self.previous} was idle",
        }.get(self.reason, self.reason)
        return f"{now}: {why}"


Payload = (
    Liftoff | Apex | Touchdown | Fall | Reset | GainsChanged | WheelChanged | SensingChanged | GravityChanged
    | TerrainChanged
    | Disturbance | Dragged
    | DisturbanceArmed | Diverged | CommandFailed | Recording | OperatorChanged | ScheduleChanged
    | ControllerChanged | ControllerFailed | Restored | Resumed | Injected
)  # fmt: skip


@dataclasses.dataclass(frozen=True)
class Event:
    """Something that happened at simulation `time` (s) in `run` (counts resets from 0)."""

    time: float
    run: int
    payload: Payload

    @property
    def kind(self) -> EventKind:
        return self.payload.kind

    def describe(self) -> str:
        return self.payload.describe()
