"""What each controller costs: closed loop against bare mj_step replaying the same controls, per controller.

Run: python -m benchmarks.bench_controllers [--controllers pid,lqr,mpc,FILE.py:Class] [--rounds 5]
         [--hops 7] [--seed 0] [--sensing ideal|realistic]

Every controller flies the same episode. For each, one run records its controls; then, in each
round, every controller's closed loop and its bare replay run back to back (ABAB across the
controllers, on one core): the machine's noise moves both sides of a ratio together. Reported per
controller: the median ratio closed / raw and its spread over the rounds, the closed loop's real
time factor (simulated s per wall s), and the controller's mean compute per call (us).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import mujoco
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from benchmarks.bench_sim import ControlRecorder  # noqa: E402
from hopper.config import SimConfig  # noqa: E402
from hopper.controllers import with_controller  # noqa: E402
from hopper.sim import Simulation  # noqa: E402


def closed(config: SimConfig, hops: int) -> tuple[float, float, float, Simulation]:
    """(steps/s, real-time factor, us per controller call, sim) of the closed loop."""
    sim = Simulation(config)
    start = time.perf_counter()
    sim.run(hops)
    wall = time.perf_counter() - start
    law = sim.law
    per_call = law.compute_ns / law.calls / 1e3 if law.calls else 0.0
    return sim.ticks / wall, sim.time / wall, per_call, sim


def raw(config: SimConfig, controls: np.ndarray) -> float:
    """Steps/s of bare mj_step with the recorded controls."""
    sim = Simulation(config)
    model, data, ctrl = sim.model, sim.data, sim.data.ctrl
    start = time.perf_counter()
    for u in controls:
        ctrl[:] = u
        mujoco.mj_step(model, data)
    return len(controls) / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--controllers", default="pid,lqr,mpc")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--hops", type=int, default=7)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--sensing", choices=("ideal", "realistic"), default="ideal")
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})  # one core
    base = SimConfig(seed=args.seed, sensing=args.sensing)
    configs = {spec: with_controller(base, spec) for spec in args.controllers.split(",") if spec}
    controls = {}
    for spec, config in configs.items():  # record each controller's own controls (and warm everything)
        sim = Simulation(config)
        recorder = ControlRecorder()
        sim.listeners.append(recorder)
        sim.run(args.hops)
        controls[spec] = np.array(recorder.ctrl)
    ratios = {spec: [] for spec in configs}
    rtf = {spec: [] for spec in configs}
    per_call = {spec: [] for spec in configs}
    for _ in range(args.rounds):
        for spec, config in configs.items():
            rate, factor, us, _ = closed(config, args.hops)
            ratios[spec].append(rate / raw(config, controls[spec]))
            rtf[spec].append(factor)
            per_call[spec].append(us)
    print(f"episode: seed {args.seed}, {args.hops} hops, {args.sensing} sensing; {args.rounds} interleaved rounds")
    print(f"{'controller':<28}{'closed/raw':>11}{'spread':>16}{'real time':>11}{'us/call':>9}")
    for spec in configs:
        r = ratios[spec]
        label = spec.rpartition("/")[2]
        print(f"{label:<28}{statistics.median(r):>11.3f}{f'{min(r):.3f}-{max(r):.3f}':>16}"
              f"{statistics.median(rtf[spec]):>10.1f}x{statistics.median(per_call[spec]):>9.1f}")  # fmt: skip


if __name__ == "__main__":
    main()
