"""Procedural lunar crater heightfields: a pure, seeded function from parameters to heights."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

# Fresh lunar craters (PHYSICS.md): depth/diameter 0.2 to 0.25, rim height/diameter 0.02 to 0.06,
# cumulative count of craters wider than D falling as D^-2. Most small craters on the maria are
# degraded, hence the default depth ratio range reaches down to 0.08.


@dataclasses.dataclass(frozen=True, kw_only=True)
class CraterParams:
    """Parameters of a crater field on a rectangular strip.

    Lengths in metres; the strip spans x in [x0, x0 + length], y in [-width/2, width/2].
    """

    length: float = 30.0  # m; at 0.8 m a hop, room for more than 30 hops
    width: float = 2.0  # m; the robot is planar, the strip only needs to hold both feet
    x0: float = -2.0  # m; world x of the strip's -x edge
    cell: float = 0.05  # m; grid spacing, no smaller than the 4 cm foot radius
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
        for name in ("diameter_range", "depth_ratio_range", "rim_ratio_range"):
            lo, hi = getattr(self, name)
            check(
                math.isfinite(lo) and math.isfinite(hi) and 0 <= lo <= hi,
                f"{name} must satisfy 0 <= low <= high, got ({lo}, {hi})",
            )
        check(self.diameter_range[0] > 0, "diameter_range low must be > 0")
        check(self.depth_ratio_range[1] <= 0.5, "depth/diameter above 0.5 is not a crater")

    @property
    def shape(self) -> tuple[int, int]:
        """Grid shape (nrow along y, ncol along x)."""
        return (round(self.width / self.cell) + 1, round(self.length / self.cell) + 1)


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


def smooth_noise(rng: np.random.Generator, shape: tuple[int, int], cells: float) -> np.ndarray:
    """Unit-RMS Gaussian noise low-passed with a Gaussian kernel of `cells` grid cells, via FFT."""
    white = rng.standard_normal(shape)
    ky = np.fft.fftfreq(shape[0])[:, None]
    kx = np.fft.rfftfreq(shape[1])[None, :]
    kernel = np.exp(-2.0 * (math.pi * cells) ** 2 * (kx**2 + ky**2))
    field = np.fft.irfft2(np.fft.rfft2(white) * kernel, s=shape)
    std = field.std()
    return field / std if std > 0 else field


def generate(params: CraterParams, rng: np.random.Generator) -> np.ndarray:
    """Crater field heights in metres, shape (nrow, ncol); row 0 is the -y edge, column 0 the -x edge."""
    nrow, ncol = params.shape
    xs = params.x0 + np.arange(ncol) * params.cell
    ys = -params.width / 2 + np.arange(nrow) * params.cell
    heights = params.roughness * smooth_noise(rng, (nrow, ncol), params.roughness_scale / params.cell)

    count = rng.poisson(params.density * params.length * params.width)
    diameters = sample_diameters(rng, count, *params.diameter_range)
    for diameter in diameters:
        radius = diameter / 2
        # Centres may sit just off the strip so that partial craters cut its edges.
        cx = rng.uniform(xs[0] - radius, xs[-1] + radius)
        cy = rng.uniform(ys[0] - radius, ys[-1] + radius)
        if abs(cx) < params.clear_radius + 2 * radius:  # keep the start pad level
            continue
        depth = diameter * rng.uniform(*params.depth_ratio_range)
        rim = diameter * rng.uniform(*params.rim_ratio_range)
        # Only the crater's footprint (rho < 2) is evaluated.
        ix = slice(
            max(0, int((cx - 2 * radius - xs[0]) / params.cell)), int((cx + 2 * radius - xs[0]) / params.cell) + 2
        )
        iy = slice(
            max(0, int((cy - 2 * radius - ys[0]) / params.cell)), int((cy + 2 * radius - ys[0]) / params.cell) + 2
        )
        rho = np.hypot(xs[None, ix] - cx, ys[iy, None] - cy) / radius
        heights[iy, ix] += crater_profile(rho, depth, rim)

    # Blend the start pad to zero height so the robot starts standing on level ground.
    pad = np.clip((np.abs(xs) - params.clear_radius) / params.clear_radius, 0.0, 1.0)
    return heights * pad[None, :]


def flat(params: CraterParams) -> np.ndarray:
    """A level field of the same grid, shape (nrow, ncol)."""
    return np.zeros(params.shape)
