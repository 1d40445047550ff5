"""The hop cycle's phases, why a fall was called, and the foot contact thresholds that drive them."""

from __future__ import annotations

import enum
import math


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


class FallCause(enum.IntEnum):
    """What tripped the fall detector (the kernel stores the code)."""

    NONE = 0
    PITCH_LIMIT = 1  # |pitch| beyond FALL_PITCH
    HIP_HEIGHT = 2  # hip closer than FALL_HIP_HEIGHT to the feet while on the ground

    def describe(self) -> str:
        return {
            FallCause.NONE: "no fall",
            FallCause.PITCH_LIMIT: f"pitch beyond the {math.degrees(FALL_PITCH):.0f}° limit",
            FallCause.HIP_HEIGHT: f"hip lower than {FALL_HIP_HEIGHT:g} m above the feet (legs collapsed)",
        }[self]


# Fall: beyond these the legs cannot recover the body.
FALL_PITCH = math.radians(60.0)
FALL_HIP_HEIGHT = 0.35  # m, hip above the feet in stance

# Contact force thresholds scale with the weight (hopper.control.gait); the holds below do not:
# they filter the contact's own bounce (its 5 ms solref time constant), not the gait.
DEBOUNCE_ON_S = 0.002  # s a touch must hold before it is believed
# A foot reaching for uneven ground taps it several times before it settles: leaving takes
# longer to believe than arriving, or the stance controller would flicker between supports.
DEBOUNCE_OFF_S = 0.015  # s
