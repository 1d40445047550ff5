"""The hop cycle's phases and the debounced foot contact detector that drives them."""

from __future__ import annotations

import enum


class Phase(enum.IntEnum):
    """The paper's contact-driven cycle (Sec. VI), plus FALLEN."""

    LANDING = 0  # touchdown: impedance legs absorb the impact
    STANCE = 1  # stabilise over both feet, spin the wheel down
    CROUCH = 2  # lower the hip to load the legs
    PUSH = 3  # extend the legs to the liftoff velocity
    FLIGHT = 4  # ballistic: wheel PID holds the pitch, legs swing to the landing pose
    FALLEN = 5

    @property
    def label(self) -> str:
        return self.name.lower()


GROUND_PHASES = frozenset({Phase.LANDING, Phase.STANCE, Phase.CROUCH, Phase.PUSH})

# The robot weighs 8.2 kg * 1.625 m/s^2 = 13.3 N on the Moon, about 6.7 N a foot: Earth-sized
# thresholds of tens of newtons would never fire (PHYSICS.md).
CONTACT_ON_N = 1.0  # N, normal force that starts a contact
CONTACT_OFF_N = 0.2  # N, below this the contact ends (hysteresis)
DEBOUNCE_S = 0.002  # s a new state must hold before it is believed


class ContactDetector:
    """One foot's contact state with hysteresis and debounce."""

    __slots__ = ("on", "_pending_since")

    def __init__(self) -> None:
        self.on = False
        self._pending_since: float | None = None

    def update(self, force: float, time: float) -> bool:
        """Feed the normal force (N) at `time` (s); returns the debounced contact state."""
        changing = force < CONTACT_OFF_N if self.on else force > CONTACT_ON_N
        if not changing:
            self._pending_since = None
        elif self._pending_since is None:
            self._pending_since = time
        elif time - self._pending_since >= DEBOUNCE_S - 1e-9:
            self.on = not self.on
            self._pending_since = None
        return self.on

    def reset(self, on: bool = False) -> None:
        self.on, self._pending_since = on, None
