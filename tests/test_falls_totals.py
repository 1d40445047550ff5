"""The falls benchmark's totals (benchmarks.falls.totals), per hop and per metre of crater ground, and its ground."""

from __future__ import annotations

import pytest

from benchmarks.falls import craters, totals
from hopper.config import CraterParams

pytestmark = pytest.mark.unit


def result(hops: int, x: float, fell: bool = False, stuck: bool = False, trapped: int | None = None) -> dict:
    return {"hops": hops, "x": x, "fell": fell, "stuck": stuck, "pushes": hops + 10, "recoveries": 5, "near": 2,
            "trapped": trapped}  # fmt: skip


def test_totals_count_falls_per_hop_and_per_metre_of_ground():
    line = totals("earth", [result(100, 30.0, fell=True), result(300, 50.0, trapped=120), result(50, 20.0, stuck=True)])
    assert line == (
        " earth: 450 hops, 1 falls, 1 stuck, 1 trapped, 225 hops per fall or stop, 0.22 m a hop, "
        "50 m per fall or stop, 3% of pushes recovery hops, 6 near falls (the torso beyond 15 deg and back)"
    )


def test_totals_without_a_fall_say_so_rather_than_divide_by_zero():
    line = totals("moon", [result(300, 200.0)])
    assert "- hops per fall or stop" in line and "- m per fall or stop" in line and "0.67 m a hop" in line


def test_depth_scales_every_craters_depth_and_rim_and_keeps_the_rest():
    base, half = CraterParams(), craters(0.5)
    assert half.depth_ratio_range == (base.depth_ratio_range[0] / 2, base.depth_ratio_range[1] / 2)
    assert half.rim_ratio_range == (base.rim_ratio_range[0] / 2, base.rim_ratio_range[1] / 2)
    assert half.diameter_range == base.diameter_range and half.density == base.density
    with pytest.raises(ValueError, match="depth_ratio_range"):
        craters(-1.0)
