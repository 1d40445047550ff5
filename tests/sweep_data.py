"""A small sweep in the sweep helper's Parquet format, built from real simulated episodes (tests only)."""

from __future__ import annotations

import hashlib
import itertools
import json
import time
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from hopper.config import Gains, SimConfig
from hopper.control import Phase
from hopper.sim import Simulation

# A controller file (write it as flaky.py): a PD that faults (NaN) from its second flight on, so an
# episode of 2 hops or more ends with the built-in PID flying in its place.
FLAKY = """
from hopper.controllers import Param


class Flaky:
    \"\"\"A PD that returns NaN from its second flight on.\"\"\"

    params = (Param("kp", 450.0, (0.0, 2000.0), "N m/rad"), Param("kd", 30.0, (0.0, 100.0), "N m s/rad"))

    def reset(self, obs):
        self.flights = getattr(self, "flights", 0) + 1

    def __call__(self, obs):
        return float("nan") if getattr(self, "flights", 0) >= 2 else self.kp * obs.pitch + self.kd * obs.rate
"""
KICK_DELAY_S = 0.2  # s after the first liftoff: a pitch kick in flight, what the wheel must take


def episode(config: SimConfig, hops: int, kick: float) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """Simulate one episode; its `episodes` row and its `hops` rows (the contract's columns)."""
    start = time.perf_counter()
    sim = Simulation(config)
    if kick:
        while sim.phase is not Phase.FLIGHT and sim.time < 10.0:
            sim.step()
        for _ in range(round(KICK_DELAY_S / config.timestep)):
            sim.step()
        sim.disturb("pitch_kick", kick)
    sim.run(hops)
    settings = {
        "kp": config.gains.kp, "ki": config.gains.ki, "kd": config.gains.kd, "gravity": config.gravity,
        "seed": config.seed, "hops_target": hops, "terrain": config.terrain, "wheel": config.wheel,
        "sensing": config.sensing,
        "disturbance": f"pitch_kick {kick:+g} N m s at flight +0.1 s of hop 2" if kick else "",  # spec.describe's
        "disturbance_size": float(kick),
    }  # fmt: skip
    episode_id = hashlib.sha1(json.dumps(settings, sort_keys=True).encode()).hexdigest()[:16]
    done = [h for h in sim.hops if h.completed]
    row = {
        "episode_id": episode_id, **settings,
        "hops_completed": len(done), "fell": sim.fallen,
        "worst_landing_deg": max((h.landing_pitch_deg for h in done), default=float("nan")),
        "peak_pitch_deg": max((h.peak_pitch_deg for h in sim.hops), default=0.0),
        "rms_pitch_rate_deg_s": max((h.rms_pitch_rate_deg_s for h in sim.hops), default=0.0),
        "momentum_used_pct": sim.metrics.flight_momentum_pct(),
        "saturation_s": sum(h.saturation_time_s for h in sim.hops),
        "sim_time_s": sim.time, "wall_s": time.perf_counter() - start,
    }  # fmt: skip
    hop_rows = [{"episode_id": episode_id, **settings, "hop": h.index, **h.as_dict()} for h in sim.hops]
    return row, hop_rows


def write_sweep(
    out: Path,
    kps: tuple[float, ...] = (300.0, 900.0),
    kds: tuple[float, ...] = (10.0, 40.0),
    gravities: tuple[float, ...] = (1.625, 3.72),
    kicks: tuple[float, ...] = (0.0, 1.2),
    hops: int = 2,
    parts: int = 2,
) -> Path:
    """Simulate the grid and write out/episodes/part-*.parquet, out/hops/part-*.parquet, out/spec.toml."""
    episodes, hop_rows = [], []
    for kp, kd, g, kick in itertools.product(kps, kds, gravities, kicks):
        config = SimConfig(terrain="flat", gravity=g, gains=Gains(kp=kp, ki=50.0, kd=kd))
        row, rows = episode(config, hops, kick)
        episodes.append(row)
        hop_rows += rows
    for name, rows in (("episodes", episodes), ("hops", hop_rows)):
        (out / name).mkdir(parents=True, exist_ok=True)
        size = -(-len(rows) // parts)
        for k in range(parts):  # written as work completes: several part files
            chunk = rows[k * size : (k + 1) * size]
            if chunk:
                pq.write_table(pa.Table.from_pylist(chunk), out / name / f"part-{k:05d}.parquet")
    (out / "spec.toml").write_text(
        f'hops = {hops}\nterrain = "flat"\n[axes]\nkp = {list(kps)}\nkd = {list(kds)}\n'
        f"gravity = {list(gravities)}\ndisturbance_size = {list(kicks)}\n"
    )
    return out
