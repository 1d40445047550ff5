"""A hopper log: the signals a real robot (or the simulation) records, one documented schema.

Readers (CSV, MCAP, our own .rrd) turn a file into a `Log`; replay and identification read only
`Log`. Every column is SI (s, rad, rad/s, m, m/s, m/s^2, N m, N); angles and pitch follow the
simulation's conventions (pitch + = nose down; the wheel's angle and speed relative to the torso;
leg joints as models/hopper.xml measures them).

Commands are what was sent to the actuators: the wheel torque at the wheel (N m, after the gear,
before the motor's torque-speed envelope) and the four leg joint torques (N m). Measurements are
the sensors. The state columns (a motion-capture system's, or the simulation's truth) are optional:
without them a replay starts from what the sensors give. The accelerometer's columns are optional too.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable
from typing import NamedTuple

import numpy as np

from hopper.errors import HopperError
from hopper.layout import LEG_JOINTS
from hopper.logs import plausible
from hopper.logs.world import World


class Column(NamedTuple):
    """One signal of the schema: its name, unit, and what it is."""

    name: str
    unit: str
    what: str


TIME = Column("time", "s", "sample time, strictly increasing")
COMMANDS = (
    Column("wheel_torque_cmd", "N m", "wheel torque commanded, at the wheel"),
    *(Column(f"{j}_torque_cmd", "N m", f"{j} joint torque commanded") for j in LEG_JOINTS),
)
MEASUREMENTS = (
    Column("gyro_pitch", "rad/s", "IMU gyro, body pitch axis"),
    Column("wheel_speed", "rad/s", "wheel encoder, relative to the torso"),
    *(Column(f"{j}", "rad", f"{j} joint encoder") for j in LEG_JOINTS),
    Column("foot_L_force", "N", "left foot contact normal force (0 off the ground)"),
    Column("foot_R_force", "N", "right foot contact normal force"),
)
ACCEL = (  # optional: a log without them (our own .rrd) still replays and identifies the wheel loop
    Column("accel_x", "m/s^2", "IMU specific force, torso x axis"),
    Column("accel_z", "m/s^2", "IMU specific force, torso z axis"),
)
STATE = (
    Column("x", "m", "torso CoM x, world"),
    Column("z", "m", "torso CoM z, world"),
    Column("vx", "m/s", "torso CoM x velocity"),
    Column("vz", "m/s", "torso CoM z velocity"),
    Column("pitch", "rad", "torso pitch, true (nose down +)"),
    Column("pitch_rate", "rad/s", "torso pitch rate, true"),
)
REQUIRED = (TIME, *COMMANDS, *MEASUREMENTS)
OPTIONAL = (*ACCEL, *STATE)
COLUMNS = {c.name: c for c in (*REQUIRED, *OPTIONAL)}


# The units a reader accepts for a column, by the column's SI unit, each with its factor to SI.
UNITS: dict[str, dict[str, float]] = {
    "s": {"s": 1.0, "ms": 1e-3},
    "rad": {"rad": 1.0, "deg": math.pi / 180.0},
    "rad/s": {"rad/s": 1.0, "deg/s": math.pi / 180.0, "rpm": 2.0 * math.pi / 60.0},
    "m": {"m": 1.0},
    "m/s": {"m/s": 1.0},
    "m/s^2": {"m/s^2": 1.0},
    "N m": {"N m": 1.0, "Nm": 1.0},
    "N": {"N": 1.0},
}


class LogError(HopperError, ValueError):
    """A log that cannot be read as the schema says, with what and where in one line.

    `sample` is the index of the offending sample where there is one, so a reader can say where
    it is in its file (a CSV's line).
    """

    def __init__(self, message: str, sample: int | None = None) -> None:
        super().__init__(message)
        self.sample = sample


@dataclasses.dataclass(frozen=True)
class Log:
    """A hopper log in the schema's units: `signals[name]` has one float64 value per `time`.

    `gaps` lists (start, end) s spans where samples are missing (the spacing jumps past
    GAP_FACTOR x the median period); readers mark them rather than refuse them.
    """

    time: np.ndarray  # s, (n,), strictly increasing
    signals: dict[str, np.ndarray]  # column name -> (n,) float64
    source: str  # the file it came from, for messages
    gaps: tuple[tuple[float, float], ...] = ()
    world: World | None = None  # where it was recorded, when the file says (hopper.logs.world)

    def __post_init__(self) -> None:
        validate(self)

    @property
    def period(self) -> float:
        """The median sample period, s."""
        return float(np.median(np.diff(self.time))) if len(self.time) > 1 else float("nan")

    def has_state(self) -> bool:
        return all(c.name in self.signals for c in STATE)

    def between(self, start: float, end: float) -> Log:
        """The samples with start <= time < end (s)."""
        keep = (self.time >= start) & (self.time < end)
        gaps = tuple((a, b) for a, b in self.gaps if b > start and a < end)
        return Log(self.time[keep], {k: v[keep] for k, v in self.signals.items()}, self.source, gaps, self.world)


GAP_FACTOR = 3.0  # a spacing above this many median periods is a gap


def find_gaps(time: np.ndarray) -> tuple[tuple[float, float], ...]:
    """The (start, end) spans where consecutive samples are more than GAP_FACTOR periods apart."""
    if len(time) < 3:
        return ()
    step = np.diff(time)
    where = np.flatnonzero(step > GAP_FACTOR * np.median(step))
    return tuple((float(time[i]), float(time[i + 1])) for i in where)


def validate(log: Log) -> None:
    """LogError for a log that breaks the schema: missing or unknown columns, ragged lengths, time
    not strictly increasing, non-finite values, a sample rate or a value no robot's log holds
    (hopper.logs.plausible). The message says which column and which sample."""
    where = log.source
    time = log.time
    if time.ndim != 1 or len(time) < 2:
        raise LogError(f"{where}: needs at least 2 samples, got {len(time)}")
    check_columns(("time", *log.signals), where)
    bad = np.flatnonzero(~np.isfinite(time))
    if bad.size:
        raise LogError(f"{where}: time is not finite at sample {bad[0]}", int(bad[0]))
    back = np.flatnonzero(np.diff(time) <= 0.0)
    if back.size:
        i = int(back[0]) + 1
        raise LogError(
            f"{where}: time goes backwards or repeats at sample {i} ({time[i - 1]:.6f} s then {time[i]:.6f} s)", i
        )
    rate = plausible.rate_problem(float(np.median(np.diff(time))))
    if rate is not None:
        raise LogError(f"{where}: {rate}")
    for name, values in log.signals.items():
        if values.shape != time.shape:
            raise LogError(f"{where}: column {name} has {values.shape[0]} samples, time has {time.shape[0]}")
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            i = int(bad[0])
            raise LogError(f"{where}: column {name} is not finite at sample {i} (t = {time[i]:.6f} s)", i)
        i = plausible.beyond(name, values)
        if i is not None:
            at = f"sample {i} (t = {time[i]:.6f} s)"
            raise LogError(f"{where}: {plausible.value_problem(name, COLUMNS[name].unit, values[i], at)}", i)


def check_columns(names: Iterable[str], where: str) -> None:
    """LogError unless `names` (time among them) hold every required column and only the schema's."""
    names = set(names)
    missing = [c.name for c in REQUIRED if c.name not in names]
    unknown = sorted(names - set(COLUMNS))
    if missing:  # both at once: a misspelt column is one of each
        also = f", unknown column(s) {', '.join(unknown)}" if unknown else ""
        raise LogError(f"{where}: missing column(s) {', '.join(missing)}{also}; the schema needs {schema_line()}")
    if unknown:
        raise LogError(f"{where}: unknown column(s) {', '.join(unknown)}; the schema has {', '.join(COLUMNS)}")


def to_si(name: str, unit: str, where: str) -> float:
    """The factor from `unit` to column `name`'s SI unit; LogError naming the column and the units allowed."""
    allowed = UNITS[COLUMNS[name].unit]
    if unit not in allowed:
        given = f"unit '{unit}'" if unit else "no unit"
        raise LogError(f"{where}: column {name} has {given}; allowed: {', '.join(allowed)}")
    return allowed[unit]


def schema_line() -> str:
    """The required columns with their units, for error messages."""
    return ", ".join(f"{c.name} [{c.unit}]" for c in REQUIRED)


def located(
    time: np.ndarray,
    signals: dict[str, np.ndarray],
    source: str,
    where: Callable[[int], str],
    world: World | None = None,
) -> Log:
    """The Log of a reader's columns, its gaps found; a LogError at a sample says `where(sample)` it
    is in the file too (a CSV's line, an MCAP's message)."""
    try:
        return Log(time, signals, source, find_gaps(time), world)
    except LogError as exc:
        if exc.sample is None:
            raise
        raise LogError(f"{exc} ({where(exc.sample)})", exc.sample) from None
