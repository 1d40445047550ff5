"""Crater heightfields for the lunar hopper: generation, PNG export, MuJoCo hfield data."""

from terrain.craters import CraterParams, crater_profile, flat, generate
from terrain.export import read_png, to_hfield, write_png

__all__ = ["CraterParams", "crater_profile", "flat", "generate", "read_png", "to_hfield", "write_png"]
