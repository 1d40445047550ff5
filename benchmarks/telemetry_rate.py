"""Closed-loop simulation rate with and without rerun telemetry, and recording size per simulated minute.

Run as a script (`python benchmarks/telemetry_rate.py --hops 7`) or import `measure` from the main benchmark.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from benchmarks.harness import ratio
from hopper.config import SimConfig
from hopper.sim import Simulation
from hopper.telemetry import BATCH_TICKS, Telemetry


def _run(
    config: SimConfig, hops: int, path: Path | None, batch_ticks: int = BATCH_TICKS
) -> tuple[float, float, float, int]:
    """Wall and main-thread CPU seconds, simulated seconds and ticks for `hops` hops.

    The recording (if any) is closed outside the timed loop: a one-off at the end of a session.
    CPU time of the stepping thread is the steadier figure on a shared machine; wall time also
    counts rerun's encoder and writer threads when cores are scarce.
    """
    sim = Simulation(config)
    telemetry = Telemetry(sim, path=path, batch_ticks=batch_ticks) if path is not None else None
    start_time, start, cpu = sim.time, time.perf_counter(), time.thread_time()
    sim.run(hops)
    wall, cpu = time.perf_counter() - start, time.thread_time() - cpu
    if telemetry is not None:
        telemetry.close()
    ticks = round((sim.time - start_time) / config.timestep)
    return wall, cpu, sim.time - start_time, ticks


def measure(
    seed: int = 0, hops: int = 7, repeats: int = 5, terrain: str = "crater", batch_ticks: int = BATCH_TICKS
) -> dict[str, float]:
    """Ticks per second without and with a recording (`repeats` interleaved rounds: medians) and file sizes.

    Returns rate_off, rate_on (ticks/s of wall time), ratio (on/off, the median of the rounds' ratios),
    ratio_range (their lowest and highest), rounds, tick_cost_us (extra wall time per tick), cpu_ratio
    and cpu_tick_cost_us (the same from the stepping thread's CPU time), sim_s,
    mb (the file), static_mb (a recording of zero ticks: meshes, blueprint), mb_per_sim_min (whole
    file) and data_mb_per_sim_min (without the static part).
    """
    config = SimConfig(seed=seed, terrain=terrain)  # type: ignore[arg-type]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        _run(config, 1, None)  # compile the control kernel and warm caches before timing
        off, on = [], []
        for i in range(repeats):
            off.append(_run(config, hops, None))
            on.append(_run(config, hops, folder / f"run{i}.rrd", batch_ticks))
        static = folder / "static.rrd"
        Telemetry(Simulation(config), path=static).close()
        mb = (folder / "run0.rrd").stat().st_size / 1e6
        static_mb = static.stat().st_size / 1e6
    _, _, sim_s, ticks = off[0]
    wall = ratio([r[0] for r in off], [r[0] for r in on])  # per round: rate on / rate off
    cpu = ratio([r[1] for r in off], [r[1] for r in on])
    wall_off, wall_on = statistics.median(r[0] for r in off), statistics.median(r[0] for r in on)
    cpu_off, cpu_on = statistics.median(r[1] for r in off), statistics.median(r[1] for r in on)
    return {
        "rate_off": ticks / wall_off,
        "rate_on": ticks / wall_on,
        "ratio": wall.median,
        "ratio_range": (wall.low, wall.high),
        "rounds": len(off),
        "tick_cost_us": (wall_on - wall_off) / ticks * 1e6,
        "cpu_ratio": cpu.median,
        "cpu_tick_cost_us": (cpu_on - cpu_off) / ticks * 1e6,
        "sim_s": sim_s,
        "mb": mb,
        "static_mb": static_mb,
        "mb_per_sim_min": mb / (sim_s / 60.0),
        "data_mb_per_sim_min": (mb - static_mb) / (sim_s / 60.0),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--hops", type=int, default=7)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--terrain", choices=("crater", "flat"), default="crater")
    parser.add_argument("--batch-ticks", type=int, default=BATCH_TICKS, help="ticks per rerun send")
    args = parser.parse_args()
    for line in report(measure(args.seed, args.hops, args.repeats, args.terrain, args.batch_ticks)):
        print(line)


def report(r: dict[str, float]) -> list[str]:
    """The measurement as printed lines."""
    return [
        f"ticks/s without recording {r['rate_off']:9.0f}",
        f"ticks/s with recording    {r['rate_on']:9.0f}",
        f"ratio with/without        {r['ratio']:9.3f}   median ({r['ratio_range'][0]:.3f}-{r['ratio_range'][1]:.3f} "
        f"over {r['rounds']} rounds; target >= 0.85)",
        f"telemetry cost per tick   {r['tick_cost_us']:9.2f} us",
        f"same from CPU time        {r['cpu_ratio']:9.3f}   ({r['cpu_tick_cost_us']:.2f} us a tick)",
        f"recording                 {r['mb']:9.2f} MB for {r['sim_s']:.1f} s simulated"
        f" ({r['static_mb']:.2f} MB static)",
        f"MB per simulated minute   {r['mb_per_sim_min']:9.2f}"
        f"   (data only {r['data_mb_per_sim_min']:.2f}; target < 5)",
    ]


if __name__ == "__main__":
    main()
