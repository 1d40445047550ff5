"""A run as the figures see it: settings, hop table and a time series, from `hopper-sim` JSON."""

from __future__ import annotations

import dataclasses
import json
from typing import Any

import numpy as np

from hopper.config import SimConfig
from hopper.errors import ModelError
from hopper.robot import PACKAGED
from hopper.trace import TRACE_COLUMNS

FLOAT_COLUMNS = tuple(c for c in TRACE_COLUMNS if c != "phase")


@dataclasses.dataclass(frozen=True, kw_only=True)
class Run:
    """One episode. `trace` holds TRACE_COLUMNS as arrays (shape (n,); phase as str); `hops` the
    HopMetrics of each hop as dicts (hopper.metrics names and units)."""

    label: str
    wheel: bool
    fell: bool
    settings: dict[str, Any]  # hopper-sim's `settings` (SimConfig as a dict), or what a recording says
    hops: list[dict[str, Any]]
    trace: dict[str, np.ndarray]
    source: str  # where it came from: "run JSON", "compare JSON", ".rrd", "re-simulated"
    fault: str = ""  # why the controller was replaced by the PID mid-run (its later flights the PID's), "" if not

    @property
    def seed(self) -> int | None:
        return self.settings.get("seed")

    def wheel_torque_limit(self) -> float | None:
        """N m, the flown robot's wheel torque limit: its `--model`'s (hopper.robot), the packaged
        one's without; None if that model cannot be read now."""
        model = self.settings.get("model")
        if model is None:
            return PACKAGED.wheel_torque_limit
        from hopper.model import robot_of  # MuJoCo's import, paid only for a user's model

        try:
            return robot_of(SimConfig(model=model, terrain="flat")).wheel_torque_limit
        except ModelError:
            return None

    def flights(self) -> list[tuple[float, float]]:
        """(liftoff, touchdown) times of each hop, s."""
        return [(h["touchdown_time_s"] - h["flight_time_s"], h["touchdown_time_s"]) for h in self.hops]


def wheel_label(wheel: bool) -> str:
    return "wheel on" if wheel else "wheel off (zero torque, free to spin)"


def trace_arrays(trace: dict[str, Any]) -> dict[str, np.ndarray]:
    """A JSON trace's columns as numpy arrays; KeyError names a missing column."""
    missing = [c for c in TRACE_COLUMNS if c not in trace]
    if missing:
        raise KeyError(f"the trace lacks {', '.join(missing)}")
    out = {c: np.asarray(trace[c], dtype=float) for c in FLOAT_COLUMNS}
    out["phase"] = np.asarray(trace["phase"], dtype=str)
    return out


# The hop keys the figures and tables read (hopper.report.build.HOP_TABLE, run_figures), all numbers.
HOP_NUMBERS = ("index", "distance_m", "apex_height_m", "flight_time_s", "peak_pitch_deg", "rms_pitch_rate_deg_s",
               "landing_pitch_deg", "saturation_time_s", "peak_wheel_rpm", "touchdown_time_s")  # fmt: skip


def _json_type(value: Any) -> str:  # noqa: ANN401
    """What a JSON value is, in JSON's words ("a string", "null")."""
    if value is None or isinstance(value, bool):
        return {None: "null", True: "true", False: "false"}[value]
    names = {str: "a string", int: "a number", float: "a number", list: "a list", dict: "an object"}
    return names.get(type(value), type(value).__name__)


def hop_dicts(hops: Any) -> list[dict[str, Any]]:  # noqa: ANN401 (a hand-edited JSON may hold anything)
    """A result's `hops`, checked: a list of objects with a number for each of HOP_NUMBERS and a
    true/false `completed`; ValueError, one line, naming the first thing that is not."""
    if not isinstance(hops, list):
        raise ValueError(f"hops must be a list of hops, got {_json_type(hops)}")
    for i, hop in enumerate(hops):
        if not isinstance(hop, dict):
            raise ValueError(f"hops[{i}] must be an object, got {_json_type(hop)}")
        for key in HOP_NUMBERS:
            value = hop.get(key)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"hops[{i}].{key} must be a number, got {json.dumps(value)}")
        if not isinstance(hop.get("completed"), bool):
            raise ValueError(f"hops[{i}].completed must be true or false, got {json.dumps(hop.get('completed'))}")
    return list(hops)


def run_from_result(result: dict[str, Any], source: str) -> Run:
    """A Run from one result of `hopper-sim run --json` (or one of `compare --json`'s runs).

    The result must hold a `trace` (hopper-sim writes one since the report existed; an older
    result is re-simulated from its settings by the CLI first). ValueError, one line, for a
    result whose settings or hops are not what hopper-sim writes (a hand-edited one)."""
    settings = result["settings"]
    if not isinstance(settings, dict):
        raise ValueError(f"settings must be an object, got {_json_type(settings)}")
    wheel = bool(result.get("wheel", settings.get("wheel", True)))
    return Run(
        label=f"seed {settings.get('seed', '?')}, {wheel_label(wheel)}",
        wheel=wheel,
        fell=bool(result["fell"]),
        settings=settings,
        hops=hop_dicts(result["hops"]),
        trace=trace_arrays(result["trace"]),
        source=source,
        fault=fault_of(result),
    )


def fault_of(result: dict[str, Any]) -> str:
    """A result's controller fault: compare's runs hold it as `fault`, run's JSON as `controller.fault`
    ("" for none, or for a JSON written before either)."""
    controller = result.get("controller")
    fault = result.get("fault") or (controller.get("fault") if isinstance(controller, dict) else None)
    return fault if isinstance(fault, str) else ""


def kind_of(document: dict[str, Any]) -> str:
    """'run' for `hopper-sim run --json`, 'compare' for `compare --json`; ValueError otherwise."""
    if "runs" in document and isinstance(document["runs"], list):
        return "compare"
    if "settings" in document and "hops" in document:
        return "run"
    raise ValueError(
        "not a JSON that hopper-sim report draws: a run or compare result (no 'settings' and 'hops', nor 'runs'), "
        "a league or a stand document (no 'kind')"
    )


def pair_runs(runs: list[Run]) -> list[tuple[Run | None, Run | None]]:
    """(wheel on, wheel off) per seed, in seed order; either side may be missing."""
    by_seed: dict[Any, dict[bool, Run]] = {}
    for run in runs:
        by_seed.setdefault(run.seed, {})[run.wheel] = run
    return [(sides.get(True), sides.get(False)) for _, sides in sorted(by_seed.items(), key=lambda kv: str(kv[0]))]
