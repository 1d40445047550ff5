"""Rerun telemetry of a Simulation: 1 kHz signals, phases, events, per-hop metrics and 3D poses."""

from hopper.telemetry.blueprint import default_blueprint
from hopper.telemetry.files import check_writable, part_path, session_path
from hopper.telemetry.recorder import BATCH_TICKS, FLUSH_WALL_S, POSE_EVERY_TICKS, Telemetry
from hopper.telemetry.schema import APPLICATION_ID, HOP, HOP_DECIMALS, SIGNALS, TIME, hop_values

__all__ = [
    "APPLICATION_ID",
    "BATCH_TICKS",
    "FLUSH_WALL_S",
    "HOP",
    "HOP_DECIMALS",
    "POSE_EVERY_TICKS",
    "SIGNALS",
    "TIME",
    "Telemetry",
    "check_writable",
    "default_blueprint",
    "hop_values",
    "part_path",
    "session_path",
]
