"""The window of an endless field that the simulation holds under the robot, and when it moves.

The window is `CraterParams.length` of the field on its grid, `first` its first column. It moves
by whole columns, so the ground it shares with the window before is the same grid points, whose
heights the field gives bit for bit (hopper.terrain.field): contacts there do not jump.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
from hopper.terrain.craters import CraterParams

AHEAD_M = 10.0  # m of window kept ahead of the robot; the landing plan and the flight's arc look < 3 m ahead
BEHIND_M = 1.0  # m kept behind it (the start window keeps 2 m: CraterParams.x0)
URGENT_M = 0.5  # of those margins, the share left when a move cannot wait for a flight (a drag, a slide)
LEFT_M = 5.0  # m of window left on the side the robot came from after a move


class Field(Protocol):
    """Heights of grid columns (hopper.terrain.field's CraterField and FlatField)."""

    params: CraterParams
    vertical_range: tuple[float, float]  # m, the hfield's fixed scale

    def columns(self, first: int, count: int) -> np.ndarray: ...


class Window:
    """`params.shape[1]` columns of `field` from column `first` on; `heights` is replaced, never
    written, when it moves (readers may keep a reference and compare it with `is`)."""

    def __init__(self, field: Field, params: CraterParams) -> None:
        self.field, self.params = field, params
        self.ncol = params.shape[1]
        self.start = round(params.x0 / params.cell)  # the start window's first column
        self.first = self.start
        self.heights = field.columns(self.first, self.ncol)
        self.moves = 0  # window moves since construction (not counting returns to the same place)

    @property
    def x0(self) -> float:
        """World x (m) of the window's -x edge."""
        return self.first * self.params.cell

    @property
    def x1(self) -> float:
        """World x (m) of the window's +x edge."""
        return (self.first + self.ncol - 1) * self.params.cell

    def tiles(self) -> range:
        """The field's tiles (hopper.terrain.field) the window overlaps, for meshes drawn tile by tile."""
        n = round(self.params.tile / self.params.cell)
        return range(self.first // n, (self.first + self.ncol - 1) // n + 1)

    def place(self, first: int) -> bool:
        """Put the window's first column at `first`; True if it moved."""
        first = int(first)
        if first == self.first:
            return False
        self.first, self.heights = first, self.field.columns(first, self.ncol)
        self.moves += 1
        return True

    def due(self, x: float, urgent: bool = False) -> int:
        """+1 if the robot at world x (m) has less than AHEAD_M of window ahead, -1 if less than
        BEHIND_M behind, 0 otherwise; `urgent` asks with URGENT_M of those margins."""
        share = URGENT_M if urgent else 1.0
        if x > self.x1 - share * AHEAD_M:
            return 1
        if x < self.x0 + share * BEHIND_M:
            return -1
        return 0

    def follow(self, x: float, urgent: bool = False) -> bool:
        """Move the window if it is due for the robot at world x (m), leaving LEFT_M behind it
        (ahead of it when it travels backwards); True if it moved."""
        side = self.due(x, urgent)
        if side == 0:
            return False
        cell, span = self.params.cell, (self.ncol - 1) * self.params.cell
        left = x - LEFT_M if side > 0 else x - (span - LEFT_M)
        return self.place(math.floor(left / cell))

    def height(self, x: float, y: float) -> float:
        """Terrain height (m) at world (x, y), bilinear between grid points; beyond the window's
        edges from the field itself, beyond its width the edge row's."""
        cell = self.params.cell
        fx = (x - self.x0) / cell
        if 0.0 <= fx <= self.ncol - 1.000001:
            heights, j = self.heights, int(fx)
        else:  # two columns of the field around x
            j0 = math.floor(x / cell)
            heights, j, fx = self.field.columns(j0, 2), 0, x / cell - j0
        nrow = heights.shape[0]
        fy = min(max((y + self.params.width / 2) / cell, 0.0), nrow - 1.000001)
        i = int(fy)
        a, b = fy - i, fx - j
        top = heights[i, j] * (1 - b) + heights[i, j + 1] * b
        bottom = heights[i + 1, j] * (1 - b) + heights[i + 1, j + 1] * b
        return float(top * (1 - a) + bottom * a)
