"""The hop controller: the paper's contact-driven cycle as one compiled kernel per 1 kHz tick.

Modules, one concern each: `phases` (the cycle and its thresholds), `memory` (the kernel's
named record), `legs` (kinematics and leg torques), `wheel` (motor envelope and flight PID),
`contact` (debounced foot contact), `stance` (virtual-model control on the ground), `sensing`
(the simulated IMU, the attitude estimate and the wheel's command delay), `kernel` (the tick:
phases, actuation, metrics) and `controller` (its Python face).
"""

from hopper.control.controller import HopController
from hopper.control.kernel import EV_APEX, EV_FALL, EV_LIFTOFF, EV_TOUCHDOWN, control_tick
from hopper.control.phases import FallCause, Phase

__all__ = ["EV_APEX", "EV_FALL", "EV_LIFTOFF", "EV_TOUCHDOWN", "FallCause", "HopController", "Phase", "control_tick"]
