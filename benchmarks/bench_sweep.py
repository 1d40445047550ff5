"""Sweep throughput on Ray against the limit (bare mj_step of the same episodes x cores), in one run.

Run: python -m benchmarks.bench_sweep [--seeds 50] [--workers 2] [--out DIR] [--line]

1. A sweep of seeds x 5 kp x 4 kd x 2 gravities (2,000 episodes of 2 hops by default) starts as
   `hopper-sim sweep --executor ray` and is interrupted (SIGINT) once half its episodes are written.
2. The bare mj_step rate: a sample of the same episodes is simulated once to record its controls,
   then replayed with bare mj_step (as benchmarks/bench_sim.py does), on `workers` processes at once,
   as nice as Ray's workers.
3. The sweep is resumed in this process on Ray (run_sweep + RayExecutor): episodes per second
   without Ray's start-up, against the limit = cores x bare steps/s / mean steps per episode.
4. The bare rate again (the machine's load moves: the higher of the two is the limit).
With --line: Ray's and the local pool's start-up, and the work per core where Ray's extra start-up
falls under a tenth of the run (hopper.experiments.executor.RAY_MIN_WORK_PER_CORE_S).
These machines are noisy: only ratios measured in the same run mean anything.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow.dataset as ds

from benchmarks.bench_sim import ControlRecorder, closed_loop, raw_replay
from hopper.config import TIMESTEP
from hopper.experiments.executor import LocalPool, RayExecutor
from hopper.experiments.runner import run_sweep
from hopper.experiments.spec import Episode, SweepSpec, parse_spec


def bench_spec(seeds: int, hops: int) -> SweepSpec:
    return parse_spec({"seeds": seeds, "hops": hops, "kp": [300, 400, 500, 600, 700], "kd": [20, 25, 30, 35],
                       "gravity": ["moon", "mars"]})  # fmt: skip


def rows(out: Path) -> int:
    folder = out / "episodes"
    return ds.dataset(folder, format="parquet").count_rows() if any(folder.glob("*.parquet")) else 0


def interrupted_run(spec_flags: list[str], out: Path, total: int) -> tuple[int, float]:
    """Start the sweep on Ray as a user does, SIGINT it once half is written; (episodes kept, wall s)."""
    start = time.perf_counter()
    cli = [sys.executable, "-m", "hopper.app.sim_cli", "sweep", "--out", str(out), "--executor", "ray", *spec_flags]
    process = subprocess.Popen(cli, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    while process.poll() is None and rows(out) < total // 2:
        time.sleep(0.2)
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=120)
    if process.returncode != 130:
        raise SystemExit(f"the sweep did not stop with 130 but {process.returncode}: {err[-500:]}")
    return rows(out), time.perf_counter() - start


def _replay(episodes: list[Episode]) -> tuple[int, float, float]:
    """(steps, bare mj_step seconds, closed-loop seconds) of `episodes` in this process."""
    steps, bare, closed = 0, 0.0, 0.0
    for episode in episodes:
        recorder = ControlRecorder()
        config = episode.config()
        rate, ticks, _ = closed_loop(config, episode.hops_target, (recorder,))
        closed += ticks / rate
        rate, _ = raw_replay(config, np.array(recorder.ctrl))
        bare += ticks / rate
        steps += ticks
    return steps, bare, closed


# Ray runs its workers at this niceness (its worker_niceness, default 15) so that its own daemons
# stay responsive; the bare replay runs at the same, so both meet the machine's other load alike.
RAY_WORKER_NICENESS = int(os.environ.get("RAY_worker_niceness", "15"))  # noqa: SIM112 (Ray's spelling)


def _as_nice_as_ray() -> None:
    os.nice(RAY_WORKER_NICENESS - os.nice(0))


def bare_rate(sample: list[Episode], workers: int) -> tuple[float, float]:
    """(bare mj_step steps/s, closed-loop steps/s), summed over `workers` processes running at once."""
    parts = [sample[i::workers] for i in range(workers)]
    with multiprocessing.get_context("spawn").Pool(workers, initializer=_as_nice_as_ray) as pool:
        pool.map(_replay, [p[:1] for p in parts])  # warm: imports and the compiled kernel
        results = pool.map(_replay, parts)
    return sum(s / b for s, b, _ in results), sum(s / c for s, _, c in results)


def startup_line(spec: SweepSpec, workers: int) -> None:
    start = time.perf_counter()
    pool = LocalPool(workers)
    list(pool.map([[e] for e in list(spec.episodes())[:workers]]))  # every process up, model built
    pool_s = time.perf_counter() - start
    pool.close()
    ray_executor = RayExecutor(workers=workers)
    ray_s = ray_executor.startup_s
    ray_executor.close()
    line = max(ray_s - pool_s, 0.0) / 0.1
    print(f"start-up: Ray {ray_s:.1f} s (ray.init + actors), local pool {pool_s:.1f} s (spawn + first model)")
    print(f"Ray's extra start-up is under a tenth of the run above {line:.0f} s of work per core "
          f"(executor.RAY_MIN_WORK_PER_CORE_S uses 120 s)")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=50, help="seeds (x 40 episodes each; default 50: 2,000)")
    parser.add_argument("--hops", type=int, default=2)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--sample", type=int, default=24, help="episodes replayed for the bare rate")
    parser.add_argument("--out", type=Path, help="sweep folder (default: a temporary one)")
    parser.add_argument("--line", action="store_true", help="also measure the local-vs-Ray start-up line")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="bench-sweep-")) / "out"
    spec = bench_spec(args.seeds, args.hops)
    flags = ["--seeds", str(args.seeds), "--hops", str(args.hops), "--kp", "300,400,500,600,700", "--kd",
             "20,25,30,35", "--gravity", "moon,mars", "--workers", str(args.workers)]  # fmt: skip
    episodes = list(spec.episodes())
    sample = episodes[:: max(1, len(episodes) // args.sample)][: args.sample]
    print(f"sweep: {spec.size} episodes ({args.seeds} seeds x 5 kp x 4 kd x Moon, Mars; {args.hops} hops), "
          f"{args.workers} workers, out {out}")  # fmt: skip

    kept, first_wall = interrupted_run(flags, out, spec.size)
    print(f"1. on Ray via the CLI, SIGINT at half way: {kept} episodes kept, {first_wall:.1f} s wall (start-up incl.)")
    kept_ids = set(ds.dataset(out / "episodes", format="parquet").to_table().column("episode_id").to_pylist())
    bare_before, closed_before = bare_rate(sample, args.workers)
    run = run_sweep(spec, out, lambda todo: RayExecutor(workers=args.workers), progress=False, announce=print)
    table = ds.dataset(out / "episodes", format="parquet").to_table()
    ids = table.column("episode_id").to_pylist()
    bare_after, closed_after = bare_rate(sample, args.workers)
    print(
        f"2. resumed in-process on Ray: {run.ran} run, {run.skipped} skipped, {run.wall_s:.1f} s wall, "
        f"Ray start-up {run.startup_s:.1f} s, work {run.work_s:.1f} s; the datasets hold {len(ids)} episodes, "
        f"{len(set(ids))} distinct"
    )
    assert len(ids) == len(set(ids)) == spec.size, "an episode is missing or ran twice"

    sim_s = np.array([r["sim_time_s"] for r in table.to_pylist() if r["episode_id"] not in kept_ids])  # resumed
    steps_per_episode = float(sim_s.mean()) / TIMESTEP
    throughput = run.ran / run.work_s  # executor ready to last result written
    bare = max(bare_before, bare_after)
    limit = bare / steps_per_episode
    print(f"bare mj_step, {args.workers} processes at once: {bare_before:,.0f} and {bare_after:,.0f} steps/s "
          f"(before, after); closed loop {closed_before:,.0f} and {closed_after:,.0f}")  # fmt: skip
    print(f"mean episode: {steps_per_episode:,.0f} steps; limit = {limit:.2f} episodes/s")
    print(f"sweep throughput (Ray start-up excluded): {throughput:.2f} episodes/s")
    print(f"ratio sweep / limit: {throughput / limit:.3f}   (target >= 0.85; closed loop / bare: "
          f"{max(closed_before, closed_after) / bare:.3f})")  # fmt: skip
    print(f"with start-up: {run.ran / run.wall_s:.2f} episodes/s ({run.startup_s:.1f} s of {run.wall_s:.1f} s)")
    if args.line:
        startup_line(spec, args.workers)


if __name__ == "__main__":
    main()
