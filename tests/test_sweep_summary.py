"""The sweep's closing lines: a value whose episodes never landed says so instead of a perfect 0.00 deg."""

from __future__ import annotations

import pyarrow as pa
import pytest

from hopper.experiments.summary import axis_lines, detail_lines, overall_line

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


def test_a_controller_fault_and_a_disturbance_never_applied_are_counted_and_said() -> None:
    """A faulted episode flew its last hops on the PID, so it did not fall: the summary said `0 fell`
    and nothing more; a kick that never came said nothing at all."""
    table = episodes([True] * 4, [3] * 4, [0.1] * 4, [False] * 4).append_column(
        "controller", pa.array(["pid", "flaky.py:Flaky", "pid", "flaky.py:Flaky"])
    )
    table = table.append_column("hops_target", pa.array([3] * 4))
    table = table.append_column(
        "controller_fault", pa.array(["", "Flaky returned nan N m", "", "Flaky returned nan N m"])
    )
    table = table.append_column("disturbance_applied", pa.array([True, True, False, True]))
    assert overall_line(table).startswith("4 episodes, 0 fell (0.0 %), 2 controller faults, 1 not disturbed, ")
    (line,) = axis_lines(table, {"controller": ("pid", "flaky.py:Flaky")})
    assert "pid: 0/2 fell, 1 not disturbed, land" in line and "flaky.py:Flaky: 0/2 fell, 2 controller faults," in line
    faults, missed = detail_lines(table)
    assert faults.startswith("2 of 4 episodes had a controller fault and count as failed")
    assert "flaky.py:Flaky (2 episodes): Flaky returned nan N m" in faults
    assert missed.startswith("1 of 4 episodes' disturbance was not applied")
    older = episodes([True], [3], [0.1], [False])  # a folder of before either column: as it read then
    assert overall_line(older).startswith("1 episodes, 0 fell (0.0 %), worst landing") and detail_lines(older) == []


def test_a_controller_params_axis_gives_the_unit_its_controller_declares() -> None:
    """`param_pitch_tol: 2: ...` gave no unit where the gains' axes give theirs."""
    table = episodes([True, True], [3, 3], [0.1, 0.2], [False, False])
    table = table.append_column("controller", pa.array(["lqr", "lqr"])).append_column("param_pitch_tol", [[2.0, 5.0]])
    (line,) = axis_lines(table, {"param_pitch_tol": (2.0, 5.0)})
    assert line.startswith("param_pitch_tol (deg): 2: 0/1 fell"), line
    unknown = table.set_column(table.column_names.index("controller"), "controller", pa.array(["gone.py:X"] * 2))
    assert axis_lines(unknown, {"param_pitch_tol": (2.0, 5.0)})[0].startswith("param_pitch_tol: 2: ")


def test_the_landing_and_momentum_leave_out_the_faulted_episodes_the_counts_keep() -> None:
    """`land` and `wheel` took in the episodes whose controller faulted: a PID flying on from the fault
    to a 9 deg landing at 99 % of the wheel made them the PID's figures, not the controller's."""
    table = episodes([True] * 5, [3] * 5, [0.1, 9.0, 0.2, 9.0, 9.0], [False] * 5)
    table = table.set_column(table.column_names.index("momentum_used_pct"), "momentum_used_pct",
                             pa.array([50.0, 99.0, 60.0, 99.0, 99.0]))  # fmt: skip
    table = table.append_column("kd", pa.array([30.0, 30.0, 30.0, 40.0, 40.0]))
    table = table.append_column("hops_target", pa.array([3] * 5))
    cause = "Picky returned nan N m"
    table = table.append_column("controller_fault", pa.array(["", cause, "", cause, cause]))
    (line,) = axis_lines(table, {"kd": (30.0, 40.0)})
    assert line == ("kd (N m s/rad): 30: 0/3 fell, 1 controller fault, land 0.20 deg, wheel 60.0 % (1 faulted left "
                    "out); 40: 0/2 fell, 2 controller faults, land none, wheel none (all 2 faulted)"), line  # fmt: skip
    assert "0 fell (0.0 %), 3 controller faults, worst landing 0.20 deg (3 faulted left out), " in overall_line(table)
    every = table.filter(pa.array([False, True, False, True, True]))
    assert "worst landing none (every episode's controller faulted), " in overall_line(every)
