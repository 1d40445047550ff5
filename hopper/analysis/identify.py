"""The flight loop identified from the simulation: a small kick in flight, and the modes fitted to it.

Checks hopper.analysis.loop's analysis against the full simulation. Two identical runs are stepped to the
same moment of the first flight (the legs in their landing pose); one is kicked; the difference of
their pitch is the loop's response to the kick alone, free of the flight's own motion.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hopper.analysis.linearize import flight_plant, settled_flight
from hopper.analysis.loop import Mode, Plant, modes
from hopper.commands import Disturb
from hopper.config import SimConfig

KICK = 0.02  # N m s: about 10 deg/s on the torso, a linear response far below the torque limit
WINDOW_S = 0.3  # s of response fitted, inside what is left of a lunar flight
ORDER = 6  # modes fitted: the pair, the integral, the hip servos' and the fast ones
FIT_DT = 0.002  # s between the samples the fit uses (better conditioned than every 1 ms tick)


@dataclasses.dataclass(frozen=True)
class KickResponse:
    time: np.ndarray  # s after the kick
    pitch: np.ndarray  # rad, kicked minus unkicked
    plant: Plant  # the flight plant linearized at the kick


def kick_in_flight(config: SimConfig, kick: float = KICK, window: float = WINDOW_S) -> KickResponse:
    """The pitch response to a `kick` (N m s) on the torso early in the first flight's descent."""
    base, kicked = settled_flight(config), settled_flight(config)
    plant = flight_plant(kicked)
    kicked.submit(Disturb("pitch_kick", kick))
    ticks = round(window / config.timestep)
    pitch = np.empty((2, ticks))
    for i in range(ticks):
        for j, sim in enumerate((base, kicked)):
            sim.step()
            pitch[j, i] = sim.state().pitch
    return KickResponse(time=(np.arange(ticks) + 1) * config.timestep, pitch=pitch[1] - pitch[0], plant=plant)


def fit_modes(response: KickResponse, order: int = ORDER, dt: float = FIT_DT) -> list[Mode]:
    """The modes of the linear free response that best fits `response`, with their energy shares.

    Prony's method: a free response of order n obeys y[k] = a1 y[k-1] + ... + an y[k-n]; least
    squares gives the a's, the recursion's roots are the modes, and least squares again their
    amplitudes.
    """
    tick = response.time[1] - response.time[0]
    step = max(1, round(dt / tick))
    y = response.pitch[::step]
    rows = np.column_stack([y[order - i - 1 : len(y) - i - 1] for i in range(order)])
    coeffs, *_ = np.linalg.lstsq(rows, y[order:], rcond=None)
    z = np.roots(np.concatenate([[1.0], -coeffs])).astype(complex)
    powers = z[np.newaxis, :] ** np.arange(len(y))[:, np.newaxis]
    residues, *_ = np.linalg.lstsq(powers, y.astype(complex), rcond=None)
    return modes(z, residues, step * tick)
