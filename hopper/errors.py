"""HopperError: the base of the product's own errors (each also keeps its standard base)."""

from __future__ import annotations


class HopperError(Exception):
    """Anything this product refuses or cannot do, with a one-line message that says why.

    Each subclass also derives from the standard exception it refines (ValueError for bad input,
    RuntimeError or OSError for what failed), so `except ValueError` keeps catching bad input and
    `except HopperError` catches every error of ours and none of a library's.
    """


class ModelError(HopperError, ValueError):
    """An MJCF model the product cannot fly: not found, not MJCF, a name it needs missing, or a
    robot its controller does not describe (hopper.robot says which assumptions)."""
