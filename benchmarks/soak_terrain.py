"""Soak of the endless terrain: one headless run of many hops, resident memory sampled every N hops.

Run: python -m benchmarks.soak_terrain [--hops 10000] [--every 500] [--warmup 1000] [--gravity moon] [--seed 0]

One Simulation hops on (a fall resets it to the start and the run goes on, counted), as
`hopper-sim run` steps it without its 100 Hz trace (which grows with the run by design). Every
`every` hops a row: this process's RSS (psutil), simulated time, distance, the terrain window's
moves, the tiles the field keeps, the events in sim.events (the newest hopper.sim.EVENT_RECORD).
Printed, all from this one run: the table, and the RSS from the warm-up on: growth to the end and
the largest deviation from the warm-up value (target: both within 5 %).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

EVENT_BYTES = 590  # B an event held in sim.events: this soak's RSS growth per event when the record had no bound


@dataclasses.dataclass(frozen=True)
class Row:
    hops: int  # hops done, falls included
    rss_mb: float
    sim_s: float
    wall_s: float
    x_m: float  # world x of the torso, m
    moves: int  # terrain window moves so far (a fall's return to the start included)
    tiles: int  # tiles the field keeps (hopper.terrain.field.CACHE_TILES at most)
    events: int  # len(sim.events)
    falls: int


def soak(hops: int, every: int, gravity: float, seed: int) -> list[Row]:
    import psutil

    from hopper.config import SimConfig
    from hopper.sim import Simulation

    process = psutil.Process()
    sim = Simulation(SimConfig(seed=seed, gravity=gravity))
    done, falls, travelled = 0, 0, 0.0
    rows: list[Row] = []
    start = time.perf_counter()
    while done < hops:
        target = min(every - done % every, hops - done)
        before = len(sim.hops)
        sim.run(before + target)
        done += len(sim.hops) - before
        if sim.fallen or len(sim.hops) - before < target:  # a fall, or the run's time limit: start again
            falls += sim.fallen
            travelled += sim.state().x
            sim.reset(reason="soak")
            continue
        tiles = len(getattr(sim.terrain.field, "_tiles", ()))
        rows.append(
            Row(done, process.memory_info().rss / 1e6, sim.time, time.perf_counter() - start,
                travelled + sim.state().x, sim.terrain.moves, tiles, len(sim.events), falls)
        )  # fmt: skip
    return rows


def report(rows: list[Row], warmup: int) -> list[str]:
    lines = [f"{'hops':>6} {'RSS MB':>8} {'sim s':>8} {'wall s':>7} {'x m':>8} {'moves':>6} {'tiles':>5} "
             f"{'events':>7} {'falls':>5}"]  # fmt: skip
    lines += [
        f"{r.hops:6d} {r.rss_mb:8.1f} {r.sim_s:8.0f} {r.wall_s:7.1f} {r.x_m:8.1f} {r.moves:6d} {r.tiles:5d} "
        f"{r.events:7d} {r.falls:5d}"
        for r in rows
    ]
    after = [r for r in rows if r.hops >= warmup]
    if len(after) < 2:
        return [*lines, f"fewer than two samples after the {warmup}-hop warm-up: no growth figure"]
    base = after[0].rss_mb
    growth = 100.0 * (after[-1].rss_mb - base) / base
    worst = max(abs(r.rss_mb - base) for r in after) * 100.0 / base
    added = after[-1].events - after[0].events
    lines += [
        f"RSS after the {after[0].hops}-hop warm-up {base:.1f} MB, at {after[-1].hops} hops {after[-1].rss_mb:.1f} MB: "
        f"growth {growth:+.2f} %, largest deviation {worst:.2f} % (target: within 5 %)",
        f"the event record (sim.events) grew by {added} events, about {added * EVENT_BYTES / 1e6:.1f} MB; "
        f"the terrain: {after[-1].moves} window moves, at most {max(r.tiles for r in rows)} tiles held",
    ]
    return lines


def main(argv: list[str] | None = None) -> dict[str, Any]:
    from hopper.config import GRAVITY_PRESETS

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--hops", type=int, default=10_000)
    p.add_argument("--every", type=int, default=500, help="hops between samples (default 500)")
    p.add_argument("--warmup", type=int, default=1000, help="hops before the reference sample (default 1000)")
    p.add_argument("--gravity", choices=sorted(GRAVITY_PRESETS), default="moon")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    rows = soak(args.hops, args.every, GRAVITY_PRESETS[args.gravity], args.seed)
    for line in report(rows, args.warmup):
        print(line, flush=True)
    return {"rows": [dataclasses.asdict(r) for r in rows]}


if __name__ == "__main__":
    main()
