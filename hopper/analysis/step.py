"""Step response of the attitude loop: a step of the pitch reference, measured and predicted.

Rise time from 10 % to 90 % of the final value (interpolated between ticks), overshoot beyond the
final value in percent of it, settling time until the response stays within SETTLE_BAND of the
final value. The final value is the response's own (its mean over the last tenth of the record):
a loop without an integral (an LQR holding the wheel's speed too) may settle short of the step.
"""

from __future__ import annotations

import dataclasses
import math

import control as ct
import numpy as np

from hopper.analysis.frequency import NotMeasured
from hopper.analysis.predict import Loop

SETTLE_BAND = 0.05  # of the final value (free legs drift by 2 to 3 % over seconds: their pendulum under gravity)
RISE_FROM, RISE_TO = 0.1, 0.9


@dataclasses.dataclass(frozen=True)
class StepMetrics:
    """A step response's figures: times in s from the step, overshoot in % of the final value."""

    rise_s: float
    overshoot_pct: float
    settling_s: float
    final: float  # rad, the response's final value
    step: float  # rad, the reference's step


def _crossing(t: np.ndarray, y: np.ndarray, level: float) -> float:
    above = np.flatnonzero(y >= level)
    if not len(above):
        return math.nan
    i = int(above[0])
    if i == 0:
        return float(t[0])
    return float(np.interp(level, y[i - 1 : i + 1], t[i - 1 : i + 1]))


def metrics(t: np.ndarray, y: np.ndarray, step: float) -> StepMetrics:
    """Figures of the response `y` (rad, starting at 0) sampled at `t` (s from the step), shape (n,)."""
    sign = 1.0 if step >= 0.0 else -1.0
    y = sign * np.asarray(y, float)
    final = float(np.mean(y[-max(len(y) // 10, 1) :]))
    if not final > 0.0:
        raise NotMeasured(f"the response to a {math.degrees(step):.3g} deg step never moved toward it")
    rise = _crossing(t, y, RISE_TO * final) - _crossing(t, y, RISE_FROM * final)
    overshoot = max(float(y.max()) / final - 1.0, 0.0) * 100.0
    outside = np.flatnonzero(np.abs(y - final) > SETTLE_BAND * final)
    if len(outside) and outside[-1] == len(y) - 1:
        raise NotMeasured(
            f"the response had not settled within {SETTLE_BAND:.0%} by the end of the record: lengthen it"
        )
    settling = float(t[outside[-1] + 1]) if len(outside) else float(t[0])
    return StepMetrics(rise, overshoot, settling, sign * final, step)


def predicted_step(loop: Loop, step: float, seconds: float) -> tuple[np.ndarray, np.ndarray]:
    """(t s, pitch rad) of the model's loop after a reference step of `step` rad at t = 0."""
    n = round(seconds / loop.dt)
    t = np.arange(n) * loop.dt
    result = ct.forced_response(loop.reference_loop(), T=t, U=np.full(n, step))
    return t, np.asarray(result.outputs, float).ravel()
