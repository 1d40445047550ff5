"""Our own `.rrd` recordings as hopper logs, read with rerun's own reader (rerun.chunk.RrdReader).

A recording (hopper/telemetry/schema.py) keeps at 1 kHz the `signals` struct (pitch, pitch rate,
wheel rpm, wheel torque in float32; leg angles and torques, foot forces in float16) and at 50 Hz
the body poses (`world/tf`). The wheel command is the torque the controller asked (`wheel_cmd_nm`,
before the motor's delay line and torque-speed envelope); the legs' are the torques applied. A
recording made before the command was kept has the applied wheel torque stand in for it, as the
Log's source says. The IMU as the controller read it is not kept: `gyro_pitch` is MuJoCo's gyro
(noise-free). The state: `pitch` and `pitch_rate` at 1 kHz; `x`, `z` the torso frame's position
(its CoM in models/hopper.xml) and `vx`, `vz` its central differences, at the 50 Hz poses
interpolated. The world (terrain, seed, gravity, model, the commands' delay and wheel motor) is the
recording's `config` property, if it never changed; an older recording's delay is 0 ticks (its
torques are the applied ones).
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pyarrow as pa
from rerun.chunk import RrdReader

from hopper.layout import LEG_JOINTS
from hopper.logs.schema import Log, LogError, located
from hopper.logs.world import World, from_meta

DEG = math.pi / 180.0
RPM = 2.0 * math.pi / 60.0
COMMAND = "wheel_cmd_nm"  # the wheel torque asked (recordings made since it was kept)
# Log column <- (the recording's signal field, factor to SI).
FROM_SIGNALS = {
    "wheel_torque_cmd": ("wheel_torque_nm", 1.0),  # applied, at the wheel: COMMAND replaces it where recorded
    **{f"{j}_torque_cmd": (f"{j}_torque_nm", 1.0) for j in LEG_JOINTS},  # applied
    "gyro_pitch": ("pitch_rate_deg_s", DEG),
    "wheel_speed": ("wheel_rpm", RPM),
    **{j: (f"{j}_deg", DEG) for j in LEG_JOINTS},
    "foot_L_force": ("foot_L_n", 1.0),
    "foot_R_force": ("foot_R_n", 1.0),
    "pitch": ("pitch_deg", DEG),
    "pitch_rate": ("pitch_rate_deg_s", DEG),
}
NOTE = "our .rrd: leg torques applied, gyro noise-free, x z vx vz from 50 Hz poses"
OLD_NOTE = "our .rrd: applied torques stand in for the commands, gyro noise-free, x z vx vz from 50 Hz poses"
WORLD_KEYS = ("terrain", "seed", "gravity", "model")
MOTOR_KEYS = ("delay_ticks", "wheel_torque_limit", "wheel_damping")  # recorded with COMMAND


def _chunks(path: Path) -> tuple[list[pa.RecordBatch], list[pa.RecordBatch]]:
    """The recording's `signals` and `world/tf` record batches; LogError if it is no rerun recording."""
    signals: list[pa.RecordBatch] = []
    poses: list[pa.RecordBatch] = []
    try:
        with warnings.catch_warnings():  # rerun warns of a file without its footer: said below if it is torn
            warnings.filterwarnings("ignore", "RRD file has no footer")
            reader = RrdReader(path)
        for chunk in reader.stream().filter(content=["/signals", "/world/tf"], is_static=False):
            (signals if chunk.entity_path == "/signals" else poses).append(chunk.to_record_batch())
    except Exception as exc:  # rerun raises its own types (and ValueError, RuntimeError) for a bad file
        why = str(exc).splitlines()[0].replace(f"Failed to read RRD file at {path}: ", "")
        raise LogError(f"{path}: not a rerun recording, or one cut short ({why})") from None
    return signals, poses


def _world(path: Path, commanded: bool) -> World | None:
    """The recording's world from its `config` property (hopper.telemetry.recorder), None if it has
    none or it changed during the recording (a Regenerate: which one would the log be?). `commanded`:
    the recording keeps the wheel command, and with it the commands' delay and motor."""
    rows = []
    for chunk in RrdReader(path).stream().filter(content=["/__properties/config"]):
        rows += chunk.to_record_batch().to_pylist()
    keys = WORLD_KEYS + (MOTOR_KEYS if commanded else ())
    seen = {tuple((r.get(k) or [""])[0] for k in keys) for r in rows}
    if len(seen) != 1:
        return None
    meta = {k: str(v) for k, v in zip(keys, seen.pop(), strict=True)}
    if not commanded:  # its wheel "commands" are the torques applied, after the motor's delay: a replay adds none
        meta["delay_ticks"] = "0"
    try:
        return from_meta(meta)
    except ValueError as exc:
        raise LogError(f"{path}: the recording's config property: {exc}") from None


def _seconds(table: pa.Table) -> np.ndarray:
    return table.column("sim_time").cast(pa.int64()).to_numpy() / 1e9


def _torso(poses: list[pa.RecordBatch], time: np.ndarray, path: Path) -> dict[str, np.ndarray]:
    """x, z (m) and vx, vz (m/s) of the torso at `time`, from its 50 Hz poses."""
    if not poses:
        raise LogError(f"{path}: no world/tf poses in the recording (the torso's position)")
    tf = pa.Table.from_batches(poses)
    frames = pa.chunked_array([c.flatten() for c in tf.column("Transform3D:child_frame").chunks])
    rows = np.flatnonzero(np.asarray(frames.to_pylist(), dtype=object) == "torso")
    if rows.size < 2:
        raise LogError(f"{path}: fewer than 2 torso poses in world/tf")
    torso = tf.take(pa.array(rows)).sort_by("sim_time")
    t = _seconds(torso)
    translations = pa.chunked_array([c.flatten() for c in torso.column("Transform3D:translation").chunks])
    xyz = np.asarray(translations.combine_chunks().flatten().to_numpy(zero_copy_only=False), dtype=float)
    xyz = xyz.reshape(-1, 3)
    out = {}
    for axis, name in ((0, "x"), (2, "z")):
        position, velocity = xyz[:, axis], np.gradient(xyz[:, axis], t)
        # Samples before the first pose or after the last (up to 20 ms) carry on at the end's velocity.
        ends = np.clip(time, t[0], t[-1])
        out[name] = np.interp(ends, t, position) + np.interp(ends, t, velocity) * (time - ends)
        out[f"v{name}"] = np.interp(time, t, velocity)
    return out


def read(path: str | Path) -> Log:
    """Our recording at `path` as a Log (see the module's docstring for what stands in for what)."""
    path = Path(path)
    if path.stat().st_size == 0:
        raise LogError(f"{path}: empty file (not a rerun recording)")
    batches, poses = _chunks(path)
    if not batches:
        raise LogError(f"{path}: no 'signals' entity: not a hopper recording")
    table = pa.Table.from_batches(batches).sort_by("sim_time")
    time = _seconds(table)
    struct = pa.chunked_array([c.flatten() for c in table.column("signals").chunks]).combine_chunks()
    recorded = set(struct.type.names) if pa.types.is_struct(struct.type) else set()
    missing = sorted({field for field, _ in FROM_SIGNALS.values()} - recorded)
    if missing:
        raise LogError(f"{path}: the recording's signals lack {', '.join(missing)}: not a hopper recording")
    commanded = COMMAND in recorded
    fields = FROM_SIGNALS | ({"wheel_torque_cmd": (COMMAND, 1.0)} if commanded else {})
    signals = {
        name: struct.field(field).to_numpy(zero_copy_only=False).astype(np.float64) * factor
        for name, (field, factor) in fields.items()
    }
    signals |= _torso(poses, time, path)
    note = NOTE if commanded else OLD_NOTE
    return located(time, signals, f"{path} ({note})", lambda i: f"sim_time {time[i]:.3f} s", _world(path, commanded))
