"""Endless crater heightfields for the lunar hopper: the field, the window of it, PNG export, hfield data."""

from hopper.terrain.craters import CraterParams, crater_profile
from hopper.terrain.export import read_png, to_hfield, write_png
from hopper.terrain.field import CraterField, FlatField
from hopper.terrain.window import Field, Window

__all__ = [
    "CraterField",
    "CraterParams",
    "Field",
    "FlatField",
    "Window",
    "crater_profile",
    "read_png",
    "to_hfield",
    "write_png",
]
