"""Where a log was recorded: the ground, gravity and robot a replay or a fit puts the model in.

A log written here (capture, or a log exported from our recordings) carries its world, so that a
replay flies it on the same ground by default; a real robot's log has none, and the command line
or the dashboard says which world to use. As text it is a flat string map (an MCAP channel's
metadata, an .npz entry as JSON): `to_meta` and `from_meta`, which refuses a bad value in one line.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

from hopper.config import MOON_GRAVITY, SimConfig

TERRAINS = ("flat", "crater")


@dataclasses.dataclass(frozen=True, kw_only=True)
class World:
    """The ground and gravity of a log, and the robot's MJCF (None: the packaged one)."""

    terrain: str = "flat"  # "flat" or "crater"
    seed: int = 0  # the crater field's
    gravity: float = MOON_GRAVITY  # m/s^2
    model: str | None = None  # the robot's MJCF path (SimConfig.model)

    def config(self) -> SimConfig:
        return SimConfig(terrain=self.terrain, seed=self.seed, gravity=self.gravity, model=self.model)  # type: ignore[arg-type]

    def describe(self) -> str:
        robot = f", model {self.model}" if self.model else ""
        ground = f"crater seed {self.seed}" if self.terrain == "crater" else "flat"
        return f"{ground}, {self.gravity:g} m/s^2{robot}"

    def to_meta(self) -> dict[str, str]:
        meta = {"terrain": self.terrain, "seed": str(self.seed), "gravity": repr(self.gravity)}
        return meta | ({"model": self.model} if self.model else {})


def of_config(config: SimConfig) -> World:
    return World(terrain=config.terrain, seed=config.seed, gravity=config.gravity, model=config.model)


def from_meta(meta: Mapping[str, str]) -> World:
    """The World written by `to_meta`; ValueError saying which value is bad (a reader adds where)."""
    terrain = meta.get("terrain", "")
    if terrain not in TERRAINS:
        raise ValueError(f"its world's terrain is {terrain!r}, expected one of {', '.join(TERRAINS)}")
    try:
        seed, gravity = int(meta.get("seed", "")), float(meta.get("gravity", ""))
    except ValueError:
        raise ValueError(f"its world's seed or gravity is not a number ({dict(meta)})") from None
    if seed < 0 or not math.isfinite(gravity) or gravity <= 0.0:
        raise ValueError(f"its world's seed must be >= 0 and gravity > 0 m/s^2, got {seed} and {gravity:g}")
    return World(terrain=terrain, seed=seed, gravity=gravity, model=meta.get("model") or None)


def resolve(
    recorded: World | None,
    terrain: str | None = None,
    seed: int | None = None,
    gravity: float | None = None,
    model: str | None = None,
) -> tuple[World, str]:
    """The world to replay a log in, and a line saying where it came from: each of terrain, seed and
    gravity as asked, else the log's (`recorded`), else World's default. The robot is always `model`
    (None: the packaged one): the log's is the robot being compared with, not the model."""
    base = recorded or World()
    world = World(
        terrain=base.terrain if terrain is None else terrain,
        seed=base.seed if seed is None else seed,
        gravity=base.gravity if gravity is None else gravity,
        model=model,
    )
    asked = [k for k, v in (("terrain", terrain), ("seed", seed), ("gravity", gravity)) if v is not None]
    if recorded is None:
        origin = (
            "the log names no world: "
            + ("as asked" if asked else "the defaults")
            + (" (the rest the defaults)" if asked and len(asked) < 3 else "")
        )
    elif asked:
        origin = f"as asked ({', '.join(asked)}); the log's is {recorded.describe()}"
    else:
        origin = "the log's"
    return world, origin
