"""What a sweep's episodes rows say happened, by one rule for the summary, Monte Carlo and the report.

An episode fails short of its hops, by a fall, or by a controller fault (the built-in PID flew on
from the fault, so the rest of its flights are not the controller's); it succeeds when it did not
fail and every landing was within LANDING_LIMIT_DEG. A folder written before a column existed reads
as it did then: no `controller_fault` column, no fault; no `disturbance_applied`, applied.
"""

from __future__ import annotations

from collections import Counter

import numpy as np
import pyarrow as pa

from hopper.experiments.stress import LANDING_LIMIT_DEG

SUCCESS_RULE = f"all hops done, no fall, no controller fault, every landing within {LANDING_LIMIT_DEG:g} deg"
NOT_APPLIED = "its hop or phase never came, or its delay outlasted the phase"


def column(table: pa.Table, name: str) -> np.ndarray:
    """A column of `table` as a numpy array."""
    return table.column(name).to_numpy(zero_copy_only=False)


def faults(table: pa.Table) -> np.ndarray:
    """Per episode, why its controller was replaced by the PID (str), "" where it was not."""
    if "controller_fault" not in table.column_names:
        return np.full(table.num_rows, "", dtype=object)
    return np.array([text or "" for text in table.column("controller_fault").to_pylist()], dtype=object)


def faulted(table: pa.Table) -> np.ndarray:
    """Per episode (bool): its controller faulted."""
    return faults(table) != ""


def applied(table: pa.Table) -> np.ndarray:
    """Per episode (bool): its disturbance happened (True without one, and in a folder without the column)."""
    if "disturbance_applied" not in table.column_names:
        return np.ones(table.num_rows, dtype=bool)
    return np.array([value is not False for value in table.column("disturbance_applied").to_pylist()], dtype=bool)


def failed(table: pa.Table) -> np.ndarray:
    """Per episode (bool): short of its hops, fell, or its controller faulted."""
    short = column(table, "hops_completed") < column(table, "hops_target")
    return short | column(table, "fell").astype(bool) | faulted(table)


def success(table: pa.Table) -> np.ndarray:
    """Per episode (bool): not failed and every landing within LANDING_LIMIT_DEG (SUCCESS_RULE)."""
    landing = np.nan_to_num(column(table, "worst_landing_deg").astype(float), nan=np.inf)
    return ~failed(table) & (landing <= LANDING_LIMIT_DEG)


def fault_line(table: pa.Table) -> str | None:
    """The controller faults in one line, each cause with its count (most common first); None without one."""
    causes = faults(table)
    hit = causes != ""
    if not hit.any():
        return None
    named = Counter(zip(_controllers(table)[hit], causes[hit], strict=True))
    why = "; ".join(f"{controller} ({n} episode{'s' if n != 1 else ''}): {cause}"
                    for (controller, cause), n in named.most_common())  # fmt: skip
    return (f"{int(hit.sum())} of {table.num_rows} episodes had a controller fault and count as failed "
            f"(the PID flew on from it): {why}")  # fmt: skip


def not_applied_line(table: pa.Table) -> str | None:
    """How many disturbances never happened, in one line; None if every one did."""
    missed = int((~applied(table)).sum())
    if not missed:
        return None
    return (f"{missed} of {table.num_rows} episodes' disturbance was not applied ({NOT_APPLIED}): "
            "left out of the success against disturbance size")  # fmt: skip


def _controllers(table: pa.Table) -> np.ndarray:
    if "controller" not in table.column_names:
        return np.full(table.num_rows, "pid", dtype=object)
    return np.array(table.column("controller").to_pylist(), dtype=object)
