"""A run read back from a rerun `.rrd` recording with rerun's own reader (rerun.chunk.RrdReader).

What hopper.telemetry writes (hopper/telemetry/schema.py): `signals` (a struct per 1 kHz tick:
pitch_deg, pitch_rate_deg_s, wheel_rpm, wheel_torque_nm, ...), `world/tf` (body poses at 50 Hz,
the torso's translation among them), `phase` (state changes), `hops` (a row per hop, a
component per HopMetrics field) and the `config` recording property (terrain, seed, gravity,
gains, wheel, sensing). The figures want the trace of hopper.trace, so signals are thinned to
the trace's rate and the torso's x, z interpolated onto them.
"""

from __future__ import annotations

import warnings
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
from rerun.chunk import RrdReader

from hopper.errors import HopperError
from hopper.metrics import HopMetrics
from hopper.report.runs import Run, wheel_label
from hopper.trace import TRACE_HZ

SIGNAL_FIELDS = ("pitch_deg", "pitch_rate_deg_s", "wheel_rpm", "wheel_torque_nm")
_TABLES = ("/signals", "/world/tf", "/phase", "/hops", "/__properties/config")


class RecordingError(HopperError, ValueError):
    """A file that is not a hopper recording (or lacks what the figures need)."""


def _tables(path: Path) -> dict[str, pa.Table]:
    batches: dict[str, list[pa.RecordBatch]] = defaultdict(list)
    try:
        with warnings.catch_warnings():
            # A file without rerun's footer (truncated, or written by an older rerun) warns on two lines
            # that store() is unsupported; stream() is all this reads, and a bad file gets the error below.
            warnings.filterwarnings("ignore", message="RRD file has no footer")
            for chunk in RrdReader(path).stream():
                if chunk.entity_path in _TABLES:
                    batches[chunk.entity_path].append(chunk.to_record_batch())
    except Exception as exc:  # rerun raises its own types for a bad file
        raise RecordingError(f"{path}: cannot read it as a rerun recording ({exc})") from None
    return {entity: pa.Table.from_batches(b) for entity, b in batches.items() if b}


def _seconds(table: pa.Table) -> np.ndarray:
    return table.column("sim_time").cast(pa.int64()).to_numpy() / 1e9


def _first(table: pa.Table, name: str) -> list[Any]:
    """One value per row of a component column (each row holds a one-element list)."""
    return [cell[0] if cell else None for cell in table.column(name).to_pylist()]


def read_run(path: Path, hz: float = TRACE_HZ) -> Run:
    """The recording at `path` as a Run (time series at `hz`, hop table, settings)."""
    tables = _tables(path)
    if "/signals" not in tables:
        raise RecordingError(f"{path}: no 'signals' entity: not a hopper-sim recording")
    signals = tables["/signals"].sort_by("sim_time")
    t = _seconds(signals)
    struct = pa.chunked_array([c.flatten() for c in signals.column("signals").chunks]).combine_chunks()
    step = max(1, round(1.0 / (hz * float(np.median(np.diff(t))))) if len(t) > 1 else 1)
    keep = np.arange(0, len(t), step)
    trace: dict[str, np.ndarray] = {"t_s": t[keep]}
    for name in SIGNAL_FIELDS:
        trace[name] = struct.field(name).to_numpy(zero_copy_only=False).astype(float)[keep]
    trace["x_m"], trace["z_m"] = _torso(tables.get("/world/tf"), trace["t_s"])
    trace["phase"] = _phases(tables.get("/phase"), trace["t_s"])
    settings = _settings(tables.get("/__properties/config"))
    hops = _hops(tables.get("/hops"))
    wheel = bool(settings.get("wheel", True))
    fell = bool(hops and not hops[-1]["completed"])
    return Run(label=f"seed {settings.get('seed', '?')}, {wheel_label(wheel)}", wheel=wheel, fell=fell,
               settings=settings, hops=hops, trace=trace, source=".rrd")  # fmt: skip


def _torso(tf: pa.Table | None, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The torso's world x, z (m) at times t, interpolated from its 50 Hz poses (NaN without)."""
    if tf is None:
        return np.full(t.shape, np.nan), np.full(t.shape, np.nan)
    frames = _first(tf, "Transform3D:child_frame")
    rows = [i for i, f in enumerate(frames) if f == "torso"]
    if not rows:
        return np.full(t.shape, np.nan), np.full(t.shape, np.nan)
    torso = tf.take(pa.array(rows))
    times = _seconds(torso)
    xyz = np.array(_first(torso, "Transform3D:translation"), dtype=float)
    order = np.argsort(times, kind="stable")
    return np.interp(t, times[order], xyz[order, 0]), np.interp(t, times[order], xyz[order, 2])


def _phases(phase: pa.Table | None, t: np.ndarray) -> np.ndarray:
    """The phase label in force at each time (the last change at or before it)."""
    if phase is None:
        return np.full(t.shape, "", dtype=object).astype(str)
    phase = phase.sort_by("sim_time")
    times, labels = _seconds(phase), np.array(_first(phase, "StateChange:state"), dtype=str)
    index = np.searchsorted(times, t, side="right") - 1
    return np.where(index >= 0, labels[np.clip(index, 0, None)], "")


def _settings(config: pa.Table | None) -> dict[str, Any]:
    """The last `config` property sent (the live settings when the recording ended)."""
    if config is None or config.num_rows == 0:
        return {}
    row = config.slice(config.num_rows - 1).to_pylist()[0]
    flat = {k: (v[0] if isinstance(v, list) and v else v) for k, v in row.items() if not k.startswith("rerun.")}
    gains = {k: flat.pop(k) for k in ("kp", "ki", "kd") if k in flat}
    return {**flat, "gains": gains} if gains else flat


def _hops(hops: pa.Table | None) -> list[dict[str, Any]]:
    """The hop table's rows as HopMetrics dicts (the recording rounds them: 1 mm, 0.01 deg, ...)."""
    if hops is None:
        return []
    hops = hops.sort_by("sim_time")
    names = [f.name for f in HopMetrics.__dataclass_fields__.values()]
    columns = {name: _first(hops, name) for name in names if name in hops.column_names}
    return [{name: columns[name][i] for name in columns} for i in range(hops.num_rows)]
