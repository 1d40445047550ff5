"""Named commands: what other threads may ask of the simulation, applied by its loop between steps.

Each is a hopper.sim.Command: Simulation.submit() queues it, the loop calls its apply(sim).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Literal

import numpy as np

from hopper.config import Gains, InvalidConfig
from hopper.disturbances import DisturbanceKind
from hopper.schedule import KickSchedule
from hopper.sim import Command as Command  # re-exported: it was defined here before
from hopper.sim import Simulation
from hopper.stand import Injection, StandSimulation


@dataclasses.dataclass(frozen=True)
class SetGains:
    gains: Gains
    source: str = ""  # what chose them when not typed or dragged, e.g. "pole placement, wn 25 rad/s"

    def apply(self, sim: Simulation) -> None:
        sim.set_gains(self.gains, self.source)


@dataclasses.dataclass(frozen=True)
class SetController:
    """Fly another controller from the next tick (hopper.controllers); refused (CommandFailed) if it cannot."""

    spec: str
    params: tuple[tuple[str, float], ...] = ()

    def apply(self, sim: Simulation) -> None:
        sim.set_controller(self.spec, self.params)


@dataclasses.dataclass(frozen=True)
class SetControllerParam:
    name: str
    value: float

    def apply(self, sim: Simulation) -> None:
        sim.set_controller_param(self.name, self.value)


@dataclasses.dataclass(frozen=True)
class SetWheel:
    enabled: bool

    def apply(self, sim: Simulation) -> None:
        sim.set_wheel(self.enabled)


@dataclasses.dataclass(frozen=True)
class SetSensing:
    sensing: Literal["ideal", "realistic"]

    def apply(self, sim: Simulation) -> None:
        sim.set_sensing(self.sensing)


@dataclasses.dataclass(frozen=True)
class SetGravity:
    gravity: float  # m/s^2

    def apply(self, sim: Simulation) -> None:
        sim.set_gravity(self.gravity)


@dataclasses.dataclass(frozen=True)
class SetTerrain:
    terrain: Literal["crater", "flat"]
    seed: int

    def apply(self, sim: Simulation) -> None:
        sim.set_terrain(self.terrain, self.seed)


@dataclasses.dataclass(frozen=True)
class Disturb:
    disturbance: DisturbanceKind
    magnitude: float  # in the disturbance's unit (hopper.disturbances.DISTURBANCE_LIMITS)

    def apply(self, sim: Simulation) -> None:
        sim.disturb(self.disturbance, self.magnitude)


@dataclasses.dataclass(frozen=True)
class Grab:
    """Start a mouse pull (hopper.perturb) at a point of the torso, world (x, z) in m."""

    point: tuple[float, float]

    def apply(self, sim: Simulation) -> None:
        sim.grab(self.point)


@dataclasses.dataclass(frozen=True)
class PullTo:
    """Move the running pull's target to world (x, z), m."""

    target: tuple[float, float]

    def apply(self, sim: Simulation) -> None:
        sim.pull_to(self.target)


@dataclasses.dataclass(frozen=True)
class Release:
    """End the running pull; it is recorded as a disturbance."""

    def apply(self, sim: Simulation) -> None:
        sim.release()


@dataclasses.dataclass(frozen=True)
class SetSchedule:
    schedule: KickSchedule | None  # None clears it

    def apply(self, sim: Simulation) -> None:
        sim.set_schedule(self.schedule)


@dataclasses.dataclass(frozen=True)
class Reset:
    reason: str = "user"

    def apply(self, sim: Simulation) -> None:
        sim.reset(reason=self.reason)


@dataclasses.dataclass(frozen=True)
class SetReference:
    """Step the stand's pitch reference to `pitch` (rad); refused off the stand."""

    pitch: float  # rad

    def apply(self, sim: Simulation) -> None:
        if not isinstance(sim, StandSimulation):
            raise InvalidConfig("a reference step needs the stand: choose a stand mode first")
        sim.set_reference(self.pitch)


@dataclasses.dataclass(frozen=True, eq=False)
class Inject:
    """Play `signal` into the stand's loop from the next tick (hopper.stand.StandSimulation.inject);
    refused off the stand or while another plays. `done(injection)` is called on the loop's thread
    when it has played, or was stopped (injection.stopped says why)."""

    signal: np.ndarray  # one sample a tick: N m at "input", rad at "reference"
    at: Literal["input", "reference"]
    done: Callable[[Injection], None]
    what: str = ""  # for the event log: "a 20 s logarithmic chirp, 0.5-40 Hz, 2 N m"

    def apply(self, sim: Simulation) -> None:
        if not isinstance(sim, StandSimulation):
            raise InvalidConfig("an injection needs the stand: choose a stand mode first")
        sim.inject(self.signal, self.at, self.done, self.what)
