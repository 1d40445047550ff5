"""Named keyframes: a full snapshot plus the settings that define its world, saved as JSON files.

The file carries the state arrays in base64 (float64 / the kernel's raw record, little-endian),
the gains, terrain kind and seed, gravity, sensing and wheel, and a SHA-256 of the arrays so that
a damaged file is refused rather than restored into a wrong state. Reading validates everything
before anything changes. The file is strict JSON (jq, JavaScript's JSON.parse read it): a time that
never comes is null, not the extension `Infinity` that files before version 4 carry (still read).
"""

from __future__ import annotations

import base64
import dataclasses
import hashlib
import json
import math
import re
from collections.abc import Collection

import numpy as np

from hopper.config import Gains, InvalidConfig
from hopper.control.memory import MEMORY
from hopper.errors import HopperError
from hopper.metrics import HopInProgress
from hopper.schedule import KickSchedule
from hopper.sim import Simulation
from hopper.snapshot import Pending, Snapshot, SnapshotMismatch

FORMAT = "hopper-keyframe"
VERSION = 4  # 4: strict JSON (null for a time that never comes); 3: where the terrain window stood;
# 2: the loop's pending disturbances and the hop in progress by name
READS = (1, 2, 3, 4)  # versions read (1: the same state as three lists; 1 and 2 were made on the start window)
MAX_FILE_BYTES = 1_000_000  # a keyframe is ~4 KB; anything far larger is not one
MAX_NAME = 60  # characters


class KeyframeError(HopperError, ValueError):
    """A keyframe file or name that cannot be used; the message says why, in one line."""


@dataclasses.dataclass(frozen=True, eq=False)
class Keyframe:
    name: str
    snapshot: Snapshot

    @property
    def time(self) -> float:
        return self.snapshot.time


def check_name(name: str) -> str:
    name = name.strip()
    if not name:
        raise KeyframeError("a keyframe needs a name")
    if len(name) > MAX_NAME or not name.isprintable():
        raise KeyframeError(f"a keyframe name is at most {MAX_NAME} printable characters")
    return name


def unique_name(name: str, taken: Collection[str]) -> str:
    """`name`, or if it is taken the first free "name (2)", "name (3)", ... (a copy of "a (2)" is
    "a (3)"), cut to MAX_NAME characters."""
    if name not in taken:
        return name
    base = re.sub(r" \(\d+\)$", "", name)
    n = 2
    while True:
        suffix = f" ({n})"
        candidate = base[: MAX_NAME - len(suffix)].rstrip() + suffix
        if candidate not in taken:
            return candidate
        n += 1


def save(sim: Simulation, name: str) -> Keyframe:
    """The simulation now, named (call between ticks, on its thread)."""
    return Keyframe(check_name(name), sim.snapshot())


def apply(sim: Simulation, keyframe: Keyframe) -> None:
    """Restore the keyframe's world and state exactly (call between ticks, on its thread)."""
    sim.restore(keyframe.snapshot)


def _b64(array: np.ndarray) -> str:
    return base64.b64encode(array.tobytes()).decode("ascii")


def _digest(*parts: bytes) -> str:
    h = hashlib.sha256()
    for part in parts:
        h.update(part)
    return h.hexdigest()


def to_json(keyframe: Keyframe) -> str:
    s = keyframe.snapshot
    c = s.config
    physics, sensors = s.physics.astype("<f8"), s.sensors.astype("<f8")
    memory = s.memory.tobytes()
    doc = {
        "format": FORMAT,
        "version": VERSION,
        "name": keyframe.name,
        "time": s.time,
        "config": {
            "gains": dataclasses.asdict(c.gains),
            "terrain": c.terrain,
            "seed": c.seed,
            "gravity": c.gravity,
            "sensing": c.sensing,
            "wheel": c.wheel,
            "timestep": c.timestep,
        },
        "pending": {k: _never_as_null(v) for k, v in dataclasses.asdict(s.pending).items()},
        "schedule": dataclasses.asdict(s.schedule) if s.schedule else None,
        "progress": dataclasses.asdict(s.progress),
        "terrain_first": s.terrain_first,
        "state": {
            "physics": _b64(physics),
            "sensors": _b64(sensors),
            "memory": base64.b64encode(memory).decode("ascii"),
            "memory_itemsize": MEMORY.itemsize,
            "sha256": _digest(physics.tobytes(), sensors.tobytes(), memory),
        },
    }
    return json.dumps(doc, indent=1, allow_nan=False)  # a non-finite value left is a bug: raise, not write it


def _never_as_null(value: float) -> float | None:
    """A time that never comes (inf) as null: strict JSON has no Infinity."""
    return None if value == math.inf else value


def _need(doc: dict, key: str, kind: type | tuple[type, ...]) -> object:
    value = doc.get(key)
    if not isinstance(value, kind) or isinstance(value, bool):
        raise KeyframeError(f"field {key!r} is missing or not a {getattr(kind, '__name__', kind)}")
    return value


def _array(text: object, what: str) -> bytes:
    if not isinstance(text, str):
        raise KeyframeError(f"state field {what!r} is missing")
    try:
        return base64.b64decode(text, validate=True)
    except ValueError:
        raise KeyframeError(f"state field {what!r} is not valid base64 (the file is damaged)") from None


V1_PROGRESS = ("last_touchdown_x", "ground_start", "liftoff_time", "liftoff_z", "liftoff_momentum")


def _fields(value: object, cls: type, what: str, null: float | None = None) -> dict:
    """`value` as the keyword arguments of dataclass `cls`: every field, each a number (or null, read
    as `null`)."""
    names = [f.name for f in dataclasses.fields(cls)]
    if not isinstance(value, dict) or set(value) != set(names):
        raise KeyframeError(f"field {what!r} must hold {', '.join(names)}")
    for name, v in value.items():
        if not (v is None or (isinstance(v, (int, float)) and not isinstance(v, bool))):
            raise KeyframeError(f"field {what}.{name} must be a number, got {v!r}")
    return {k: (float(v) if v is not None else null) for k, v in value.items()}


def _loop_state(doc: dict) -> tuple[Pending, HopInProgress]:
    """The loop's pending disturbances and the hop in progress, from a version 4, 3, 2 or 1 file."""
    if doc.get("version") in (2, 3, 4):  # a pending time is null (never) from version 4, Infinity before
        return Pending(**_fields(doc.get("pending"), Pending, "pending", null=math.inf)), HopInProgress(
            **_fields(doc.get("progress"), HopInProgress, "progress")
        )
    pulse, kick, metrics = doc.get("pulse"), doc.get("kick", [math.inf, 0.0]), doc.get("metrics")
    if not (isinstance(pulse, list) and len(pulse) == 3 and all(isinstance(v, (int, float)) for v in pulse)):
        raise KeyframeError("field 'pulse' must be three numbers")
    if not (isinstance(kick, list) and len(kick) == 2 and all(isinstance(v, (int, float)) for v in kick)):
        raise KeyframeError("field 'kick' must be two numbers")
    if not isinstance(metrics, dict) or set(metrics) != {f"_{n}" for n in V1_PROGRESS}:
        raise KeyframeError("field 'metrics' is missing or incomplete")
    progress = _fields({n: metrics[f"_{n}"] for n in V1_PROGRESS} | {"response_start": None}, HopInProgress, "metrics")
    armed, magnitude, at = map(float, pulse)
    return Pending(armed, magnitude, at, float(kick[0]), float(kick[1])), HopInProgress(**progress)


def from_json(text: str | bytes, sim: Simulation) -> Keyframe:
    """Parse and validate a keyframe file against `sim`'s model; raises KeyframeError, changes nothing.

    Settings not in the file (gait, crater and sensor parameters) are taken from `sim`'s config.
    """
    if len(text) > MAX_FILE_BYTES:
        raise KeyframeError(f"file too large for a keyframe ({len(text)} bytes)")
    try:
        doc = json.loads(text)
    except (ValueError, UnicodeDecodeError) as exc:
        raise KeyframeError(f"not a keyframe file: invalid JSON ({exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise KeyframeError("not a keyframe file (no 'format': 'hopper-keyframe')")
    if doc.get("version") not in READS:
        raise KeyframeError(f"keyframe version {doc.get('version')!r} is not supported (expected one of {READS})")
    name = check_name(str(_need(doc, "name", str)))
    time = float(_need(doc, "time", (int, float)))  # type: ignore[arg-type]
    cfg, state = _need(doc, "config", dict), _need(doc, "state", dict)
    assert isinstance(cfg, dict) and isinstance(state, dict)
    try:
        gains = Gains(**_need(cfg, "gains", dict))  # type: ignore[arg-type]
        config = dataclasses.replace(
            sim.config,
            gains=gains,
            terrain=cfg.get("terrain"),
            seed=cfg.get("seed"),
            gravity=cfg.get("gravity"),
            sensing=cfg.get("sensing"),
            wheel=bool(cfg.get("wheel", True)),
        )
    except (InvalidConfig, TypeError) as exc:
        raise KeyframeError(f"bad settings in the keyframe: {exc}") from None
    if cfg.get("timestep") != sim.config.timestep:
        raise KeyframeError(f"keyframe timestep {cfg.get('timestep')!r} s differs from this model's")
    physics, sensors = _array(state.get("physics"), "physics"), _array(state.get("sensors"), "sensors")
    memory = _array(state.get("memory"), "memory")
    if state.get("sha256") != _digest(physics, sensors, memory):
        raise KeyframeError("the state's checksum does not match (the file is damaged)")
    if state.get("memory_itemsize") != MEMORY.itemsize or len(memory) != MEMORY.itemsize:
        raise KeyframeError("the controller memory has another layout (a keyframe from another version)")
    if len(physics) % 8 or len(sensors) % 8:
        raise KeyframeError("state arrays have a wrong length")
    pending, progress = _loop_state(doc)
    terrain_first = doc.get("terrain_first") if doc.get("version") in (3, 4) else None  # 1, 2: the 30 m strip
    if terrain_first is not None and (not isinstance(terrain_first, int) or isinstance(terrain_first, bool)):
        raise KeyframeError(f"field 'terrain_first' must be an integer grid column, got {terrain_first!r}")
    schedule = doc.get("schedule")
    try:
        schedule = KickSchedule(**schedule) if schedule is not None else None
    except (TypeError, ValueError) as exc:
        raise KeyframeError(f"field 'schedule' is not a valid kick schedule: {exc}") from None
    snap = Snapshot(
        time=time,
        physics=np.frombuffer(physics, "<f8").astype(np.float64),
        sensors=np.frombuffer(sensors, "<f8").astype(np.float64),
        memory=np.frombuffer(memory, MEMORY).copy(),
        pending=pending,
        progress=progress,
        hops=None,
        config=config,
        schedule=schedule,
        terrain_first=terrain_first,
    )
    try:
        sim.check_fits(snap)
    except SnapshotMismatch as exc:
        raise KeyframeError(f"keyframe does not fit this model: {exc}") from None
    if not (np.isfinite(snap.physics).all() and math.isfinite(time) and snap.physics[0] == time):
        raise KeyframeError("the state holds non-finite values or a wrong time")
    return Keyframe(name, snap)
