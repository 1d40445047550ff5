"""One line per swept axis: for each of its values, episodes, falls and the worst landing and momentum.

The landing and momentum say how the controller flew, so they leave out the episodes whose controller
faulted (the PID flew on from the fault, hopper.experiments.outcome); the failure counts keep them."""

from __future__ import annotations

from typing import Any

import pyarrow as pa
import pyarrow.compute as pc

from hopper.experiments import outcome
from hopper.experiments.spec import GAINS, PARAM_PREFIX
from hopper.experiments.store import worst_landing

UNITS = {"kp": "N m/rad", "ki": "N m/(rad s)", "kd": "N m s/rad", "gravity": "m/s^2"}


def axis_lines(episodes: pa.Table, axes: dict[str, tuple[Any, ...]]) -> list[str]:
    """Axes with more than one value; each value: n episodes, falls, and over those without a controller
    fault the worst landing (deg) and peak momentum (%)."""
    lines = []
    for name, values in axes.items():
        if len(values) < 2:
            continue
        pool = _flying(episodes, name)
        column = pool.column(name)
        parts = []
        for value in values:
            rows = pool.filter(pc.equal(column, pa.scalar(value, type=column.type)))
            if rows.num_rows == 0:
                continue
            falls = pc.sum(rows.column("fell")).as_py() or 0
            parts.append(f"{_label(value)}: {falls}/{rows.num_rows} fell{_failed_otherwise(rows)}, {_flown(rows)}")
        notes = [_unit(pool, name)] + (["pid episodes"] if pool is not episodes else [])
        unit = ", ".join(note for note in notes if note)
        lines.append(f"{name}{f' ({unit})' if unit else ''}: " + "; ".join(parts))
    return lines


def _unit(episodes: pa.Table, name: str) -> str:
    """A swept setting's unit: a gain's or gravity's, or a controller param's as its controllers
    declare it (hopper.controllers.Param); "" if none or they disagree."""
    if name in UNITS:
        return UNITS[name]
    if not name.startswith(PARAM_PREFIX) or "controller" not in episodes.column_names:
        return ""
    from hopper.controllers import ControllerError, load_class

    units = set()
    for spec in set(episodes.column("controller").to_pylist()):
        try:
            declared = load_class(spec).params
        except ControllerError:  # a file gone since the sweep: no unit rather than no summary
            continue
        units |= {p.unit for p in declared if p.name == name.removeprefix(PARAM_PREFIX)}
    return units.pop() if len(units) == 1 else ""


def _flying(episodes: pa.Table, name: str) -> pa.Table:
    """The episodes whose flight law flies the setting `name`: a gain axis only the PID's (the other
    controllers' episodes hold the default gains, hopper.experiments.spec.SweepSpec.flown)."""
    if name not in GAINS or "controller" not in episodes.column_names:
        return episodes
    pid = pc.equal(episodes.column("controller"), "pid")
    return episodes if pc.all(pid).as_py() else episodes.filter(pid)


def overall_line(episodes: pa.Table) -> str:
    n = episodes.num_rows
    if n == 0:
        return "no episodes"
    falls = pc.sum(episodes.column("fell")).as_py() or 0
    sim = pc.sum(episodes.column("sim_time_s")).as_py()
    kept, faults = _unfaulted(episodes)
    if kept.num_rows:
        landing = _landing(kept) + (f" ({faults} faulted left out)" if faults else "")
    else:
        landing = "none (every episode's controller faulted)"
    return (f"{n} episodes, {falls} fell ({100 * falls / n:.1f} %){_failed_otherwise(episodes)}, worst landing "
            f"{landing}, {sim:.0f} s simulated")  # fmt: skip


def _unfaulted(rows: pa.Table) -> tuple[pa.Table, int]:
    """The episodes the controller flew to the end, and how many faulted (their later flights the PID's)."""
    faulted = outcome.faulted(rows)
    return rows.filter(pa.array(~faulted)), int(faulted.sum())


def _flown(rows: pa.Table) -> str:
    """ "land X, wheel Y %": the worst landing and peak wheel momentum over the episodes without a fault,
    saying how many faulted ones were left out."""
    kept, faults = _unfaulted(rows)
    if not kept.num_rows:
        return f"land none, wheel none (all {faults} faulted)"
    momentum = pc.max(kept.column("momentum_used_pct")).as_py()
    return f"land {_landing(kept)}, wheel {momentum:.1f} %" + (f" ({faults} faulted left out)" if faults else "")


def _failed_otherwise(rows: pa.Table) -> str:
    """ ", k controller faults" and ", k not disturbed" where there are any (outcome's rule): a fault is a
    failure whatever the PID did after it, an episode whose disturbance never came no survivor of it."""
    faults, missed = int(outcome.faulted(rows).sum()), int((~outcome.applied(rows)).sum())
    return (f", {faults} controller fault{'s' if faults != 1 else ''}" if faults else "") + (
        f", {missed} not disturbed" if missed else ""
    )


def detail_lines(episodes: pa.Table) -> list[str]:
    """The controller faults' causes and the disturbances not applied, a line each where there are any."""
    return [line for line in (outcome.fault_line(episodes), outcome.not_applied_line(episodes)) if line]


def _landing(rows: pa.Table) -> str:
    """The worst landing over the episodes that landed at least once."""
    worst = pc.max(worst_landing(rows)).as_py()
    return "none (no hop completed)" if worst is None else f"{worst:.2f} deg"


def _label(value: Any) -> str:
    if isinstance(value, bool):
        return "on" if value else "off"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value) if value != "" else "none"
