"""A test-only command: run any function on the simulation's thread, between steps."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

from hopper.sim import Simulation


@dataclasses.dataclass(frozen=True)
class Call:
    """`sim.submit(Call(fn))` runs fn(sim) where commands run; for tests that poke the state."""

    fn: Callable[[Simulation], Any]

    def apply(self, sim: Simulation) -> None:
        self.fn(sim)
