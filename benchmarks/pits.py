"""The robot over a field of identical pits: which walls it crosses, at which gravity.

Run: python -m benchmarks.pits [--bodies earth] [--angles 20,25,30] [--depths 0.1,0.2] [--hops 150]
         [--starts 8] [--workers 2] [--model PATH.xml]

The crater field mixes every slope and depth (benchmarks.falls); here one wall at a time. The
ground is level for LEVEL m, then a pit: a wall down at ANGLE deg to DEPTH m below, FLOOR m of
level floor, a wall back up at the same angle; and again, from x = START on. Per (body, angle,
depth), `--starts` runs of `hopper-sim run --hops N`, the pits shifted by 1/starts of their period
from one to the next (the runs are chaotic: where the robot meets the first wall decides much):
the runs that fell, the pits crossed, pits crossed a fall, and where each fall ended (the level
ground, wall down, floor or wall up).
"""

from __future__ import annotations

import argparse
import math
import sys
from multiprocessing import Pool
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from hopper.config import GRAVITY_PRESETS, CraterParams  # noqa: E402

START, LEVEL, FLOOR = 2.0, 3.0, 0.6  # m
PARTS = ("level", "wall down", "floor", "wall up")  # of a period of the ground, in order


class PitField:
    """A hopper.terrain.Field: level ground with a pit every period from x = START on (heights in m)."""

    def __init__(self, params: CraterParams, angle: float, depth: float, shift: float = 0.0) -> None:
        """`shift`: the pits start this share of a period after START."""
        if not (0.0 < angle < 80.0 and 0.0 < depth <= 1.0):
            raise ValueError(f"a pit needs 0 < angle < 80 deg and 0 < depth <= 1 m, got {angle:g} deg, {depth:g} m")
        self.params, self.depth = params, depth
        self.slope = math.tan(math.radians(angle))
        self.wall = depth / self.slope  # m, each wall's run
        self.period = LEVEL + 2.0 * self.wall + FLOOR
        self.start = START + shift * self.period
        self.vertical_range = (-depth - 0.05, 0.05)  # m, the hfield's fixed scale

    def height(self, x: np.ndarray) -> np.ndarray:
        """Ground height (m) at world x (m)."""
        u = np.mod(x - self.start, self.period) - LEVEL  # m into the pit (< 0: on the level before it)
        down = -self.slope * u
        up = -self.depth + self.slope * (u - self.wall - FLOOR)
        h = np.clip(np.maximum(down, up), -self.depth, 0.0)
        return np.where((x < self.start) | (u < 0.0), 0.0, h)

    def columns(self, first: int, count: int) -> np.ndarray:
        x = np.arange(first, first + count) * self.params.cell
        return np.tile(self.height(x), (self.params.shape[0], 1))

    def where(self, x: float) -> tuple[int, str]:
        """How many pits lie wholly behind world x (m), and the part of the ground x is on."""
        if x < self.start:
            return 0, "level"
        crossed, u = divmod(x - self.start, self.period)
        u -= LEVEL
        ends = (0.0, self.wall, self.wall + FLOOR, math.inf)
        return int(crossed), next(part for end, part in zip(ends, PARTS, strict=True) if u < end)


def simulation(body: str, angle: float, depth: float, shift: float = 0.0, model: str | None = None) -> tuple:
    """(a Simulation, its PitField): the robot at `body`'s gravity, standing before pits of `angle`
    (deg) and `depth` (m) shifted by `shift` of a period."""
    from hopper import terrain
    from hopper.config import SimConfig
    from hopper.model import set_terrain
    from hopper.sim import Simulation

    sim = Simulation(SimConfig(gravity=GRAVITY_PRESETS[body], model=model))
    field = PitField(sim.config.craters, angle, depth, shift)
    sim.terrain = terrain.Window(field, sim.config.craters)  # the Simulation's window, on our field
    set_terrain(sim.model, sim.terrain)
    sim.reset()
    return sim, field


def run(job: tuple[str, float, float, float, int, str | None]) -> dict:
    """One run over pits of `angle` (deg) and `depth` (m), shifted: hops done, fell, where it ended."""
    body, angle, depth, shift, hops, model = job
    sim, field = simulation(body, angle, depth, shift, model)
    done = sum(h.completed for h in sim.run(hops))
    x = sim.state().x
    crossed, part = field.where(x)
    return {"body": body, "angle": angle, "depth": depth, "hops": done, "fell": sim.fallen, "x": x,
            "crossed": crossed, "part": part}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bodies", default="earth", help="gravity presets (default earth)")
    parser.add_argument("--angles", default="20,25,30", help="wall angles, deg (default 20,25,30)")
    parser.add_argument("--depths", default="0.1,0.2", help="pit depths, m (default 0.1,0.2)")
    parser.add_argument("--hops", type=int, default=150, help="hops asked of each run (default 150)")
    parser.add_argument("--starts", type=int, default=8, help="runs per case, the pits shifted (default 8)")
    parser.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    parser.add_argument("--model", type=Path, default=None, help="your own MJCF of the robot (hopper-sim --model)")
    args = parser.parse_args(argv)
    bodies = args.bodies.split(",")
    try:
        angles = [float(a) for a in args.angles.split(",")]
        depths = [float(d) for d in args.depths.split(",")]
        for a in angles:
            for d in depths:
                PitField(CraterParams(), a, d)
    except ValueError as error:
        parser.error(str(error))
    if any(b not in GRAVITY_PRESETS for b in bodies) or min(args.hops, args.starts, args.workers) < 1:
        parser.error(f"bodies are {', '.join(GRAVITY_PRESETS)}; hops, starts and workers at least 1")
    model = str(args.model.resolve()) if args.model is not None else None
    cases = [(b, a, d) for b in bodies for d in depths for a in angles]
    jobs = [(*case, k / args.starts, args.hops, model) for case in cases for k in range(args.starts)]
    with Pool(args.workers) as pool:
        results = pool.map(run, jobs)
    for case in cases:
        runs = [r for r in results if (r["body"], r["angle"], r["depth"]) == case]
        falls = [r for r in runs if r["fell"]]
        crossed = sum(r["crossed"] for r in runs)
        per = f"{crossed / len(falls):.1f}" if falls else "-"
        ends = ", ".join(f"{n} on the {part}" for part in PARTS if (n := sum(r["part"] == part for r in falls)))
        print(f"{case[0]:>6} {case[1]:4.0f} deg x {case[2]:.2f} m: {len(falls)} of {len(runs)} runs fell, "
              f"{crossed} pits crossed, {per} pits a fall{f' ({ends})' if ends else ''}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
