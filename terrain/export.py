"""Heightfield export: grayscale PNG (as the paper does) and MuJoCo hfield normalisation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, PngImagePlugin

MIN_ELEVATION = 1e-3  # m; MuJoCo needs a positive hfield elevation even for a flat field


def to_hfield(heights: np.ndarray, vertical: tuple[float, float] | None = None) -> tuple[np.ndarray, float, float]:
    """Normalise heights (m, shape (nrow, ncol)) to MuJoCo's [0, 1] data, over `vertical` (low,
    high; m) if given (a field's fixed range, so data decode the same whatever the window) or
    over the heights' own range.

    Returns (data, elevation_z, offset_z): height = offset_z + data * elevation_z.
    """
    low, high = (float(heights.min()), float(heights.max())) if vertical is None else vertical
    elevation = max(high - low, MIN_ELEVATION)
    return (heights - low) / elevation, elevation, low


def write_png(heights: np.ndarray, path: str | Path, bits: int = 16) -> Path:
    """Write heights as a grayscale PNG, top row = +y (MuJoCo's row 0 is -y, so rows flip).

    16-bit keeps 1/65535 of the relief (an 8-bit image quantises to 1/255); the metres per grey
    level are stored in the PNG's text chunk so `read_png` restores heights in metres.
    """
    if bits not in (8, 16):
        raise ValueError(f"bits must be 8 or 16, got {bits}")
    data, elevation, offset = to_hfield(heights)
    top = (1 << bits) - 1
    pixels = np.round(np.flipud(data) * top).astype(np.uint16 if bits == 16 else np.uint8)
    info = PngImagePlugin.PngInfo()
    info.add_text("elevation_m", repr(elevation))
    info.add_text("offset_m", repr(offset))
    path = Path(path)
    Image.fromarray(pixels).save(path, pnginfo=info)
    return path


def read_png(path: str | Path) -> np.ndarray:
    """Heights in metres, shape (nrow, ncol), row 0 = -y, from a PNG written by `write_png`."""
    with Image.open(path) as image:
        elevation = float(image.text.get("elevation_m", 1.0))
        offset = float(image.text.get("offset_m", 0.0))
        pixels = np.asarray(image)
    top = 65535 if pixels.dtype == np.uint16 or pixels.max() > 255 else 255
    return offset + np.flipud(pixels.astype(np.float64) / top) * elevation
