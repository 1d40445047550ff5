"""The attitude plant a model-based controller designs on: pitch, pitch rate and wheel speed.

From hopper.analysis.linearize's flight plant (the whole MuJoCo model linearized in flight with the leg
servos closed), the rows and columns of the three states an API controller observes. The hip
servos' springs stay in it (the pitch row's restoring term); the legs' own states are dropped.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from hopper.analysis.linearize import flight_plant, settled_flight
from hopper.analysis.loop import Plant
from hopper.config import SimConfig


@dataclasses.dataclass(frozen=True)
class AttitudeModel:
    """x[k+1] = a x[k] + b tau[k], x = (pitch rad, rate rad/s, wheel speed rad/s), tau the wheel torque (N m)."""

    a: np.ndarray  # (3, 3)
    b: np.ndarray  # (3,)
    dt: float  # s
    full: Plant  # the whole flight plant it was cut from
    states: tuple[int, int, int]  # indices of pitch, rate and wheel speed in the full plant's state


def attitude_model(config: SimConfig) -> AttitudeModel:
    """The attitude plant of config's model at its gravity, gait and timestep (cached: a linearization
    takes ~0.3 s). The full plant's `robot` is that model's."""
    key = SimConfig(
        gravity=config.gravity, gait=config.gait, timestep=config.timestep, terrain="flat", model=config.model
    )
    return _model(key)


@functools.lru_cache(maxsize=16)
def _model(config: SimConfig) -> AttitudeModel:
    sim = settled_flight(config)
    plant = flight_plant(sim)
    nv = sim.model.nv
    states = (sim.layout.v_pitch, nv + sim.layout.v_pitch, nv + sim.layout.v_wheel)
    idx = np.array(states)
    return AttitudeModel(plant.a[np.ix_(idx, idx)], plant.b[idx, 0], plant.dt, plant, states)


def closed_loop_radius(model: AttitudeModel, gain: np.ndarray) -> float:
    """Spectral radius of the attitude model under tau = gain @ (pitch, rate, wheel speed): < 1 is stable.

    Not of the full plant: its leg modes (one slightly unstable in flight, the legs' servos hold
    them) and the free positions stay what they are whatever the wheel does, PID included.
    """
    return float(np.abs(np.linalg.eigvals(model.a + np.outer(model.b, gain))).max())
