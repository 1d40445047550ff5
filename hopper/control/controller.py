"""The Python face of the control kernel: its parameters, phase and memory."""

from __future__ import annotations

import numpy as np

from hopper.config import SimConfig
from hopper.control import gait as gaits
from hopper.control.memory import new_memory
from hopper.control.phases import FallCause, Phase
from hopper.layout import ModelLayout


class HopController:
    """Owns the kernel's MEMORY record; `configure()` writes a config's gains, gravity, wheel
    and gait into it (between ticks). The settings themselves live in Simulation.config."""

    def __init__(self, layout: ModelLayout, config: SimConfig) -> None:
        self.mem = new_memory(layout)  # passed to control_tick; everything in it has a name
        (self.mem["x0"], self.mem["z0"]), self.mem["dt"] = layout.torso_origin, config.timestep
        self.configure(config)
        self.reset()

    def configure(self, config: SimConfig) -> None:
        m, g, gait = self.mem, config.gains, config.gait
        m["kp"], m["ki"], m["kd"] = g.kp, g.ki, g.kd
        m["gravity"], m["wheel_on"] = config.gravity, config.wheel
        self.gait = gaits.derive(config.gravity, gait)
        for name, value in self.gait.record().items():
            m[name] = value
        m["stand"], m["crouch"] = gait.stand_height, gait.crouch_height
        m["push"], m["flight_length"], m["spread"] = gait.push_length, gait.flight_length, gait.foot_spread
        m["tuck_length"] = gait.tuck_length
        m["lean"] = gait.crouch_lean
        m["friction"] = gait.friction

    def reset(self, time: float = 0.0, standing: bool = True) -> None:
        """Start in stance (feet believed on the ground when `standing`)."""
        m = self.mem
        for name in (
            "phase_start", "push_done", "integral", "saturated", "wheel_command", "prev_vz",
            "last_contact", "fall_cause", "fall_height",
        ):  # fmt: skip
            m[name] = 0
        m["phase"], m["phase_start"], m["clock"] = int(Phase.STANCE), time, time
        m["contact_l"] = m["contact_r"] = standing
        m["pending_l"] = m["pending_r"] = -1.0

    def field(self, name: str) -> np.ndarray:
        """A live view (shape (1,)) of one field of the kernel's memory, e.g. for a recorder."""
        return self.mem[name]

    @property
    def phase(self) -> Phase:
        return Phase(int(self.mem["phase"][0]))

    @property
    def fall_cause(self) -> FallCause:
        return FallCause(int(self.mem["fall_cause"][0]))

    @property
    def fall_height(self) -> float:
        """Hip above the supporting feet when the fall was called, m (0 in flight)."""
        return float(self.mem["fall_height"][0])

    @property
    def wheel_command(self) -> float:
        """Wheel torque asked this tick, N m."""
        return float(self.mem["wheel_command"][0])
