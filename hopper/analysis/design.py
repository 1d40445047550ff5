"""Gain design for the flight PID: pole placement on the flight plant, and Bryson's LQR.

Both start from the reduced model `J theta_ddot = -tau_w` (hopper.analysis.loop). Pole placement then
corrects the gains on the plant given (the linearized flight, where the leg servos make the torso
lighter than J at the loop's frequencies) until its dominant pair is the one asked for.
"""

from __future__ import annotations

import math

import control as ct
import numpy as np
from scipy.optimize import least_squares

from hopper.analysis.loop import Plant, close, dominant_pair, pitch_modes
from hopper.config import GAIN_RANGES, Gains

# The integral's real pole at this fraction of wn: slow (it only trims model error in flight, where
# no steady torque acts) and far enough below the pair not to move it.
INTEGRAL_POLE_RATIO = 0.02
PLACEMENT_TOLERANCE = 0.01  # relative error in wn and zeta accepted from the correction


def _reduced(inertia: float, integral: bool) -> tuple[np.ndarray, np.ndarray]:
    """J theta_ddot = -tau_w on x = [int theta, theta, theta_dot] (or without the integral)."""
    a = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    b = np.array([[0.0], [0.0], [-1.0 / inertia]])
    return (a, b) if integral else (a[1:, 1:], b[1:])


def _gains(kp: float, ki: float, kd: float) -> Gains:
    """The designed gains, refused with the reason when outside the ranges the loop accepts."""
    for name, value in (("kp", kp), ("ki", ki), ("kd", kd)):
        span = GAIN_RANGES[name]
        if not (math.isfinite(value) and span.low <= value <= span.high):
            raise ValueError(
                f"the design needs {name} = {value:.4g} {span.unit}, outside [{span.low:g}, {span.high:g}]"
            )
    return Gains(kp=kp, ki=ki, kd=kd)


def reduced_placement(inertia: float, wn: float, zeta: float, integral: bool = True) -> tuple[float, float, float]:
    """(kp, ki, kd) placing the reduced model's pair at wn (rad/s), zeta and the integral at 0.02 wn.

    Ackermann's formula (control.acker), which also places the repeated poles of zeta = 1.
    """
    root = complex(zeta * zeta - 1.0) ** 0.5
    poles = [wn * (-zeta + root), wn * (-zeta - root)] + ([-INTEGRAL_POLE_RATIO * wn] if integral else [])
    a, b = _reduced(inertia, integral)
    k = -np.real(np.asarray(ct.acker(a, b, poles))).ravel()  # acker gives u = -k x; the law is tau = k x
    return (float(k[1]), float(k[0]), float(k[2])) if integral else (float(k[0]), 0.0, float(k[1]))


def place_poles(plant: Plant, wn: float, zeta: float, integral: bool = True, delay: int = 0) -> Gains:
    """Gains whose loop on `plant` has its dominant pair at wn (rad/s) and zeta.

    Starts from the reduced model's placement and corrects kp and kd by least squares on the
    plant's own dominant pair; ki keeps the reduced placement's slow integral pole.
    """
    if not (math.isfinite(wn) and wn > 0.0):
        raise ValueError(f"natural frequency must be a positive number of rad/s, got {wn!r}")
    if not (math.isfinite(zeta) and 0.05 <= zeta <= 2.0):
        raise ValueError(f"damping ratio must be in [0.05, 2], got {zeta!r}")
    inertia = plant.inertia.effective if plant.inertia else 1.0 / plant.kick[plant.rate]
    kp0, ki, kd0 = reduced_placement(inertia, wn, zeta, integral)
    _gains(kp=min(kp0, GAIN_RANGES["kp"].high), ki=ki, kd=min(kd0, GAIN_RANGES["kd"].high))  # ki is final
    low = np.log([GAIN_RANGES["kp"].high * 1e-4, GAIN_RANGES["kd"].high * 1e-4])
    high = np.log([GAIN_RANGES["kp"].high, GAIN_RANGES["kd"].high])

    def pair_error(logs: np.ndarray) -> np.ndarray:
        loop = close(plant, Gains(kp=float(np.exp(logs[0])), ki=ki, kd=float(np.exp(logs[1]))), delay)
        x0 = np.zeros(len(loop.a))
        x0[: len(plant.kick)] = plant.kick
        got_wn, got_zeta = dominant_pair(pitch_modes(loop.closed, x0, loop.pitch, loop.dt))
        if not (math.isfinite(got_wn) and math.isfinite(got_zeta)):
            return np.array([10.0, 10.0])
        return np.array([got_wn / wn - 1.0, got_zeta / zeta - 1.0])

    start = np.clip(np.log([max(kp0, 1e-3), max(kd0, 1e-3)]), low, high)
    fit = least_squares(pair_error, start, bounds=(low, high), diff_step=1e-4, max_nfev=60)
    if np.max(np.abs(fit.fun)) > PLACEMENT_TOLERANCE:
        raise ValueError(f"no gains in range give wn = {wn:g} rad/s, zeta = {zeta:g} on this plant")
    kp, kd = np.exp(fit.x)
    return _gains(kp=float(kp), ki=ki, kd=float(kd))


def lqr_bryson(inertia: float, max_pitch_deg: float, max_torque: float, ki: float = 0.0) -> Gains:
    """Kp and Kd of the 2-state LQR on the reduced model [theta, theta_dot], Bryson's weights.

    Q = diag(1 / max_pitch^2, 0), R = 1 / max_torque^2: the torque the loop may spend per radian
    of pitch. Ki is not part of the design and is passed through (it only trims model error).
    """
    if not (math.isfinite(max_pitch_deg) and 0.0 < max_pitch_deg <= 90.0):
        raise ValueError(f"max pitch must be in (0, 90] deg, got {max_pitch_deg!r}")
    if not (math.isfinite(max_torque) and max_torque > 0.0):
        raise ValueError(f"max torque must be a positive number of N m, got {max_torque!r}")
    a, b = _reduced(inertia, integral=False)
    q = np.diag([1.0 / math.radians(max_pitch_deg) ** 2, 0.0])
    r = np.array([[1.0 / max_torque**2]])
    k, _, _ = ct.lqr(a, b, q, r)
    return _gains(kp=float(-k[0, 0]), ki=ki, kd=float(-k[0, 1]))
