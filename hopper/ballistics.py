"""Where a flight ends: the centre of mass's parabola and the first foot to meet the terrain.

In flight only gravity acts on the whole robot, so its CoM follows a parabola whatever the wheel
and legs do. The feet are where the controller will hold them for the landing (see
`HopController.landing_feet`), carried along with the CoM; the landing is the first time either
foot's sphere reaches the terrain under it, and both feet's points then are where they come down
(the controller sets the legs' reach so that they touch down together).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hopper.robot import PACKAGED, Robot
from hopper.terrain import Window

STEP_S = 0.005  # s between predicted points
DROP_M = 3.0  # m: the prediction gives up this far below the start (a fall into nothing)


@dataclasses.dataclass(frozen=True)
class Arc:
    """A predicted flight from simulation time `t0` (s)."""

    t0: float
    times: np.ndarray  # (n,), s after t0
    com: np.ndarray  # (n, 2), world (x, z) of the CoM, m
    feet: list[tuple[float, float]]  # world (x, z) of each foot's contact point at the landing, m; [] if none
    landing_s: float | None  # s after t0

    def com_at(self, t: float) -> np.ndarray:
        """The predicted CoM (x, z) at simulation time `t` (clamped to the arc)."""
        k = min(max(round((t - self.t0) / STEP_S), 0), len(self.times) - 1)
        return self.com[k]


class Ground:
    """The terrain's height under each foot's line (y = +-`robot.foot_y`) in a window, vectorised in x,
    and the feet's radius (m) that meets it.

    The simulation keeps AHEAD_M of window ahead of the robot (hopper.terrain.window), more than
    any flight's arc spans; beyond the window's edges the edge heights are used."""

    def __init__(self, window: Window, robot: Robot = PACKAGED) -> None:
        heights, params = window.heights, window.params
        self.foot_radius = robot.foot_radius
        self.heights = heights  # the window's array this was built from (a moved window has a new one)
        nrow, ncol = heights.shape
        self.xs = window.x0 + params.cell * np.arange(ncol)
        rows = []
        for y in (robot.foot_y, -robot.foot_y):  # bilinear in y between the two grid rows around the foot's line
            fy = min(max((y + params.width / 2) / params.cell, 0.0), nrow - 1.000001)
            i, a = int(fy), fy - int(fy)
            rows.append(heights[i] * (1 - a) + heights[i + 1] * a)
        self.profiles = rows

    def height(self, foot: int, x: np.ndarray) -> np.ndarray:
        """Terrain height (m) under foot 0 (left) or 1 (right) at world x (m); the edge beyond the window."""
        return np.interp(x, self.xs, self.profiles[foot])


def predict(
    t0: float,
    com: tuple[float, float],
    com_vel: tuple[float, float],
    feet: list[tuple[float, float]],
    gravity: float,
    ground: Ground,
) -> Arc:
    """The flight from CoM `com` (x, z, m) moving at `com_vel` (m/s), with the feet (left, right) at
    world (x, z) now in the pose they will land in."""
    vx, vz = com_vel
    # Long enough to fall DROP_M below the start: sqrt of the positive root of the parabola.
    span = (vz + np.sqrt(vz * vz + 2.0 * gravity * DROP_M)) / gravity
    times = np.arange(0.0, span + STEP_S, STEP_S)
    x = com[0] + vx * times
    z = com[1] + vz * times - 0.5 * gravity * times**2
    first: int | None = None
    paths = []
    for side, (fx, fz) in enumerate(feet):
        foot_x, foot_z = x + (fx - com[0]), z + (fz - com[1])
        paths.append(foot_x)
        below = foot_z - ground.foot_radius <= ground.height(side, foot_x)
        below[0] = False  # a foot on the ground now is lifting off, not landing
        hits = np.flatnonzero(below)
        if hits.size and (first is None or hits[0] < first):
            first = int(hits[0])
    if first is None:
        return Arc(t0, times, np.stack([x, z], axis=1), [], None)
    points = [(float(p[first]), float(ground.height(side, p[first : first + 1])[0])) for side, p in enumerate(paths)]
    com_xz = np.stack([x[: first + 1], z[: first + 1]], axis=1)
    return Arc(t0, times[: first + 1], com_xz, points, float(times[first]))
