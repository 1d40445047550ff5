"""GUI panels, one small builder each; every builder returns its handles and a reset to defaults."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Protocol

import viser

from hopper.sim import Command


class LoopControls(Protocol):
    """What the panels may ask of the simulation loop (never MjData itself): each call queues a
    command that the loop applies with the simulation's, in order (loop_commands)."""

    stay_fallen: bool  # read only: set_stay_fallen changes it

    def set_stay_fallen(self, stay: bool) -> None: ...

    def set_paused(self, paused: bool) -> None: ...

    def request_steps(self, count: int) -> None: ...

    def set_speed(self, speed: float) -> None: ...

    def set_mode(self, mode: str) -> None: ...


@dataclasses.dataclass(frozen=True)
class PanelContext:
    """Shared by the builders: the server, the command queue and the loop's controls."""

    server: viser.ViserServer
    submit: Callable[[Command], None]
    loop: LoopControls
