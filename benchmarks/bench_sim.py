"""Closed-loop simulation speed against bare mj_step replaying the very same controls.

Run: python -m benchmarks.bench_sim [--seed 0] [--hops 7] [--rounds 7] [--sensing ideal|realistic]
Everything is measured in this one run on one core, interleaved (closed loop, tick by tick, bare;
again, ...: STYLE.md item 30), and each ratio is the median of its rounds' ratios with their range:
these machines are noisy (the bare rate moved 1.7x within an hour), so only ratios measured side
by side mean anything, across machines or within one.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import mujoco
import numpy as np

from benchmarks import telemetry_rate
from benchmarks.harness import MIN_ROUNDS, interleaved, ratio, spread
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
    """(steps per second, steps, sim) of controller + phases + metrics + mj_step, as Simulation.run steps."""
    sim = Simulation(config)
    sim.listeners.extend(listeners)
    start = time.perf_counter()
    sim.run(hops)
    return sim.ticks / (time.perf_counter() - start), sim.ticks, sim


def tick_by_tick(config: SimConfig, steps: int) -> tuple[float, np.ndarray]:
    """(steps per second, final qpos) of the same closed loop one Simulation.step() at a time: every
    tick through Python, as every tick went before the compiled bursts (hopper.stepping)."""
    sim = Simulation(config)
    step = sim.step
    start = time.perf_counter()
    for _ in range(steps):
        step()
    return steps / (time.perf_counter() - start), sim.data.qpos.copy()


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
    parser.add_argument("--rounds", type=int, default=7, help=f"interleaved rounds (>= {MIN_ROUNDS}); medians")
    parser.add_argument("--sensing", choices=("ideal", "realistic"), default="ideal", help="SimConfig.sensing")
    parser.add_argument("--no-telemetry", action="store_true", help="skip the rerun recording's part")
    args = parser.parse_args()
    if args.rounds < MIN_ROUNDS:
        parser.error(f"--rounds must be at least {MIN_ROUNDS}: a median of fewer rounds says little")
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})  # one core, as the target says
    config = SimConfig(seed=args.seed, sensing=args.sensing)

    recorder = ControlRecorder()
    _, steps, reference = closed_loop(config, args.hops, (recorder,))  # also warms the compiled kernel
    controls = np.array(recorder.ctrl)
    episode: list[float] = []

    def closed() -> float:
        t = time.perf_counter()
        rate, ticks, sim = closed_loop(config, args.hops)
        episode.append(time.perf_counter() - t)
        assert ticks == steps and np.array_equal(sim.data.qpos, reference.data.qpos), "the closed loop changed"
        return rate

    def per_tick() -> float:
        rate, qpos = tick_by_tick(config, steps)
        assert np.array_equal(qpos, reference.data.qpos), "tick by tick diverged from the closed loop"
        return rate

    def bare() -> float:
        rate, qpos = raw_replay(config, controls)
        assert np.array_equal(qpos, reference.data.qpos), "replay diverged from the closed loop"
        return rate

    rates = interleaved({"closed": closed, "per_tick": per_tick, "bare": bare}, args.rounds)
    print(f"episode: seed {args.seed}, {args.hops} hops, {args.sensing} sensing, {steps} steps = {steps / 1000:.1f} s")
    print(f"{args.rounds} rounds, each: closed loop, tick by tick, bare replay (medians, range in brackets)")
    print(f"closed loop (Simulation.run: compiled bursts):     {spread(rates['closed'])} steps/s")
    print(f"tick by tick (Simulation.step, every tick Python): {spread(rates['per_tick'])} steps/s")
    print(f"bare replay (same controls, bare mj_step):         {spread(rates['bare'])} steps/s")
    print(f"ratio closed / bare:       {ratio(rates['closed'], rates['bare'])}   (target >= 0.93, issue 22)")
    print(f"ratio tick by tick / bare: {ratio(rates['per_tick'], rates['bare'])}   (every tick in Python)")
    median_s = statistics.median(episode)
    print(f"one {args.hops}-hop episode, wall time incl. setup: {median_s:.3f} s median   (target < 1 s)")
    if args.no_telemetry:
        return
    print("\nwith rerun recording (benchmarks/telemetry_rate.py, ideal sensing):")
    for line in telemetry_rate.report(telemetry_rate.measure(seed=args.seed, hops=args.hops, repeats=args.rounds)):
        print(line)


if __name__ == "__main__":
    main()
