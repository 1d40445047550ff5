"""The hop cycle's phases and the foot contact thresholds that drive them."""

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


# The robot weighs 8.2 kg * 1.625 m/s^2 = 13.3 N on the Moon, about 6.7 N a foot: Earth-sized
# thresholds of tens of newtons would never fire (PHYSICS.md).
CONTACT_ON_N = 1.0  # N, normal force that starts a contact
CONTACT_OFF_N = 0.2  # N, below this the contact ends (hysteresis)
DEBOUNCE_ON_S = 0.002  # s a touch must hold before it is believed
# A foot reaching for uneven ground taps it several times before it settles: leaving takes
# longer to believe than arriving, or the stance controller would flicker between supports.
DEBOUNCE_OFF_S = 0.015  # s
