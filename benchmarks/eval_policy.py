"""The learned policy on seeds and gravities it never trained on, beside the PID (issue 19's acceptance).

Run: python -m benchmarks.eval_policy [--controllers pid,policy] [--sensing realistic]

Moon crater seeds 0-9 (training drew 10,000-19,999), 20 hops each; Mars and Ceres, seeds 0-9, 10
hops each. Per controller and body: falls, controller faults, hops done, and |landing pitch| p50,
p95 and max (deg).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from hopper.config import GRAVITY_PRESETS, SimConfig  # noqa: E402
from hopper.controllers import with_controller  # noqa: E402
from hopper.sim import Simulation  # noqa: E402

BATTERY = (("moon", 20), ("mars", 10), ("ceres", 10))  # (body, hops)
SEEDS = range(10)


def evaluate(spec: str, sensing: str) -> list[str]:
    lines = []
    for body, hops in BATTERY:
        falls = faults = done = 0
        landing: list[float] = []
        for seed in SEEDS:
            config = with_controller(SimConfig(seed=seed, gravity=GRAVITY_PRESETS[body], sensing=sensing), spec)
            sim = Simulation(config)
            result = sim.run(hops)
            falls += sim.fallen
            faults += sim.controller_fault is not None
            done += sum(h.completed for h in result)
            landing += [abs(h.landing_error_deg) for h in result if h.completed]
        p50, p95, top = np.percentile(landing, 50), np.percentile(landing, 95), max(landing)
        head = f"{spec:>8} {body:>6} {hops:>3} hops x {len(SEEDS)} seeds: {falls} falls, {faults} faults, "
        lines.append(head + f"{done}/{hops * len(SEEDS)} hops, landing p50 {p50:.2f} p95 {p95:.2f} max {top:.2f} deg")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--controllers", default="pid,policy")
    parser.add_argument("--sensing", default="realistic", choices=("ideal", "realistic"))
    args = parser.parse_args()
    print(f"sensing {args.sensing}")
    for spec in args.controllers.split(","):
        for line in evaluate(spec, args.sensing):
            print(line, flush=True)


if __name__ == "__main__":
    main()
