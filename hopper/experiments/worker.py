"""Run episodes on one Simulation built once: each episode reconfigures it in place and resets it.

A fresh `Simulation(config)` and a reused one give identical episodes (tests/test_sweep.py), so a
sweep's rows are what `hopper-sim run` gives for the same settings.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

from hopper.config import SimConfig
from hopper.controllers import ControllerError
from hopper.experiments.spec import Episode
from hopper.experiments.stress import run_episode
from hopper.metrics import HopMetrics
from hopper.sim import Simulation
from hopper.trace import TraceRecorder


@dataclasses.dataclass(frozen=True)
class EpisodeResult:
    """What one episode did: its hops and the figures the episodes table holds."""

    episode: Episode
    hops: tuple[HopMetrics, ...]
    fell: bool
    sim_time_s: float
    wall_s: float
    saturation_s: float  # s, every hop's plus the unfinished one's
    momentum_used_pct: float  # the most wheel momentum a flight used, % of capacity (hopper.metrics)
    applied: bool  # the disturbance happened (its phase came); True without one
    controller_fault: str = ""  # why the controller could not fly or was replaced by the PID; "" if neither
    compute_us: float = 0.0  # us, the controller's mean call (0 for the compiled PID)
    trace: dict[str, Any] | None = None  # the 100 Hz time series (TraceRecorder.as_dict) if the episode asked

    def row(self) -> dict[str, Any]:
        """The episodes-table row (hopper.experiments.store.EPISODE_COLUMNS)."""
        done = [h for h in self.hops if h.completed]
        return {
            "episode_id": self.episode.episode_id,
            **self.episode.settings(),
            "hops_completed": len(done),
            "fell": self.fell,
            "worst_landing_deg": max((h.landing_pitch_deg for h in done), default=0.0),
            "peak_pitch_deg": max((h.peak_pitch_deg for h in self.hops), default=0.0),
            "rms_pitch_rate_deg_s": max((h.rms_pitch_rate_deg_s for h in self.hops), default=0.0),
            "momentum_used_pct": self.momentum_used_pct,
            "saturation_s": self.saturation_s,
            "sim_time_s": self.sim_time_s,
            "wall_s": self.wall_s,
            "controller_fault": self.controller_fault,
            "energy_j_per_hop": energy_per_hop(self),
            "disturbance_applied": self.applied,
        }

    def hop_rows(self) -> list[dict[str, Any]]:
        """The hops-table rows: the settings, then `hop` (1-based) and every HopMetrics field."""
        head = {"episode_id": self.episode.episode_id, **self.episode.settings()}
        return [{**head, "hop": hop.index, **hop.as_dict()} for hop in self.hops]


def energy_per_hop(result: EpisodeResult) -> float:
    """An episode's mean electrical energy per hop, wheel and legs (J): over its completed hops, or
    over the flight that fell if none completed, 0 without a hop."""
    hops = [h for h in result.hops if h.completed] or list(result.hops)
    return sum(h.wheel_energy_j + h.leg_energy_j for h in hops) / len(hops) if hops else 0.0


def _compute_us(sim: Simulation) -> float:
    law = sim.failed_law or sim.law
    return law.compute_ns / law.calls / 1e3 if law.calls else 0.0


class Worker:
    """One process's simulation, built at its first episode and reused (reset, not rebuilt) after."""

    def __init__(self) -> None:
        self.sim: Simulation | None = None
        self.built = 0  # models compiled (1 after the first episode, whatever follows)

    def warm(self) -> None:
        """Build the model and load the compiled controller now (start-up), not in the first episode."""
        if self.sim is None:
            self._prepare(SimConfig())

    def run_chunk(self, episodes: list[Episode]) -> list[EpisodeResult]:
        return [self.run(e) for e in episodes]

    def run(self, episode: Episode) -> EpisodeResult:
        """Simulate one episode to its hops, a fall or the time limit (as `hopper-sim run` does)."""
        start = time.perf_counter()
        try:
            sim = self._prepare(episode.config())
        except ControllerError as exc:  # the episode fails with its cause; the batch goes on
            wall = time.perf_counter() - start  # an undisturbed episode's disturbance counts as applied
            return EpisodeResult(episode, (), False, 0.0, wall, 0.0, 0.0, episode.disturbance is None, str(exc))
        hops, schedule = episode.hops_target, episode.disturbance
        # A listener every tick costs ~10 % of the episode's wall time (no compiled bursts): only if asked.
        recorder = TraceRecorder(sim.config.timestep) if episode.trace else None
        if recorder is not None:
            sim.listeners.append(recorder)
        try:
            applied = run_episode(sim, hops, schedule)
        finally:
            if recorder is not None:
                sim.listeners.remove(recorder)  # the next episode on this simulation records nothing of it
        mem = sim.controller.mem
        saturation = sum(h.saturation_time_s for h in sim.hops) + float(mem["acc_saturation"][0])
        return EpisodeResult(
            episode=episode,
            hops=tuple(sim.hops),
            fell=sim.fallen,
            sim_time_s=sim.time,
            wall_s=time.perf_counter() - start,
            saturation_s=saturation,
            momentum_used_pct=sim.metrics.flight_momentum_pct(),
            applied=applied,
            controller_fault=sim.controller_fault or "",
            compute_us=_compute_us(sim),
            trace=recorder.as_dict() if recorder is not None else None,
        )

    def _prepare(self, config: SimConfig) -> Simulation:
        """The simulation set to `config`, standing at the start, as Simulation(config) leaves it."""
        if self.sim is None or self.sim.config.model != config.model:  # another robot: build its model
            self.sim = Simulation(config)
            self.built += 1
        else:
            self.sim.start_over(config)
        return self.sim
