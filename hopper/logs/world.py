"""Where a log was recorded: the ground, gravity, robot, wheel-command delay and wheel motor a replay or a fit uses.

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
from hopper.errors import ModelError
from hopper.robot import PACKAGED, PACKAGED_TOLERANCE, Robot

TERRAINS = ("flat", "crater")
# Ticks (1 ms) from a wheel command to its torque when a log does not say: realistic sensing's.
DEFAULT_DELAY_TICKS = SensingParams().motor_delay_ticks


@dataclasses.dataclass(frozen=True, kw_only=True)
class World:
    """The ground and gravity of a log, the robot's MJCF (None: the packaged one), how late its
    wheel commands reached the motor (None: not recorded, DEFAULT_DELAY_TICKS is assumed) and the
    wheel motor they were made for (None: the packaged one's).

    A log's wheel column is a torque command; the robot's drive turned it into a voltage by
    inverting the motor its controller knows (hopper.control.wheel.wheel_ctrl: the flown robot's,
    hopper.robot.Robot.of). A replay's drive inverts that same motor, and the model replayed turns
    the voltage into torque with its own: the model that made the log then replays it exactly, and
    a model whose motor differs from the robot's shows it (identify's motor_torque).
    """

    terrain: str = "flat"  # "flat" or "crater"
    seed: int = 0  # the crater field's
    gravity: float = MOON_GRAVITY  # m/s^2
    model: str | None = None  # the robot's MJCF path (SimConfig.model)
    delay_ticks: int | None = None  # 1 ms ticks from the logged wheel command to the motor
    # (stall torque N m, back-EMF slope N m s/rad) at the wheel of the motor the commands were made for
    wheel_motor: tuple[float, float] | None = None

    @property
    def command_delay(self) -> int:
        """Ticks a replay delays the logged wheel commands by."""
        return DEFAULT_DELAY_TICKS if self.delay_ticks is None else self.delay_ticks

    @property
    def drive(self) -> Robot:
        """The motor a replay's drive inverts (hopper.logs.replay.simulate): the one the commands were made for."""
        if self.wheel_motor is None:
            return PACKAGED
        limit, damping = self.wheel_motor
        return dataclasses.replace(PACKAGED, wheel_torque_limit=limit, wheel_no_load_speed=limit / damping)

    def config(self) -> SimConfig:
        return SimConfig(terrain=self.terrain, seed=self.seed, gravity=self.gravity, model=self.model)  # type: ignore[arg-type]

    def describe(self) -> str:
        robot = f", model {self.model}" if self.model else ""
        ground = f"crater seed {self.seed}" if self.terrain == "crater" else "flat"
        d = self.drive
        motor = (
            ""
            if packaged_motor(d)
            else f" for a {d.wheel_torque_limit:.4g} N m, {d.wheel_no_load_speed:.4g} rad/s wheel motor"
        )
        return f"{ground}, {self.gravity:g} m/s^2{robot}, wheel commands {self.command_delay} ticks late{motor}"

    def to_meta(self) -> dict[str, str]:
        meta = {"terrain": self.terrain, "seed": str(self.seed), "gravity": repr(self.gravity)}
        meta |= {"delay_ticks": str(self.delay_ticks)} if self.delay_ticks is not None else {}
        if self.wheel_motor is not None:
            meta |= {"wheel_torque_limit": repr(self.wheel_motor[0]), "wheel_damping": repr(self.wheel_motor[1])}
        return meta | ({"model": self.model} if self.model else {})


def packaged_motor(robot: Robot) -> bool:
    """`robot`'s wheel motor is the packaged one (within hopper.robot.PACKAGED_TOLERANCE)."""
    return all(
        abs(getattr(robot, f) - getattr(PACKAGED, f)) <= PACKAGED_TOLERANCE * getattr(PACKAGED, f)
        for f in ("wheel_torque_limit", "wheel_no_load_speed")
    )


def motor_of(robot: Robot) -> tuple[float, float]:
    """World.wheel_motor for `robot`'s wheel motor."""
    return robot.wheel_torque_limit, robot.wheel_damping


def of_config(config: SimConfig, robot: Robot | None = None) -> World:
    """The world of a run of `config` whose controller knows `robot` (hopper.sim.Simulation.robot;
    None: the motor is not recorded); its wheel commands are late only under realistic sensing."""
    return World(
        terrain=config.terrain, seed=config.seed, gravity=config.gravity, model=config.model,
        delay_ticks=config.command_delay_ticks,
        wheel_motor=None if robot is None else motor_of(robot),
    )  # fmt: skip


def model_motor(path: str | None) -> tuple[float, float]:
    """World.wheel_motor of the robot MJCF at `path` (None: the packaged); ModelError in one line."""
    from hopper.model import robot_of  # here: compiling a model is not every reader's business

    return motor_of(robot_of(SimConfig(model=path, terrain="flat")))


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
    return World(
        terrain=terrain, seed=seed, gravity=gravity, model=meta.get("model") or None, delay_ticks=delay,
        wheel_motor=_motor_meta(meta),
    )  # fmt: skip


def _motor_meta(meta: Mapping[str, str]) -> tuple[float, float] | None:
    """World.wheel_motor from `to_meta`'s keys (None in logs written before it was recorded)."""
    given = [meta.get(k) for k in ("wheel_torque_limit", "wheel_damping")]
    if given == [None, None]:
        return None
    try:
        limit, damping = (float(v) for v in given)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"its world's wheel_torque_limit and wheel_damping must be two numbers, got {given}") from None
    if not (math.isfinite(limit) and math.isfinite(damping) and limit > 0.0 and damping > 0.0):
        raise ValueError(f"its world's wheel motor must have a positive stall torque and slope, got {given}")
    return limit, damping


def resolve(
    recorded: World | None,
    terrain: str | None = None,
    seed: int | None = None,
    gravity: float | None = None,
    model: str | None = None,
    delay_ticks: int | None = None,
    drive: str | None = None,
) -> tuple[World, str]:
    """The world to replay a log in, and a line saying where it came from: each of terrain, seed,
    gravity, the command delay and the wheel motor its commands were made for (`drive`: an MJCF's
    path or "packaged") as asked, else the log's (`recorded`), else World's default. The robot is
    always `model` (None: the packaged one): the log's is the robot being compared with.
    ModelError in one line if the robot whose motor is needed cannot be read."""
    base = recorded or World()
    world = World(
        terrain=base.terrain if terrain is None else terrain,
        seed=base.seed if seed is None else seed,
        gravity=base.gravity if gravity is None else gravity,
        model=model,
        delay_ticks=base.delay_ticks if delay_ticks is None else check_delay(delay_ticks),
        wheel_motor=_drive(base, drive),
    )
    flags = (("terrain", terrain), ("seed", seed), ("gravity", gravity), ("delay", delay_ticks), ("drive", drive))
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


def _drive(recorded: World, drive: str | None) -> tuple[float, float] | None:
    """World.wheel_motor: `drive`'s (a path or "packaged"), else the log's, else its robot's MJCF's
    (a log written before the motor was recorded), else None (the packaged motor's)."""
    if drive is not None:
        return model_motor(None if drive == "packaged" else drive)
    if recorded.wheel_motor is not None or recorded.model is None:
        return recorded.wheel_motor
    try:
        return model_motor(recorded.model)
    except ModelError as exc:
        raise ModelError(f"the log's robot, whose wheel motor its commands were made for: {exc}") from None
