"""The dashboard loop's own commands (pause, speed, steps, stay fallen, restore, mode), on the simulation's queue.

Viser's threads never write the loop's flags: they submit these, and the loop applies them with the
simulation's commands, in the order they came, at the top of its next round (Dashboard._run).
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from hopper.sim import Simulation
    from hopper.snapshot import Snapshot


class Loop(Protocol):
    """What these commands change: the loop's state, on the loop's thread (hopper.app.dashboard.server)."""

    def apply_paused(self, paused: bool) -> None: ...

    def apply_speed(self, speed: float) -> None: ...

    def apply_steps(self, count: int) -> None: ...

    def apply_stay_fallen(self, stay: bool) -> None: ...

    def apply_restore(self, snapshot: Snapshot, what: str) -> None: ...

    def apply_mode(self, mode: str) -> None: ...


@dataclasses.dataclass(frozen=True)
class Pause:
    loop: Loop
    paused: bool

    def apply(self, sim: Simulation) -> None:
        self.loop.apply_paused(self.paused)


@dataclasses.dataclass(frozen=True)
class SetSpeed:
    loop: Loop
    speed: float  # x real time

    def apply(self, sim: Simulation) -> None:
        self.loop.apply_speed(self.speed)


@dataclasses.dataclass(frozen=True)
class Steps:
    loop: Loop
    count: int  # ticks to step, paused or not

    def apply(self, sim: Simulation) -> None:
        self.loop.apply_steps(self.count)


@dataclasses.dataclass(frozen=True)
class StayFallen:
    loop: Loop
    stay: bool

    def apply(self, sim: Simulation) -> None:
        self.loop.apply_stay_fallen(self.stay)


@dataclasses.dataclass(frozen=True)
class Restore:
    loop: Loop
    snapshot: Snapshot
    what: str  # for the event log: "the moment 5.0 s back", "keyframe 'mid hop'"

    def apply(self, sim: Simulation) -> None:
        self.loop.apply_restore(self.snapshot, self.what)


@dataclasses.dataclass(frozen=True)
class SetMode:
    """Hop, or put the robot on the test stand ("stand locked", "stand free"): the loop rebuilds its
    simulation between rounds (Dashboard.apply_mode)."""

    loop: Loop
    mode: str

    def apply(self, sim: Simulation) -> None:
        self.loop.apply_mode(self.mode)
