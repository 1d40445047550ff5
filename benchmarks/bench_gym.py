"""The Gymnasium env's speed against the bare simulation's, interleaved in one run.

Run: python -m benchmarks.bench_gym [--rounds 5] [--seconds 3] [--envs 4]

Each round runs, back to back (ABC ABC ..., one core): the bare Simulation.run with the compiled
PID, one FlightAttitudeEnv driven by the paper's PD in numpy (agent side included), and a
SyncVectorEnv of --envs envs. Reported: median and spread over the rounds of env steps/s (an env
step is one flight tick; the ground ticks between flights are simulated inside it) and simulated
ticks/s, and the ratio of each to the bare simulation's ticks/s.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from hopper.config import SimConfig  # noqa: E402
from hopper.gym_env import FlightAttitudeEnv, make_vector  # noqa: E402
from hopper.sim import Simulation  # noqa: E402

PD = np.array([450.0 * 0.1, 30.0]) / 29.5  # the paper's PD on the normalised pitch and rate


def bare(seconds: float) -> tuple[float, float]:
    """(ticks/s, ticks/s): Simulation.run with the PID, hop after hop, for about `seconds` wall."""
    sim, ticks, start = Simulation(SimConfig(seed=1)), 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        sim.start_over(SimConfig(seed=1))
        sim.run(7)
        ticks += sim.ticks
    rate = ticks / (time.perf_counter() - start)
    return rate, rate


def single(seconds: float) -> tuple[float, float]:
    """(env steps/s, simulated ticks/s) of one env with a numpy PD as the agent."""
    env, steps, ticks, episode, start = FlightAttitudeEnv(flights=3), 0, 0, 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        obs, _ = env.reset(seed=episode)
        episode, done = episode + 1, False
        while not done:
            obs, _, terminated, truncated, _ = env.step(np.array([np.clip(PD @ obs[:2], -1, 1)], np.float32))
            steps, done = steps + 1, terminated or truncated
        ticks += env.sim.ticks
    wall = time.perf_counter() - start
    return steps / wall, ticks / wall


def vector(seconds: float, n: int) -> tuple[float, float]:
    """(env steps/s summed over the envs, simulated ticks/s) of a SyncVectorEnv (autoreset)."""
    envs = make_vector(n, flights=3)
    obs, _ = envs.reset(seed=0)
    steps, done_ticks, start = 0, 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        before = [e.unwrapped.sim.ticks for e in envs.envs]
        obs, _, _, _, _ = envs.step(np.clip(obs[:, :2] @ PD, -1, 1).reshape(n, 1).astype(np.float32))
        after = [e.unwrapped.sim.ticks for e in envs.envs]
        done_ticks += sum(a - b if a >= b else a for a, b in zip(after, before, strict=True))  # a reset restarts ticks
        steps += n
    wall = time.perf_counter() - start
    envs.close()
    return steps / wall, done_ticks / wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=3.0, help="wall seconds per side per round")
    parser.add_argument("--envs", type=int, default=4)
    args = parser.parse_args()
    bare(0.5), single(0.5), vector(0.5, args.envs)  # warm up: numba, first models
    results: dict[str, list[tuple[float, float]]] = {"bare sim (PID)": [], "env": [], f"vector x{args.envs}": []}
    for _ in range(args.rounds):
        results["bare sim (PID)"].append(bare(args.seconds))
        results["env"].append(single(args.seconds))
        results[f"vector x{args.envs}"].append(vector(args.seconds, args.envs))
    base = [r[1] for r in results["bare sim (PID)"]]
    print(f"{args.rounds} rounds of {args.seconds:g} s each, interleaved; median (min-max)")
    for name, rows in results.items():
        steps, ticks = [r[0] for r in rows], [r[1] for r in rows]
        ratio = [t / b for t, b in zip(ticks, base, strict=True)]
        print(f"{name:>16}: {statistics.median(steps):8.0f} steps/s ({min(steps):.0f}-{max(steps):.0f}), "
              f"{statistics.median(ticks):8.0f} ticks/s, ticks ratio to bare {statistics.median(ratio):.3f} "
              f"({min(ratio):.3f}-{max(ratio):.3f})")  # fmt: skip


if __name__ == "__main__":
    main()
