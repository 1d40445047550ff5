"""Sweep throughput on Ray against the limit (bare mj_step of the same episodes x cores), in one run.

Run: python -m benchmarks.bench_sweep [--seeds 50] [--workers 2] [--out DIR] [--line]

1. A sweep of seeds x 5 kp x 4 kd x 2 gravities (2,000 episodes of 2 hops by default) starts as
   `hopper-sim sweep --executor ray` and is interrupted (SIGINT) once half its episodes are written.
2. It is resumed in this process on Ray (the store skips what is done), in segments; after each, a
   sample of that segment's episodes is simulated once to record its controls and replayed with
   bare mj_step (as benchmarks/bench_sim.py does) on `workers` processes at once, as nice as Ray's
   workers: the limit. Ratio = the segment's simulated steps per second / the bare steps per second
   (= episodes/s against bare rate x cores / steps per episode). Ray's start-up is reported apart.
With --line: Ray's and the local pool's start-up, and the work per core where Ray's extra start-up
falls under a tenth of the run (hopper.experiments.executor.RAY_MIN_WORK_PER_CORE_S).
These machines are noisy: only ratios measured side by side mean anything; each is the median of the
segments' ratios, with their range (benchmarks/harness.py).
"""

from __future__ import annotations

import argparse
import contextlib
import multiprocessing
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import psutil
import pyarrow.dataset as ds

from benchmarks.bench_sim import ControlRecorder, closed_loop, raw_replay
from benchmarks.harness import MIN_ROUNDS, Ratio, ratio
from hopper.config import TIMESTEP
from hopper.experiments.executor import LocalPool, RayExecutor, chunks
from hopper.experiments.runner import pending
from hopper.experiments.spec import Episode, SweepSpec, parse_spec
from hopper.experiments.store import SweepStore


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


def _replay(episodes: list[Episode]) -> tuple[int, float, float, float]:
    """(steps, bare mj_step seconds, closed-loop seconds, bare mj_step CPU seconds) of `episodes` here."""
    steps, bare, closed, cpu = 0, 0.0, 0.0, 0.0
    for episode in episodes:
        recorder = ControlRecorder()
        config = episode.config()
        rate, ticks, _ = closed_loop(config, episode.hops_target, (recorder,))
        closed += ticks / rate
        start = time.process_time()
        rate, _ = raw_replay(config, np.array(recorder.ctrl))
        cpu += time.process_time() - start
        bare += ticks / rate
        steps += ticks
    return steps, bare, closed, cpu


def sweep_cpu_s(exclude: set[int]) -> float:
    """CPU seconds so far of this process and its descendants (Ray's daemons and actors), but `exclude`."""
    me = psutil.Process()
    total = sum(me.cpu_times()[:2])
    for child in me.children(recursive=True):
        if child.pid not in exclude:
            with contextlib.suppress(psutil.NoSuchProcess):
                total += sum(child.cpu_times()[:2])
    return total


# Ray runs its workers at this niceness (its worker_niceness, default 15) so that its own daemons
# stay responsive; the bare replay runs at the same, so both meet the machine's other load alike.
RAY_WORKER_NICENESS = int(os.environ.get("RAY_worker_niceness", "15"))  # noqa: SIM112 (Ray's spelling)


def _as_nice_as_ray() -> None:
    os.nice(RAY_WORKER_NICENESS - os.nice(0))


def resumed_in_segments(
    spec: SweepSpec, out: Path, workers: int, count: int, sample: int
) -> list[tuple[int, float, float, float, float, float]]:
    """Resume the sweep on Ray (the store skips what is done) in `count` segments, each followed by the
    bare and closed-loop rates of a sample of its own episodes: the machine's load moves, so each
    segment is compared with a limit measured right after it. Rows: (episodes, wall s, sweep steps/s,
    bare steps/s, closed-loop steps/s, CPU ratio: steps per CPU second of the sweep's every process,
    driver and Ray's daemons included, over bare mj_step's)."""
    store = SweepStore(out, spec)
    todo = pending(spec, store.open())
    start = time.perf_counter()
    executor = RayExecutor(workers=workers)
    size = -(-len(todo) // count)
    rows = []
    with multiprocessing.get_context("spawn").Pool(workers, initializer=_as_nice_as_ray) as pool:
        pool.map(_replay, [[e] for e in todo[:workers]])  # warm: imports and the compiled kernel
        replayers = {p.pid for p in multiprocessing.active_children()}
        for part in (todo[i : i + size] for i in range(0, len(todo), size)):
            t, cpu = time.perf_counter(), sweep_cpu_s(replayers)
            results = []
            for chunk in executor.map(chunks(part, executor.workers)):
                store.add(chunk)
                results += chunk
            store.flush()
            wall, cpu = time.perf_counter() - t, sweep_cpu_s(replayers) - cpu
            steps = sum(r.sim_time_s for r in results) / TIMESTEP
            picked = part[:: max(1, len(part) // sample)][:sample]
            replays = pool.map(_replay, [picked[i::workers] for i in range(workers)])
            bare = sum(n / b for n, b, _, _ in replays)
            closed = sum(n / c for n, _, c, _ in replays)
            bare_per_cpu_s = sum(n for n, *_ in replays) / sum(c for *_, c in replays)
            rows.append((len(part), wall, steps / wall, bare, closed, (steps / cpu) / bare_per_cpu_s))
    executor.close()
    ids = store.read_episodes(columns=["episode_id"]).column("episode_id").to_pylist()
    print(f"2. resumed in-process on Ray: {len(todo)} run in {time.perf_counter() - start:.1f} s (Ray start-up "
          f"{executor.startup_s:.1f} s, bare-rate samples included); the datasets hold {len(ids)} episodes, "
          f"{len(set(ids))} distinct")  # fmt: skip
    assert len(ids) == len(set(ids)) == spec.size, "an episode is missing or ran twice"
    return rows


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
    parser.add_argument("--sample", type=int, default=8, help="episodes replayed per segment for the bare rate")
    parser.add_argument("--segments", type=int, default=MIN_ROUNDS, help=f"the resumed half in this many measured "
                        f"segments, each a round: sweep, then bare (>= {MIN_ROUNDS})")  # fmt: skip
    parser.add_argument("--out", type=Path, help="sweep folder (default: a temporary one)")
    parser.add_argument("--line", action="store_true", help="also measure the local-vs-Ray start-up line")
    args = parser.parse_args()
    if args.segments < MIN_ROUNDS:
        parser.error(f"--segments must be at least {MIN_ROUNDS}: a median of fewer rounds says little")
    out = args.out or Path(tempfile.mkdtemp(prefix="bench-sweep-")) / "out"
    spec = bench_spec(args.seeds, args.hops)
    flags = ["--seeds", str(args.seeds), "--hops", str(args.hops), "--kp", "300,400,500,600,700", "--kd",
             "20,25,30,35", "--gravity", "moon,mars", "--workers", str(args.workers)]  # fmt: skip
    print(f"sweep: {spec.size} episodes ({args.seeds} seeds x 5 kp x 4 kd x Moon, Mars; {args.hops} hops), "
          f"{args.workers} workers, out {out}")  # fmt: skip

    kept, first_wall = interrupted_run(flags, out, spec.size)
    print(f"1. on Ray via the CLI, SIGINT at half way: {kept} episodes kept, {first_wall:.1f} s wall (start-up incl.)")
    segments = resumed_in_segments(spec, out, args.workers, args.segments, args.sample)
    print(f"{'segment':>8} {'episodes':>9} {'wall s':>7} {'sweep steps/s':>14} {'bare steps/s':>13} {'closed':>8} "
          f"{'sweep/bare':>11} {'closed/bare':>12} {'CPU ratio':>10}")  # fmt: skip
    for i, (n, wall, sweep, bare, closed, cpu) in enumerate(segments, 1):
        print(f"{i:>8} {n:>9} {wall:>7.1f} {sweep:>14,.0f} {bare:>13,.0f} {closed:>8,.0f} {sweep / bare:>11.3f} "
              f"{closed / bare:>12.3f} {cpu:>10.3f}")  # fmt: skip
    # The segments are the rounds: each sweep segment is followed at once by its own bare replay (ABAB...).
    sweep_bare = ratio([sweep for _, _, sweep, *_ in segments], [bare for _, _, _, bare, *_ in segments])
    closed_bare = ratio([closed for *_, closed, _ in segments], [bare for _, _, _, bare, *_ in segments])
    cpu_ratios = Ratio(tuple(cpu for *_, cpu in segments))
    print(f"ratio sweep / limit (limit = bare mj_step of the same episodes x {args.workers} processes): "
          f"{sweep_bare}   (target >= 0.85)")  # fmt: skip
    print(f"ratio closed loop / bare mj_step of the same sampled episodes: {closed_bare}")
    print(f"CPU ratio (steps per CPU second, the sweep's every process / bare mj_step; blind to the machine's "
          f"other load): {cpu_ratios}")  # fmt: skip
    if args.line:
        startup_line(spec, args.workers)


if __name__ == "__main__":
    main()
