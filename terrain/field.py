"""The crater field without end: the height of any grid point, from the parameters, the seed and its x.

World x is cut into tiles of `CraterParams.tile` metres; tile k (grid columns k*n .. k*n + n - 1,
n = tile / cell) draws its base noise and its craters from one generator seeded by (seed, k)
alone. A crater reaches one diameter from its centre and the noise kernel KERNEL_SIGMAS
correlation lengths, both at most a tile (CraterParams checks it), so tile k's heights are made
of the draws of tiles k-1, k and k+1, added in one fixed order: a grid point gets the same
height, to the bit, whichever window, order or path asks for it. Column j sits at world
x = j * cell, row i at y = -width/2 + i * cell (row 0 the -y edge), as in MuJoCo's hfield.
"""

from __future__ import annotations

import collections
import dataclasses
import math

import numpy as np
from hopper.terrain.craters import CraterParams, crater_profile, sample_diameters

KERNEL_SIGMAS = 4.0  # the noise's Gaussian kernel is cut where it falls to 3e-4 of its peak
CACHE_TILES = 32  # tiles a field keeps: a 30 m window spans 9 tiles of 4 m, and may move back
FLAT_RANGE = (0.0, 1e-3)  # m: a level field's hfield scale (MuJoCo needs a positive elevation)


@dataclasses.dataclass(frozen=True)
class TileDraws:
    """What one tile's generator drew."""

    rows: np.ndarray  # (nrow, n): its white noise through the kernel along y (drawn with pad rows beyond each edge)
    craters: np.ndarray  # (count, 5): centre x, centre y, radius, depth, rim height; m


def _zigzag(k: int) -> int:
    """Tile index to a non-negative integer (a SeedSequence takes no negative entropy): 0, -1, 1, -2, ..."""
    return 2 * k if k >= 0 else -2 * k - 1


def noise_kernel(params: CraterParams) -> np.ndarray:
    """The 1-D Gaussian kernel of the base noise, std roughness_scale, in grid cells, cut at KERNEL_SIGMAS."""
    sigma = params.roughness_scale / params.cell
    reach = math.ceil(KERNEL_SIGMAS * sigma)
    taps = np.arange(-reach, reach + 1, dtype=float)
    return np.exp(-0.5 * (taps / sigma) ** 2)


def draw_tile(params: CraterParams, seed: int, k: int) -> TileDraws:
    """Tile k's draws: white noise first, then its craters, all from the generator of (seed, k).

    Crater centres are uniform over the tile in x and, as partial craters cut the field's edges,
    over the width plus a radius each side in y; diameters follow N(>D) ~ D^-2. Craters whose
    footprint reaches the start pad (|x| < clear_radius) are dropped.
    """
    rng = np.random.default_rng(np.random.SeedSequence((seed, _zigzag(k))))
    nrow, n = params.shape[0], round(params.tile / params.cell)
    kernel = noise_kernel(params)
    noise = rng.standard_normal((nrow + len(kernel) - 1, n))
    rows = np.zeros((nrow, n))
    for t, h in enumerate(kernel):  # along y here: a tile's rows beyond the field's edges are its own
        rows += h * noise[t : t + nrow]
    count = int(rng.poisson(params.density * params.tile * params.width))
    radius = sample_diameters(rng, count, *params.diameter_range) / 2
    cx = (k + rng.random(count)) * params.tile
    cy = -params.width / 2 - radius + rng.random(count) * (params.width + 2 * radius)
    depth = 2 * radius * rng.uniform(*params.depth_ratio_range, count)
    rim = 2 * radius * rng.uniform(*params.rim_ratio_range, count)
    keep = np.abs(cx) >= params.clear_radius + 2 * radius
    return TileDraws(rows, np.stack([cx, cy, radius, depth, rim], axis=1)[keep])


def tile_heights(params: CraterParams, k: int, draws: tuple[TileDraws, TileDraws, TileDraws]) -> np.ndarray:
    """Tile k's heights (m), shape (nrow, n), from the draws of tiles k-1, k and k+1 (in that order).

    Base noise (unit RMS white noise through the separable Gaussian kernel, scaled to `roughness`
    RMS), plus every crater that reaches the tile, times the start pad's ramp, clipped to
    `vertical_range`. Taps and craters are summed in a fixed order, elementwise (no BLAS, whose
    blocking could depend on the machine), so the result depends on nothing but the arguments.
    """
    nrow, n = params.shape[0], round(params.tile / params.cell)
    kernel = noise_kernel(params)
    gain = params.roughness / float(np.sum(kernel**2))  # sqrt(sum h^2) per axis: unit variance out
    wide = np.concatenate([d.rows for d in draws], axis=1)  # (nrow, 3n): tiles k-1, k, k+1, filtered along y
    reach = len(kernel) // 2
    heights = np.zeros((nrow, n))
    for t, h in enumerate(kernel):
        heights += h * wide[:, n - reach + t : 2 * n - reach + t]
    heights *= gain

    first = k * n
    xs = (first + np.arange(n)) * params.cell
    ys = -params.width / 2 + np.arange(nrow) * params.cell
    x_lo, x_hi, cell = xs[0], xs[-1], params.cell
    for d in draws:
        for cx, cy, radius, depth, rim in d.craters:
            if cx + 2 * radius < x_lo or cx - 2 * radius > x_hi:
                continue
            # Only the footprint (rho < 2) is evaluated; the profile is exactly 0 beyond it.
            ix = slice(max(0, int((cx - 2 * radius - x_lo) / cell)), int((cx + 2 * radius - x_lo) / cell) + 2)
            iy = slice(max(0, int((cy - 2 * radius - ys[0]) / cell)), int((cy + 2 * radius - ys[0]) / cell) + 2)
            rho = np.hypot(xs[None, ix] - cx, ys[iy, None] - cy) / radius
            heights[iy, ix] += crater_profile(rho, depth, rim)

    # Blend to zero height at the start so the robot starts standing on level ground.
    ramp = np.clip((np.abs(xs) - params.clear_radius) / params.clear_radius, 0.0, 1.0)
    return np.clip(heights * ramp[None, :], *params.vertical_range)


class CraterField:
    """The crater field of `params` and `seed`; tiles are computed once and the last CACHE_TILES kept."""

    def __init__(self, params: CraterParams, seed: int) -> None:
        if not isinstance(seed, int) or seed < 0:
            raise ValueError(f"invalid crater parameter: seed must be a non-negative integer, got {seed!r}")
        self.params, self.seed = params, seed
        self.vertical_range = params.vertical_range
        self._draws: collections.OrderedDict[int, TileDraws] = collections.OrderedDict()
        self._tiles: collections.OrderedDict[int, np.ndarray] = collections.OrderedDict()

    @property
    def tile_columns(self) -> int:
        return round(self.params.tile / self.params.cell)

    def tile(self, k: int) -> np.ndarray:
        """Tile k's heights (m), shape (nrow, tile_columns); read-only."""
        heights = self._tiles.get(k)
        if heights is None:
            heights = tile_heights(self.params, k, (self._draw(k - 1), self._draw(k), self._draw(k + 1)))
            heights.flags.writeable = False
            self._tiles[k] = heights
            _trim(self._tiles)
        else:
            self._tiles.move_to_end(k)
        return heights

    def _draw(self, k: int) -> TileDraws:
        draws = self._draws.get(k)
        if draws is None:
            draws = self._draws[k] = draw_tile(self.params, self.seed, k)
            _trim(self._draws)
        else:
            self._draws.move_to_end(k)
        return draws

    def columns(self, first: int, count: int) -> np.ndarray:
        """Heights (m) of grid columns first .. first + count - 1, shape (nrow, count): a new array."""
        n = self.tile_columns
        k0, k1 = first // n, (first + count - 1) // n
        strip = np.concatenate([self.tile(k) for k in range(k0, k1 + 1)], axis=1)
        return strip[:, first - k0 * n : first - k0 * n + count].copy()


class FlatField:
    """A level field on the same grid: every height 0."""

    def __init__(self, params: CraterParams) -> None:
        self.params = params
        self.vertical_range = FLAT_RANGE

    def columns(self, first: int, count: int) -> np.ndarray:
        return np.zeros((self.params.shape[0], count))


def _trim(cache: collections.OrderedDict) -> None:
    while len(cache) > CACHE_TILES:
        cache.popitem(last=False)
