"""One episode of hopper-sim, simulated (optionally recorded) into its JSON-ready result, and back.

`simulate` runs it for `hopper-sim run` and for `hopper-sim report` (a run's wheel-off twin, or a
result written without a trace); `settings` and `sim_config` write and read a result's settings.
"""

from __future__ import annotations

import dataclasses
import importlib.metadata
import sys
import time
import typing
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from hopper.app.cli_common import fail
from hopper.app.recordings import WHOLE_FILE, FileLimits

from hopper.config import SimConfig
from hopper.interrupts import held, raise_if_stop_requested, stop_requested, wait_for_stop
from hopper.schedule import KickSchedule

if TYPE_CHECKING:
    from hopper.sim import Simulation

T = TypeVar("T")


def version() -> str:
    """The installed package's version, as recorded in every result."""
    try:
        return importlib.metadata.version("hopper-dashboard")
    except importlib.metadata.PackageNotFoundError:  # run from a checkout that was never installed
        return "unknown"


def settings(config: SimConfig, hops: int) -> dict[str, Any]:
    """Everything that reproduces a run, JSON-ready: version, hops asked and the whole SimConfig.

    SI units as in SimConfig: gravity m/s^2, timestep s, gains N m/rad, N m/(rad s), N m s/rad.
    """
    return {"version": version(), "hops": hops, **dataclasses.asdict(config)}


def _from_dict(cls: type[T], data: dict[str, Any]) -> T:
    hints = typing.get_type_hints(cls)
    kwargs = {}
    for field in dataclasses.fields(cls):
        if field.name in data:
            value, kind = data[field.name], hints[field.name]
            if dataclasses.is_dataclass(kind):
                value = _from_dict(kind, value)
            elif isinstance(value, list):  # JSON has no tuples
                value = tuple(value)
            kwargs[field.name] = value
    return cls(**kwargs)


def sim_config(settings: dict[str, Any]) -> SimConfig:
    """The SimConfig a result's `settings` came from (other keys, such as version, are ignored)."""
    return _from_dict(SimConfig, settings)


def simulate(
    config: SimConfig,
    hops: int,
    rrd: Path | None = None,
    viewer: str = "off",
    report: Callable[[dict[str, Any]], None] | None = None,
    trace: bool = True,
    limits: FileLimits = WHOLE_FILE,
    kicks: KickSchedule | None = None,
) -> dict[str, Any]:
    """Run one episode (optionally recorded), `report` its JSON-ready result and return it.

    With a served viewer the recording stays open, served, after the report until Ctrl-C.
    `trace` adds the 100 Hz time series `hopper-sim report` draws (hopper.trace): a Python call
    every tick, ~10 % of a run's wall time here; leave it out where only the metrics count.
    `limits` cut the file into numbered parts (hopper.app.recordings.FileLimits).
    """
    from hopper.sim import Simulation  # keeps `--help` and argument errors fast
    from hopper.trace import TraceRecorder

    sim = Simulation(config)
    recorder = TraceRecorder(config.timestep) if trace else None
    if recorder is not None:
        sim.listeners.append(recorder)
    telemetry, url = None, None
    # Held for the whole run: a stop signal ends it between two bursts of ticks (sim.run's stop)
    # and is raised once the recording is closed, so no moment of it can leave a file unfinished.
    with held():
        try:
            if rrd is not None or viewer != "off":
                from hopper.app.recordings import open_recording
                from hopper.app.rerun_viewer import ViewerError

                try:
                    telemetry, url = open_recording(
                        sim, rrd, viewer, limits, on_stop=_recording_stopped, on_lag=_recording_lag
                    )
                except ViewerError as exc:
                    fail(str(exc))
                if url:
                    print(f"rerun web viewer: {url}", file=sys.stderr)
            start = time.perf_counter()
            if kicks is not None:
                sim.set_schedule(kicks)  # after the recorder attached: the recording has the event
            sim.run(hops, stop=stop_requested)
            raise_if_stop_requested()
            result = {
                "settings": {**settings(config, hops), "schedule": kicks.spec() if kicks else None},
                "seed": config.seed,
                "wheel": config.wheel,
                "fell": sim.fallen,
                "sim_time_s": sim.time,
                "wall_time_s": time.perf_counter() - start,
                "hops": [hop.as_dict() for hop in sim.hops],
                "short": shortfall(sim, hops),
                "controller": controller_summary(sim),
            }
            if recorder is not None:
                result["trace"] = recorder.as_dict()
            if telemetry is not None and limits.rolls:
                result["rrd_parts"] = [str(p) for p in telemetry.parts]  # only with rollover: the numbered files
            if report is not None:
                report(result)
            if telemetry is not None and url:  # the server lives in this process
                telemetry.flush()
                print("serving the recording until Ctrl-C", file=sys.stderr)
                wait_for_stop()
        finally:  # Ctrl-C or SIGTERM still leave a valid recording
            if telemetry is not None:
                telemetry.close()
    return result


def controller_summary(sim: Simulation) -> dict[str, Any]:
    """The controller that flew (spec, class, params), its mean compute per call (us) and its fault."""
    law = sim.failed_law or sim.law  # after a fault the PID flies: report the one that was asked
    trip = getattr(law.controller, "round_trip", None)  # an out-of-process controller (hopper.laws.remote)
    return {
        "round_trip_us": dict(zip(("p50", "p99"), trip()[1:], strict=True)) if trip is not None else None,
        "spec": law.spec,
        "name": law.name,
        "params": law.values,
        "calls": law.calls,
        "compute_us": law.compute_ns / law.calls / 1e3 if law.calls else 0.0,
        "fault": sim.controller_fault,
    }


def shortfall(sim: Simulation, hops: int) -> str | None:
    """Why a run that neither fell nor did its `hops` hops stopped, in one line; None if it did."""
    done = sum(h.completed for h in sim.hops)
    if sim.fallen or done >= hops:
        return None
    x = sim.state().x  # world x: the terrain has no end (hopper.terrain.window)
    limit = f"the run's limit of {sim.time:.0f} s simulated"
    return f"{done} of {hops} hops done when {limit} ran out (the torso at x = {x:.2f} m)"


def _recording_stopped(message: str) -> None:
    """A recording that stopped by itself (a full disk): the run goes on."""
    print(f"hopper-sim: warning: {message}", file=sys.stderr)


def _recording_lag(message: str | None) -> None:
    """The recording's file fell behind what it was sent (a slow disk), or caught up again."""
    print(f"hopper-sim: warning: recording: {message or 'the file has caught up'}", file=sys.stderr)
