"""A repeatable test: the same disturbance at the same moment of every (or every Nth) flight.

`KickSchedule("pitch_kick", 0.3, delay_s=0.15)` kicks the torso 150 ms after each liftoff, so
that each hop is the same experiment and its response metrics (hopper.metrics.ResponseMetrics)
compare gain sets. The Simulation applies it (SetSchedule, ScheduleChanged, a Disturbance event
marked `scheduled` when it fires); a flight that lands before the delay is not kicked.
"""

from __future__ import annotations

import dataclasses
import math
import re

from hopper.config import require_finite
from hopper.disturbances import DISTURBANCE_LIMITS, DISTURBANCE_NAMES

MAX_DELAY_S = 2.0  # s after liftoff; flights last ~0.4-1.3 s (Moon), longer only in very low gravity
MAX_EVERY = 1000
DEFAULT_DELAY_S = 0.15  # s, as an armed torque pulse (hopper.sim.TORQUE_PULSE_DELAY_S)


@dataclasses.dataclass(frozen=True)
class KickSchedule:
    """`kind` (a hopper.disturbances.DISTURBANCE_LIMITS key) of `magnitude` (its unit), `delay_s` after the
    liftoff of every `every`-th hop (hops whose index, counted from 1 since the reset, divides by it)."""

    kind: str
    magnitude: float
    delay_s: float = DEFAULT_DELAY_S
    every: int = 1

    def __post_init__(self) -> None:
        if self.kind not in DISTURBANCE_LIMITS:
            raise ValueError(f"unknown disturbance {self.kind!r}; choose from {', '.join(DISTURBANCE_LIMITS)}")
        limit, unit = DISTURBANCE_LIMITS[self.kind]
        require_finite(f"{self.kind} magnitude", self.magnitude, -limit, limit, unit)
        require_finite("schedule delay", self.delay_s, 0.0, MAX_DELAY_S, "s")
        if isinstance(self.every, bool) or not isinstance(self.every, int) or not 1 <= self.every <= MAX_EVERY:
            raise ValueError(f"schedule 'every' must be a whole number of hops in [1, {MAX_EVERY}], got {self.every!r}")

    def due(self, hop_index: int) -> bool:
        """Whether the flight of hop `hop_index` (from 1) is kicked."""
        return hop_index % self.every == 0

    def describe(self) -> str:
        n = self.every
        which = "every liftoff" if n == 1 else f"the liftoff of hops {n}, {2 * n}, {3 * n}, …"
        unit = DISTURBANCE_LIMITS[self.kind][1]
        return f"{DISTURBANCE_NAMES[self.kind]} {self.magnitude:+g} {unit}, {self.delay_s * 1000:g} ms after {which}"

    def spec(self) -> str:
        """The text parse() reads back."""
        every = f",every:{self.every}" if self.every != 1 else ""
        return f"{self.kind}:{self.magnitude:g}@{self.delay_s * 1000:g}ms{every}"


# The delay and the count after "@" in any order; the count alone may also follow a comma
# (`pitch_kick:0.3,every:3`), as the form reads with the delay left out.
_SPEC = re.compile(r"^(?P<kind>[a-z_]+):(?P<mag>[^@,]+)(?:@(?P<when>.+)|,(?P<every>every:[^,@]*))?$")


def parse(text: str) -> KickSchedule:
    """`KIND:MAGNITUDE[@DELAYms][,every:N]`, e.g. `pitch_kick:0.3@150ms`, `torque_pulse:10@every:3`,
    `push_forward:2@200ms,every:2`, `pitch_kick:0.3,every:3`. Raises ValueError with a one-line message."""
    form = "expected KIND:MAGNITUDE[@DELAYms][,every:N], e.g. pitch_kick:0.3@150ms"
    match = _SPEC.match(text.strip())
    if not match:
        raise ValueError(f"bad schedule {text!r}: {form}")
    try:
        magnitude = float(match["mag"])
    except ValueError:
        raise ValueError(f"bad schedule magnitude {match['mag']!r}: {form}") from None
    delay, every = DEFAULT_DELAY_S, 1
    for part in (match["when"] or match["every"] or "").split(","):
        part = part.strip()
        if not part:
            continue
        if part.startswith("every:"):
            count = part.removeprefix("every:")
            if not count.isdigit():
                raise ValueError(f"bad schedule 'every' {count!r}: a whole number of hops")
            every = int(count)
        elif part.endswith("ms"):
            try:
                delay = float(part.removesuffix("ms")) / 1000.0
            except ValueError:
                raise ValueError(f"bad schedule delay {part!r}: {form}") from None
            if not math.isfinite(delay):
                raise ValueError(f"bad schedule delay {part!r}: {form}")
        else:
            raise ValueError(f"bad schedule part {part!r}: {form}")
    return KickSchedule(match["kind"], magnitude, delay, every)
