"""Lunar craters: the field's parameters, one crater's profile and the size-frequency draw."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

# Fresh lunar craters (PHYSICS.md): depth/diameter 0.2 to 0.25, rim height/diameter 0.02 to 0.06,
# cumulative count of craters wider than D falling as D^-2. Most small craters on the maria are
# degraded, hence the default depth ratio range reaches down to 0.08.


@dataclasses.dataclass(frozen=True, kw_only=True)
class CraterParams:
    """Parameters of an endless crater field (hopper.terrain.field) and of the window of it the
    simulation holds (hopper.terrain.window).

    Lengths in metres. The field spans every x and y in [-width/2, width/2]; the window is `length`
    long and starts at x in [x0, x0 + length]; both sit on the grid x = j cell (j any integer).
    """

    length: float = 30.0  # m; the window: at 0.8 m a hop, the start window holds more than 30 hops
    width: float = 2.0  # m; the robot is planar, the field only needs to hold both feet
    x0: float = -2.0  # m; world x of the start window's -x edge
    cell: float = 0.05  # m; grid spacing, no smaller than the 4 cm foot radius
    tile: float = 4.0  # m; the field's draws come per tile; a crater and the noise kernel reach < 1 tile
    density: float = 1.0  # craters per m^2
    diameter_range: tuple[float, float] = (0.3, 2.0)  # m
    depth_ratio_range: tuple[float, float] = (0.08, 0.2)  # depth / diameter
    rim_ratio_range: tuple[float, float] = (0.02, 0.04)  # rim height / diameter
    roughness: float = 0.008  # m; RMS of the smoothed base noise
    roughness_scale: float = 0.3  # m; correlation length of the base noise
    clear_radius: float = 1.0  # m; no crater within this distance of the start (x = 0)

    def __post_init__(self) -> None:
        def check(ok: bool, what: str) -> None:
            if not ok:
                raise ValueError(f"invalid crater parameter: {what}")

        for name in ("length", "width", "cell", "roughness_scale"):
            value = getattr(self, name)
            check(math.isfinite(value) and value > 0, f"{name} must be finite and > 0, got {value}")
        for name in ("density", "roughness", "clear_radius"):
            value = getattr(self, name)
            check(math.isfinite(value) and value >= 0, f"{name} must be finite and >= 0, got {value}")
        check(math.isfinite(self.x0), f"x0 must be finite, got {self.x0}")
        check(self.cell <= min(self.length, self.width) / 4, f"cell {self.cell} m is too coarse")
        for name in ("x0", "tile", "length"):  # whole cells: every window and tile starts on the one grid
            cells = getattr(self, name) / self.cell
            check(abs(cells - round(cells)) < 1e-9, f"{name} {getattr(self, name)} m is not a whole number of cells")
        for name in ("diameter_range", "depth_ratio_range", "rim_ratio_range"):
            lo, hi = getattr(self, name)
            check(
                math.isfinite(lo) and math.isfinite(hi) and 0 <= lo <= hi,
                f"{name} must satisfy 0 <= low <= high, got ({lo}, {hi})",
            )
        check(self.diameter_range[0] > 0, "diameter_range low must be > 0")
        check(self.depth_ratio_range[1] <= 0.5, "depth/diameter above 0.5 is not a crater")
        # A crater reaches one diameter from its centre, the noise kernel 4 correlation lengths
        # (hopper.terrain.field): within a tile, so a tile's heights need only its neighbours.
        reach = max(self.diameter_range[1], 4 * self.roughness_scale)
        check(self.tile >= reach, f"tile {self.tile} m is shorter than a crater's or the noise's reach, {reach} m")

    @property
    def shape(self) -> tuple[int, int]:
        """The window's grid shape (nrow along y, ncol along x)."""
        return (round(self.width / self.cell) + 1, round(self.length / self.cell) + 1)

    @property
    def vertical_range(self) -> tuple[float, float]:
        """Lowest and highest height (m) of the field: two of the deepest bowls (or highest rims)
        on top of each other and six RMS of noise. Fixed, so the hfield's scale never changes as
        the window moves (its float32 data then decode to the same heights); the field clips to it."""
        widest = self.diameter_range[1]
        noise = 6.0 * self.roughness
        return (-2.0 * self.depth_ratio_range[1] * widest - noise, 2.0 * self.rim_ratio_range[1] * widest + noise)


def crater_profile(rho: np.ndarray, depth: float, rim: float) -> np.ndarray:
    """Radially symmetric crater height at normalised radius rho = r / R.

    A parabolic bowl from -depth at the centre up to the rim crest (+rim) at rho = 1, then an
    ejecta blanket falling as rho^-3 (the classic power-law fall-off of ejecta thickness) that is
    faded to zero by rho = 2 so craters stay local.
    """
    inside = -depth + (depth + rim) * rho**2
    fade = np.clip(2.0 - rho, 0.0, 1.0)
    outside = rim * np.power(np.maximum(rho, 1.0), -3.0) * fade
    return np.where(rho <= 1.0, inside, outside)


def sample_diameters(rng: np.random.Generator, count: int, lo: float, hi: float) -> np.ndarray:
    """Diameters whose cumulative count above D falls as D^-2 (pdf ~ D^-3), truncated to [lo, hi]."""
    if lo == hi:
        return np.full(count, lo)
    u = rng.random(count)
    a, b = lo**-2, hi**-2
    return (a - u * (a - b)) ** -0.5
