"""Where a log was recorded: the ground, gravity, robot and wheel-command delay a replay or a fit uses.

A log written here (capture, or a log exported from our recordings) carries its world, so that a
replay flies it on the same ground by default; a real robot's log has none, and the command line
or the dashboard says which world to use. As text it is a flat string map (an MCAP channel's
metadata, an .npz entry as JSON): `to_meta` and `from_meta`, which refuses a bad value in one line.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

from hopper.config import MAX_MOTOR_DELAY_TICKS, MOON_GRAVITY, SensingParams, SimConfig

TERRAINS = ("flat", "crater")
# Ticks (1 ms) from a wheel command to its torque when a log does not say: realistic sensing's.
DEFAULT_DELAY_TICKS = SensingParams().motor_delay_ticks


@dataclasses.dataclass(frozen=True, kw_only=True)
class World:
    """The ground and gravity of a log, the robot's MJCF (None: the packaged one) and how late its
    wheel commands reached the motor (None: not recorded, DEFAULT_DELAY_TICKS is assumed)."""

    terrain: str = "flat"  # "flat" or "crater"
    seed: int = 0  # the crater field's
    gravity: float = MOON_GRAVITY  # m/s^2
    model: str | None = None  # the robot's MJCF path (SimConfig.model)
    delay_ticks: int | None = None  # 1 ms ticks from the logged wheel command to the motor

    @property
    def command_delay(self) -> int:
        """Ticks a replay delays the logged wheel commands by."""
        return DEFAULT_DELAY_TICKS if self.delay_ticks is None else self.delay_ticks

    def config(self) -> SimConfig:
        return SimConfig(terrain=self.terrain, seed=self.seed, gravity=self.gravity, model=self.model)  # type: ignore[arg-type]

    def describe(self) -> str:
        robot = f", model {self.model}" if self.model else ""
        ground = f"crater seed {self.seed}" if self.terrain == "crater" else "flat"
        return f"{ground}, {self.gravity:g} m/s^2{robot}, wheel commands {self.command_delay} ticks late"

    def to_meta(self) -> dict[str, str]:
        meta = {"terrain": self.terrain, "seed": str(self.seed), "gravity": repr(self.gravity)}
        meta |= {"delay_ticks": str(self.delay_ticks)} if self.delay_ticks is not None else {}
        return meta | ({"model": self.model} if self.model else {})


def of_config(config: SimConfig) -> World:
    """The world of a run of `config`; its wheel commands are late only under realistic sensing."""
    delay = config.sensor.motor_delay_ticks if config.sensing == "realistic" else 0
    return World(
        terrain=config.terrain, seed=config.seed, gravity=config.gravity, model=config.model, delay_ticks=delay
    )


def check_delay(ticks: int) -> int:
    """`ticks` if the kernel's delay line can hold it; ValueError naming the range otherwise."""
    if not 0 <= ticks <= MAX_MOTOR_DELAY_TICKS:
        raise ValueError(f"the wheel command delay must be 0..{MAX_MOTOR_DELAY_TICKS} ticks, got {ticks}")
    return ticks


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
    delay = meta.get("delay_ticks")  # None in logs written before it was recorded
    if delay is not None:
        if not delay.isdigit() or int(delay) > MAX_MOTOR_DELAY_TICKS:
            raise ValueError(
                f"its world's delay_ticks must be a whole number 0..{MAX_MOTOR_DELAY_TICKS}, got {delay!r}"
            )
        delay = int(delay)
    return World(terrain=terrain, seed=seed, gravity=gravity, model=meta.get("model") or None, delay_ticks=delay)


def resolve(
    recorded: World | None,
    terrain: str | None = None,
    seed: int | None = None,
    gravity: float | None = None,
    model: str | None = None,
    delay_ticks: int | None = None,
) -> tuple[World, str]:
    """The world to replay a log in, and a line saying where it came from: each of terrain, seed,
    gravity and the command delay as asked, else the log's (`recorded`), else World's default. The
    robot is always `model` (None: the packaged one): the log's is the robot being compared with."""
    base = recorded or World()
    world = World(
        terrain=base.terrain if terrain is None else terrain,
        seed=base.seed if seed is None else seed,
        gravity=base.gravity if gravity is None else gravity,
        model=model,
        delay_ticks=base.delay_ticks if delay_ticks is None else check_delay(delay_ticks),
    )
    flags = (("terrain", terrain), ("seed", seed), ("gravity", gravity), ("delay", delay_ticks))
    asked = [k for k, v in flags if v is not None]
    if recorded is None:
        origin = (
            "the log names no world: "
            + ("as asked" if asked else "the defaults")
            + (" (the rest the defaults)" if asked and len(asked) < len(flags) else "")
        )
    elif asked:
        origin = f"as asked ({', '.join(asked)}); the log's is {recorded.describe()}"
    else:
        origin = "the log's"
    return world, origin
