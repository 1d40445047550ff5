"""The loop the model predicts, to lay the measured one over: L, S, T and the reference's closed loop.

The plant is the simulation linearized where it runs (hopper.analysis.linearize.flight_plant: on the
stand, or early in a flight), the law is the controller's, if it is linear (the PID's gains, or an
LQR's state feedback), and the delays are the ones the kernel really has: the gyro read one tick
late (the kernel reads the sensors mj_step computed before it integrated), the realistic mode's
attitude estimate integrating that gyro, and its motor delay line. The loop is broken where the
injection enters, at the wheel torque before the delay line: L = -K (zI - A)^-1 B.
"""

from __future__ import annotations

import dataclasses
import math

import control as ct
import numpy as np

from hopper.analysis.frequency import Margins, margins
from hopper.analysis.linearize import flight_plant
from hopper.analysis.loop import Plant
from hopper.sim import Simulation

GRID = np.geomspace(0.1, 499.0, 3000)  # Hz: where the model's margins are found (up to Nyquist)


@dataclasses.dataclass(frozen=True)
class LinearLaw:
    """tau = kp pitch + kd rate + kw wheel_speed + ki int pitch (N m per rad, rad/s, rad/s, rad s)."""

    name: str
    kp: float
    kd: float
    ki: float = 0.0
    kw: float = 0.0


def linear_law(sim: Simulation) -> LinearLaw | None:
    """The simulation's flight law as a LinearLaw, or None if it is not linear (MPC, a policy, ...):
    the paper's PID (its gains) or any controller with a `state_feedback()` of (pitch, rate, wheel)."""
    law = sim.law
    if law.compiled == "pid":
        g = sim.config.gains
        return LinearLaw(law.name, g.kp, g.kd, g.ki)
    feedback = getattr(law.controller, "state_feedback", None)
    if callable(feedback):
        kp, kd, kw = (float(v) for v in np.asarray(feedback(), float).ravel()[:3])
        return LinearLaw(law.name, kp, kd, 0.0, kw)
    if law.name == "PaperPID":  # the PID flown through the API: the same law
        v = law.values
        return LinearLaw(law.name, v["kp"], v["kd"], v["ki"])
    return None


@dataclasses.dataclass(frozen=True)
class Loop:
    """The law closed around the plant, sampled: z' = a z + b u (u the wheel torque, N m, at the
    injection point), u_c = k z; a reference r adds kr r to u_c and ar r to z'."""

    a: np.ndarray  # (m, m)
    b: np.ndarray  # (m, 1)
    k: np.ndarray  # (1, m)
    ar: np.ndarray  # (m, 1)
    kr: float
    pitch: int  # the true pitch in z
    dt: float

    def open_loop(self) -> ct.StateSpace:
        """L: from the torque at the injection point to minus the law's output."""
        return ct.ss(self.a, self.b, -self.k, np.zeros((1, 1)), self.dt)

    def reference_loop(self) -> ct.StateSpace:
        """From the pitch reference (rad) to the true pitch (rad), the loop closed."""
        c = np.zeros((1, len(self.a)))
        c[0, self.pitch] = 1.0
        return ct.ss(self.a + self.b @ self.k, self.b * self.kr + self.ar, c, np.zeros((1, 1)), self.dt)


def close_law(plant: Plant, law: LinearLaw, wheel: int, delay: int = 0, estimated: bool = False) -> Loop:
    """Close `law` around `plant` with the gyro's one-tick lag, the integral (if ki), the estimator's
    integration of the gyro (`estimated`: realistic sensing in the air) and `delay` motor ticks.
    `wheel` is the wheel speed's index in the plant's state."""
    n, dt = len(plant.a), plant.dt
    lag = n  # the gyro sample the next tick reads: this tick's rate
    est = n + 1 if estimated else None  # the attitude estimate before this tick's gyro
    integral = n + 1 + int(estimated) if law.ki else None
    first = n + 1 + int(estimated) + int(bool(law.ki))
    m = first + delay
    a, b, k, ar = np.zeros((m, m)), np.zeros((m, 1)), np.zeros((1, m)), np.zeros((m, 1))
    a[:n, :n] = plant.a
    a[lag, plant.rate] = 1.0
    if plant.gyro is not None:  # the leg servos read the late gyro too
        a[:n, lag] += plant.gyro
    pitch_row = np.zeros(m)  # the law's pitch, as a row over z
    if est is None:
        pitch_row[plant.pitch] = 1.0
    else:  # the estimate integrates the (late) gyro: e = E + dt r_lag, and E' = e
        a[est, est], a[est, lag] = 1.0, dt
        pitch_row[est], pitch_row[lag] = 1.0, dt
        if plant.estimate is not None:  # the leg servos read it too
            a[:n, est] += plant.estimate
    k[0] = law.kp * pitch_row
    k[0, lag] += law.kd
    k[0, wheel] += law.kw
    if integral is not None:  # the kernel's integral: int += pitch dt after the command used it
        a[integral] += dt * pitch_row
        a[integral, integral] += 1.0
        k[0, integral] += law.ki
        ar[integral, 0] = -dt
    if delay:
        a[:n, m - 1 : m] = plant.b  # the oldest register drives the wheel
        a[first + 1 : m, first : m - 1] = np.eye(delay - 1)
        b[first, 0] = 1.0
    else:
        b[:n] = plant.b
    return Loop(a=a, b=b, k=k, ar=ar, kr=-law.kp, pitch=plant.pitch, dt=dt)


def loop_of(sim: Simulation, law: LinearLaw | None = None) -> Loop | None:
    """The predicted loop of `sim` where it is now (on the stand, or in flight), None if its law is
    not linear."""
    law = law or linear_law(sim)
    if law is None:
        return None
    plant = flight_plant(sim, lagged_gyro=True)
    wheel = sim.model.nv + sim.layout.v_wheel
    estimated = sim.config.sensing == "realistic"
    return close_law(plant, law, wheel, delay=sim.config.command_delay_ticks, estimated=estimated)


@dataclasses.dataclass(frozen=True)
class Predicted:
    """The model's curves on the grid f (Hz), complex, shape (len(f),), and its margins."""

    f: np.ndarray
    loop: np.ndarray
    sensitivity: np.ndarray
    complementary: np.ndarray
    reference: np.ndarray  # r -> pitch
    margins: Margins


def response(loop: Loop, f: np.ndarray) -> Predicted:
    """L, S = 1 / (1 + L), T = L / (1 + L), the reference's closed loop at `f` (Hz), and the margins
    found on a fine grid up to Nyquist."""
    w = 2.0 * math.pi * np.asarray(f, float)
    ell = np.asarray(ct.frequency_response(loop.open_loop(), w).complex).ravel()
    ref = np.asarray(ct.frequency_response(loop.reference_loop(), w).complex).ravel()
    nyquist = 0.5 / loop.dt
    fine = GRID[nyquist > GRID]
    found = margins(fine, np.asarray(ct.frequency_response(loop.open_loop(), 2 * math.pi * fine).complex).ravel())
    return Predicted(np.asarray(f, float), ell, 1.0 / (1.0 + ell), ell / (1.0 + ell), ref, found)
