"""The pits benchmark's ground (benchmarks.pits): level, a wall down, a floor, a wall up, in the model."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from benchmarks.pits import FLOOR, LEVEL, START, PitField, run, simulation
from hopper.config import CraterParams

pytestmark = pytest.mark.unit

EDGE = START + LEVEL  # m, the first pit's edge


def test_a_pit_has_its_walls_at_the_angle_and_its_floor_at_the_depth():
    field = PitField(CraterParams(), 30.0, 0.2)
    rise = 0.1 * math.tan(math.radians(30.0))  # m, 0.1 m along a wall
    x = np.array([0.0, EDGE - 0.01, EDGE + 0.1, EDGE + field.wall + FLOOR / 2, EDGE + field.wall + FLOOR + 0.1])
    h = field.height(x)
    assert h == pytest.approx([0.0, 0.0, -rise, -0.2, -0.2 + rise])
    assert field.height(x[1:] + field.period) == pytest.approx(h[1:])  # the next pit is the same
    shifted = PitField(CraterParams(), 30.0, 0.2, shift=0.25)  # the pits start a quarter period later
    assert shifted.height(x + field.period / 4) == pytest.approx(h)
    assert field.where(EDGE + 0.1) == (0, "wall down")
    assert field.where(EDGE + field.wall + 0.1) == (0, "floor")
    assert field.where(EDGE + field.period + field.wall + FLOOR + 0.1) == (1, "wall up")
    assert field.where(START + field.period + 0.5) == (1, "level")


def test_a_pit_it_cannot_be_is_refused():
    with pytest.raises(ValueError, match="0 < angle < 80"):
        PitField(CraterParams(), 90.0, 0.2)
    with pytest.raises(ValueError, match="0 < depth"):
        PitField(CraterParams(), 30.0, 0.0)


def test_the_model_has_the_pits_ground_under_the_robot():
    sim, field = simulation("moon", 30.0, 0.2)
    hit, down = np.zeros(1, dtype=np.int32), np.array([0.0, 0.0, -1.0])
    for x in (EDGE - 0.5, EDGE + field.wall + FLOOR / 2, EDGE + field.wall + FLOOR + 0.1):
        # MuJoCo's own ray, from 1 m up, straight down (the robot stands metres behind).
        distance = mujoco.mj_ray(sim.model, sim.data, np.array([x, 0.0, 1.0]), down, None, 1, -1, hit)
        assert sim.model.geom(hit[0]).name == "terrain"
        assert 1.0 - distance == pytest.approx(float(field.height(np.array([x]))[0]), abs=0.01)


def test_the_robot_hops_on_the_pits_ground():
    result = run(("moon", 30.0, 0.2, 0.0, 2, None))
    assert result["hops"] == 2 and not result["fell"]
    assert result["crossed"] == 0 and result["part"] == "level"  # two hops stop short of the first pit
