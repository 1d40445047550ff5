"""The disturbances a run can be given: kinds, display names, units and largest magnitudes."""

from __future__ import annotations

from typing import Literal

# A leaf: the simulation applies these, schedules, commands, events, specs and panels check and name
# them, so nothing here may import any of those (it would close an import cycle).
DisturbanceKind = Literal["pitch_kick", "push_forward", "push_backward", "torque_pulse"]
DISTURBANCE_NAMES: dict[str, str] = {
    "pitch_kick": "pitch kick",
    "push_forward": "push ▶",
    "push_backward": "push ◀",
    "torque_pulse": "torque pulse",
}
DISTURBANCE_LIMITS: dict[str, tuple[float, str]] = {  # largest magnitude, unit
    "pitch_kick": (5.0, "N m s"),  # angular impulse on the torso
    "push_forward": (20.0, "N s"),  # linear impulse on the torso
    "push_backward": (20.0, "N s"),
    "torque_pulse": (30.0, "N m"),  # pitch torque on the torso for hopper.sim.TORQUE_PULSE_S, in flight
}
