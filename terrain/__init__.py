"""Crater heightfields for the lunar hopper: generation, PNG export, MuJoCo hfield data."""

from hopper.terrain.craters import CraterParams, crater_profile, flat, generate
from hopper.terrain.export import read_png, to_hfield, write_png

__all__ = ["CraterParams", "crater_profile", "flat", "generate", "read_png", "to_hfield", "write_png"]
