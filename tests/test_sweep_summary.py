"""The sweep's closing lines: a value whose episodes never landed says so instead of a perfect 0.00 deg."""

from __future__ import annotations

import pyarrow as pa
import pytest

from hopper.experiments.summary import axis_lines, overall_line

pytestmark = pytest.mark.unit


def episodes(wheel: list[bool], completed: list[int], landing: list[float], fell: list[bool]) -> pa.Table:
    """An episodes table with the columns the summary reads (worst_landing_deg is 0 without a hop, as stored)."""
    n = len(wheel)
    return pa.table(
        {
            "wheel": wheel,
            "hops_completed": completed,
            "worst_landing_deg": landing,
            "fell": fell,
            "momentum_used_pct": [50.0] * n,
            "sim_time_s": [10.0] * n,
        }
    )


def test_a_value_whose_robots_all_fell_before_landing_reports_no_landing() -> None:
    table = episodes([True, True, False, False], [3, 3, 0, 0], [0.04, 0.02, 0.0, 0.0], [False, False, True, True])
    (line,) = axis_lines(table, {"wheel": (True, False)})
    on, off = line.removeprefix("wheel: ").split("; ")
    assert on == "on: 0/2 fell, land 0.04 deg, wheel 50.0 %"
    assert off == "off: 2/2 fell, land none (no hop completed), wheel 50.0 %"
    assert "worst landing 0.04 deg" in overall_line(table)


def test_episodes_without_a_landing_do_not_lower_or_replace_the_worst() -> None:
    table = episodes([True, False], [0, 2], [0.0, 0.31], [True, False])
    assert "worst landing 0.31 deg" in overall_line(table)
    table = episodes([True, False], [0, 0], [0.0, 0.0], [True, True])
    assert "worst landing none (no hop completed)" in overall_line(table)
