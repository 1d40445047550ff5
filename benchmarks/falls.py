"""How often the robot falls on crater ground: N hops per (body, seed), the falls and where.

Run: python -m benchmarks.falls [--hops 300] [--seeds 0-7] [--bodies moon,mars,ceres,earth]
         [--workers 2] [--traces DIR] [--model PATH.xml] [--terrain crater|flat] [--depth 1.0]

Each run is `hopper-sim run --hops N --gravity BODY --seed S` (the default robot and controller),
stepped one tick at a time so that the last TRACE_S seconds before a fall can be kept. Per run it
prints hops done, fell or stuck (the time limit ran out short of N hops) and the torso's world x;
per fall, the phases before it (phase letter L S C P F X, then the feet down, l and r, @ the time
in s), and whether it was trapped (hopper.metrics.trapped_at). Then the totals per body: hops,
falls, stuck runs, trapped runs, hops per fall, metres a hop, metres per fall, the share of the
pushes that were recovery hops and the near falls (NEAR_FALL). With --traces, each fall's or stuck
run's last TRACE_S s go to DIR/BODY_SEED.npy, one row a tick (columns TRACE). `--terrain flat`
and `--depth` (the craters' depths and rims times this) tell the ground's share of the falls from
the controller's.

The runs are chaotic: any change to the ground controller moves where the falls happen, so compare
variants over many seeds (a few thousand hops, seeds the change was not made on), not run by run.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from multiprocessing import Pool
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from hopper.config import GRAVITY_PRESETS, CraterParams  # noqa: E402
from hopper.control.phases import Phase  # noqa: E402
from hopper.metrics import trapped_at  # noqa: E402

TRACE_S = 3.0  # s kept before a fall
TRACE = ("t", "x", "z", "pitch", "vx", "vz", "phase", "foot_l", "foot_r", "wheel_speed", "push_done", "recovering")
LETTERS = "LSCPFX"  # hopper.control.phases.Phase, in order
PUSH = int(Phase.PUSH)
SEQUENCE = 25  # phase changes shown before a fall
# A torso beyond this that comes back is a fall narrowly missed: about ten times as frequent as the
# falls on main (Mars seeds 0-39: 38 against 5), so a change to the ground controller shows in
# them over far fewer hops than in the falls themselves.
NEAR_FALL = math.radians(15.0)  # rad


def seeds(text: str) -> list[int]:
    """'0-7' or '0,3,5' (or both, comma-separated) as a list of seeds."""
    out: list[int] = []
    for part in text.split(","):
        first, _, last = part.partition("-")
        out += range(int(first), int(last or first) + 1)
    return out


def sequence(rows: np.ndarray) -> str:
    """The phase and feet changes in `rows` (TRACE columns), the last SEQUENCE of them."""
    changes, last = [], None
    for row in rows:
        key = (int(row[6]), bool(row[7]), bool(row[8]))
        if key != last:
            feet = ("l" if key[1] else "") + ("r" if key[2] else "")
            changes.append(f"{LETTERS[key[0]]}{feet}@{row[0]:.2f}")
            last = key
    return " ".join(changes[-SEQUENCE:])


def craters(depth: float) -> CraterParams:
    """The default crater field with every crater's depth and rim `depth` times as high."""
    c = CraterParams()
    depths, rims = c.depth_ratio_range, c.rim_ratio_range
    return dataclasses.replace(
        c, depth_ratio_range=(depths[0] * depth, depths[1] * depth), rim_ratio_range=(rims[0] * depth, rims[1] * depth)
    )


def run(job: tuple[str, int, int, str | None, str | None, str, float]) -> dict:
    """One run: its result, and the phases before its fall (or its stop short of the hops)."""
    from hopper.config import SimConfig
    from hopper.sim import Simulation

    body, seed, hops, traces, model, terrain, depth = job
    config = SimConfig(seed=seed, gravity=GRAVITY_PRESETS[body], model=model, terrain=terrain, craters=craters(depth))
    sim = Simulation(config)
    mem, lay, q, v = sim.controller.mem, sim.layout, sim.data.qpos, sim.data.qvel
    keep = round(TRACE_S / sim.model.opt.timestep)
    ring = np.zeros((keep, len(TRACE)))
    ticks, limit = 0, round(sim.time_limit(hops) / sim.model.opt.timestep)
    pushes = recoveries = near = 0
    phase, beyond = -1, False
    start = time.perf_counter()
    while len(sim.hops) < hops and not sim.fallen and ticks < limit:
        sim.step()
        m = mem[0]
        if m["phase"] != phase:
            phase = m["phase"]
            if phase == PUSH:
                pushes += 1
                recoveries += bool(m["recovering"])
        out = abs(m["pitch_true"]) > NEAR_FALL
        near, beyond = near + (out and not beyond), out
        ring[ticks % keep] = (sim.data.time, q[lay.q_x], q[lay.q_z], m["pitch_true"], v[lay.v_x], v[lay.v_z],
                              m["phase"], m["contact_l"], m["contact_r"], v[lay.v_wheel], m["push_done"],
                              m["recovering"])  # fmt: skip
        ticks += 1
    done = sum(h.completed for h in sim.hops)
    result = {"body": body, "seed": seed, "hops": done, "fell": sim.fallen, "stuck": not sim.fallen and done < hops,
              "x": sim.state().x, "wall_s": time.perf_counter() - start, "before": "",
              "pushes": pushes, "recoveries": recoveries, "near": near - (sim.fallen and beyond),
              "trapped": trapped_at([h.distance_m for h in sim.hops])}  # fmt: skip
    if result["fell"] or result["stuck"]:
        rows = np.roll(ring, -(ticks % keep), axis=0) if ticks >= keep else ring[:ticks]
        result["before"] = sequence(rows)
        if traces is not None:
            np.save(Path(traces) / f"{body}_{seed}.npy", rows)
    return result


def totals(name: str, results: list[dict]) -> str:
    """One line of totals over `results` (run's dicts): hops, falls, stuck runs, hops and metres per
    fall or stop, metres a hop, the share of the pushes that were recovery hops and the near falls."""
    hops, falls, stuck = (sum(r[k] for r in results) for k in ("hops", "fell", "stuck"))
    ended = falls + stuck
    ground = sum(r["x"] for r in results)
    per = f"{hops / ended:.0f}" if ended else "-"
    # Metres a hop: a robot trapped in a crater, hopping back and forth, hops on without falling.
    travel = ground / max(hops, 1)
    # Metres of crater ground a fall: the falls come from the ground met, so a gait that covers less
    # ground a hop falls less often a hop without being any surer on that ground.
    per_m = f"{ground / ended:.0f}" if ended else "-"
    # The share of pushes that were recovery hops (the capture point left the feet): how often the
    # ground phase loses the robot, counted every hop, where falls are rare.
    recovering = sum(r["recoveries"] for r in results) / max(sum(r["pushes"] for r in results), 1)
    trapped = sum(r["trapped"] is not None for r in results)
    return (
        f"{name:>6}: {hops} hops, {falls} falls, {stuck} stuck, {trapped} trapped, {per} hops per fall or stop, "
        f"{travel:.2f} m a hop, {per_m} m per fall or stop, {recovering:.0%} of pushes recovery hops, "
        f"{sum(r['near'] for r in results)} near falls (the torso beyond {math.degrees(NEAR_FALL):.0f} deg and back)"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hops", type=int, default=300, help="hops asked of each run (default 300)")
    parser.add_argument("--seeds", type=seeds, default=seeds("0-7"), help="e.g. 0-7 or 0,3,5 (default 0-7)")
    parser.add_argument("--bodies", default="moon,mars,ceres,earth", help="gravity presets (default all four)")
    parser.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    parser.add_argument("--traces", type=Path, default=None, help="keep each fall's last seconds here (.npy)")
    parser.add_argument("--model", type=Path, default=None, help="your own MJCF of the robot (hopper-sim --model)")
    parser.add_argument("--terrain", choices=("crater", "flat"), default="crater", help="the ground (default crater)")
    parser.add_argument("--depth", type=float, default=1.0, help="the craters' depths and rims times this (default 1)")
    args = parser.parse_args(argv)
    bodies = args.bodies.split(",")
    unknown = [b for b in bodies if b not in GRAVITY_PRESETS]
    if unknown or args.hops < 1 or args.workers < 1:
        parser.error(f"bodies are {', '.join(GRAVITY_PRESETS)}; hops and workers at least 1")
    try:
        craters(args.depth)
    except ValueError as error:
        parser.error(str(error))
    if args.traces is not None:
        args.traces.mkdir(parents=True, exist_ok=True)
    traces = str(args.traces) if args.traces is not None else None
    # The slowest bodies first: the pool ends with short runs, not one long one.
    model = str(args.model.resolve()) if args.model is not None else None
    jobs = sorted(
        ((b, s, args.hops, traces, model, args.terrain, args.depth) for b in bodies for s in args.seeds),
        key=lambda j: GRAVITY_PRESETS[j[0]],
    )
    results = []
    with Pool(args.workers) as pool:
        for r in pool.imap_unordered(run, jobs):
            results.append(r)
            end = "fell" if r["fell"] else "stuck" if r["stuck"] else "done"
            trap = "" if r["trapped"] is None else f", trapped from hop {r['trapped'] + 1}"
            print(f"{r['body']:>6} seed {r['seed']:>3}: {r['hops']:>5} hops, {end} at x = {r['x']:8.2f} m "
                  f"({r['wall_s']:.0f} s){trap}", flush=True)  # fmt: skip
            if r["before"]:
                print(f"       before: {r['before']}", flush=True)
    for body in [*bodies, None]:
        print(totals(body or "all", [r for r in results if body is None or r["body"] == body]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
