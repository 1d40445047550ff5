"""Landing on known terrain: heights under the feet, and leg reaches that make both feet land together."""

from __future__ import annotations

import numpy as np
import pytest
from hopper.terrain import CraterParams

from hopper.config import SimConfig
from hopper.control.landing import plan_reach
from hopper.model import terrain_window


def test_ground_height_is_the_grid_at_its_points_and_bilinear_between() -> None:
    params = CraterParams()
    window = terrain_window(SimConfig(seed=3))
    heights = window.heights
    i, j = 20, 130  # a row near y = 0, a column ~4.5 m in
    x, y = params.x0 + j * params.cell, -params.width / 2 + i * params.cell
    assert window.height(x, y) == pytest.approx(heights[i, j])
    mid = window.height(x + params.cell / 2, y)
    assert mid == pytest.approx((heights[i, j] + heights[i, j + 1]) / 2)
    # Beyond the window's edges, the field itself: the terrain has no end.
    beyond = window.field.columns(round((params.x0 - 5.0) / params.cell), 1)[20, 0]
    assert window.height(params.x0 - 5.0, 0.0) == pytest.approx(beyond)
    assert window.height(params.x0 - 5.0, 0.0) != pytest.approx(heights[20, 0])


def flat_with_a_hole(depth: float, under: int):
    """Ground at 0, except `depth` lower under one foot (0 left, 1 right)."""
    return lambda x, foot: -depth if foot == under else 0.0


def test_a_foot_over_lower_ground_reaches_down_by_the_difference() -> None:
    hip, velocity = (0.0, 1.2), (0.4, 0.0)  # at the apex, 1.2 m up
    for under in (0, 1):
        lengths = plan_reach(hip, velocity, 1.625, (0.3, -0.06), 0.86, 0.96, flat_with_a_hole(0.05, under))
        expected = [0.86, 0.86]
        expected[under] = 0.91
        assert lengths == pytest.approx(expected)


def test_flat_ground_keeps_the_nominal_length_and_reach_is_capped() -> None:
    hip, velocity = (0.0, 1.2), (0.4, 0.0)
    assert plan_reach(hip, velocity, 1.625, (0.3, -0.06), 0.86, 0.96, lambda x, f: 0.0) == (0.86, 0.86)
    deep = plan_reach(hip, velocity, 1.625, (0.3, -0.06), 0.86, 0.96, flat_with_a_hole(0.3, 0))
    assert deep == pytest.approx((0.96, 0.86))


def test_the_plan_uses_the_ground_where_the_feet_come_down() -> None:
    """A hole 0.5 m ahead only matters if the arc takes the foot there."""
    hole = lambda x, foot: -0.05 if x > 0.5 else 0.0  # noqa: E731
    slow = plan_reach((0.0, 1.2), (0.0, 0.0), 1.625, (0.2, -0.2), 0.86, 0.96, hole)
    fast = plan_reach((0.0, 1.2), (0.8, 0.0), 1.625, (0.2, -0.2), 0.86, 0.96, hole)
    assert slow == (0.86, 0.86)
    # 1.2 - 0.86 - 0.04 = 0.3 m of fall: t = 0.61 s, 0.49 m on: the left foot (0.2 ahead) is over the hole.
    assert fast[0] == pytest.approx(0.91) and fast[1] == pytest.approx(0.86)
    assert np.isfinite(fast).all()
