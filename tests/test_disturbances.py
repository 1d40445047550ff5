"""The disturbances' table (hopper.disturbances): one kind, one name, one limit."""

from __future__ import annotations

import typing

from hopper.disturbances import DISTURBANCE_LIMITS, DISTURBANCE_NAMES, DisturbanceKind


def test_every_disturbance_kind_has_a_name_and_a_limit() -> None:
    kinds = set(typing.get_args(DisturbanceKind))
    assert kinds == set(DISTURBANCE_NAMES) == set(DISTURBANCE_LIMITS)
    assert all(limit > 0 and unit for limit, unit in DISTURBANCE_LIMITS.values())
