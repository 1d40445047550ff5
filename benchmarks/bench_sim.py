"""Closed-loop simulation speed against bare mj_step replaying the very same controls.

Run: python -m benchmarks.bench_sim [--seed 0] [--hops 7] [--sensing ideal|realistic]
Everything is measured in this one run, interleaved, on one core: these machines are noisy,
so only the ratios are meaningful across machines.
"""

from __future__ import annotations

import argparse
import os
import time

import mujoco
import numpy as np

from benchmarks import telemetry_rate
from hopper.config import SimConfig
from hopper.sim import Simulation


class ControlRecorder:
    """Listener that keeps each tick's ctrl, to replay the same sequence with bare mj_step."""

    def __init__(self) -> None:
        self.ctrl: list[np.ndarray] = []

    def tick(self, sim: Simulation) -> None:
        self.ctrl.append(sim.data.ctrl.copy())

    def event(self, sim: Simulation, event: object) -> None:
        pass


def closed_loop(config: SimConfig, hops: int, listeners: tuple = ()) -> tuple[float, int, Simulation]:
    """(steps per second, steps, sim) of controller + phases + metrics + mj_step."""
    sim = Simulation(config)
    sim.listeners.extend(listeners)
    start = time.perf_counter()
    sim.run(hops)
    return sim.ticks / (time.perf_counter() - start), sim.ticks, sim


def raw_replay(config: SimConfig, controls: np.ndarray) -> tuple[float, np.ndarray]:
    """(steps per second, final qpos) of bare mj_step with recorded controls: same states, same contacts."""
    sim = Simulation(config)
    model, data = sim.model, sim.data
    ctrl = data.ctrl
    start = time.perf_counter()
    for u in controls:
        ctrl[:] = u
        mujoco.mj_step(model, data)
    return len(controls) / (time.perf_counter() - start), data.qpos.copy()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--hops", type=int, default=7)
    parser.add_argument("--repeats", type=int, default=3, help="interleaved repeats; the best of each is kept")
    parser.add_argument("--sensing", choices=("ideal", "realistic"), default="ideal", help="SimConfig.sensing")
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})  # one core, as the target says
    config = SimConfig(seed=args.seed, sensing=args.sensing)

    recorder = ControlRecorder()
    _, steps, reference = closed_loop(config, args.hops, (recorder,))  # also warms the compiled kernel
    controls = np.array(recorder.ctrl)

    closed, raw, episode = [], [], []
    for _ in range(args.repeats):
        t = time.perf_counter()
        rate, _, _ = closed_loop(config, args.hops)
        episode.append(time.perf_counter() - t)
        closed.append(rate)
        rate, qpos = raw_replay(config, controls)
        raw.append(rate)
        assert np.array_equal(qpos, reference.data.qpos), "replay diverged from the closed loop"

    best_closed, best_raw = max(closed), max(raw)
    print(f"episode: seed {args.seed}, {args.hops} hops, {args.sensing} sensing, {steps} steps = {steps / 1000:.1f} s")
    print(f"closed loop (controller + phases + metrics + mj_step): {best_closed:9.0f} steps/s")
    print(f"raw replay (same controls, bare mj_step):              {best_raw:9.0f} steps/s")
    print(f"ratio closed / raw: {best_closed / best_raw:.3f}   (target >= 0.9 with ideal sensing, issue 8)")
    print(f"one {args.hops}-hop episode, wall time incl. setup: {min(episode):.3f} s   (target < 1 s)")
    print("\nwith rerun recording (benchmarks/telemetry_rate.py, ideal sensing):")
    for line in telemetry_rate.report(telemetry_rate.measure(seed=args.seed, hops=args.hops, repeats=args.repeats)):
        print(line)


if __name__ == "__main__":
    main()
