"""Shared fixtures: small, seeded, headless."""

from __future__ import annotations

import pytest

from hopper.config import SimConfig
from hopper.sim import Simulation


@pytest.fixture
def flat_sim() -> Simulation:
    return Simulation(SimConfig(terrain="flat"))
