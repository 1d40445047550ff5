"""Discrete full-state LQR on the flight's attitude plant: pitch, rate and the wheel's speed."""

from __future__ import annotations

import math

import control as ct
import numpy as np

from hopper.config import WHEEL_TORQUE_LIMIT
from hopper.controllers.api import ControllerContext, ControllerError, Observation, Param
from hopper.laws.plant import AttitudeModel, attitude_model, closed_loop_radius


class LQR:
    """tau = K (pitch, rate, wheel speed), K from control.dlqr on hopper.laws.plant's model at the
    config's gravity and gait, redesigned when gravity or a param changes.

    The weights follow Bryson's rule: each state's cost is 1 at its tolerance, the torque's at
    torque_scale. Weighting the wheel's speed makes the law spend the wheel's momentum with care:
    in flight the total momentum is conserved, so the wheel's speed is only what the torso's
    motion leaves it, and the law trades pitch against a full wheel. The design assumes no command
    delay; with realistic sensing the motor's delay lowers its margins (hopper.analysis.loop measures them).
    """

    params = (
        Param("pitch_tol", 2.0, (0.05, 30.0), "deg"),
        Param("rate_tol", 40.0, (0.5, 1000.0), "deg/s"),
        Param("wheel_tol", 1.0, (0.05, 10.0), "x top speed"),
        Param("torque_scale", WHEEL_TORQUE_LIMIT, (0.5, 300.0), "N m"),
    )

    def __init__(self) -> None:
        self.model: AttitudeModel | None = None
        self.gain = np.zeros(3)  # N m per (rad, rad/s, rad/s)
        self._designed: tuple[float, ...] | None = None
        self._k = (0.0, 0.0, 0.0)

    def configure(self, context: ControllerContext) -> None:
        self.model = attitude_model(context.config)
        self._designed = None

    def design(self) -> np.ndarray:
        """K for the present params; ControllerError if the loop it closes on the full plant is unstable."""
        if self.model is None:
            raise ControllerError("LQR needs its plant: it is configured when attached to a simulation")
        m = self.model
        top = m.full.robot.wheel_no_load_speed  # rad/s, the plant's wheel's
        scales = (math.radians(self.pitch_tol), math.radians(self.rate_tol), self.wheel_tol * top)
        q = np.diag([1.0 / s**2 for s in scales])
        r = np.array([[1.0 / self.torque_scale**2]])
        k, _, _ = ct.dlqr(m.a, m.b.reshape(3, 1), q, r)
        gain = -np.asarray(k).ravel()  # control's u = -K x; the API's torque is the command itself
        radius = closed_loop_radius(m, gain)
        if radius >= 1.0:
            raise ControllerError(f"LQR: these weights destabilise the attitude plant (spectral radius {radius:.4f})")
        return gain

    def state_feedback(self) -> np.ndarray:
        """K for the present params, N m per (rad, rad/s, rad/s): a linear law (the loop analysis reads it)."""
        key = (self.pitch_tol, self.rate_tol, self.wheel_tol, self.torque_scale)
        if key != self._designed:
            self.gain, self._designed = self.design(), key
            # The flight's copy, set with the gain: a design asked first by the loop analysis (the
            # dashboard shows K before any flight) left it at zero, and the LQR flew no torque.
            self._k = tuple(float(v) for v in self.gain)  # Python floats: a numpy scalar a tick costs
        return self.gain

    def __call__(self, obs: Observation) -> float:
        if (self.pitch_tol, self.rate_tol, self.wheel_tol, self.torque_scale) != self._designed:
            self.state_feedback()
        kp, kd, kw = self._k
        return kp * obs.pitch + kd * obs.rate + kw * obs.wheel_speed
