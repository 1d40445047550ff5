"""A log's gaps (Log.gaps) in rows: a replay never flies across one, since the commands sent while
the logger was silent are not in the log, and an open-loop flight on commands that are not there
scores the logger's silence, not the model.

A span of rows that holds a gap is cut there into pieces that each follow on sample by sample; the
piece after a gap starts again from the log's state at its far side (re-anchored, as multiple
shooting does at every window), LEAD rows past it: a replay from row k also reads the rows before
it (the wheel's delay line holds the commands of the last few ticks; the legs' rates are backward
differences), and those must be samples the log holds, not ones from before the gap. A whole hop,
which starts at its liftoff, is not: half a hop from mid-flight is no hop, and its error is no
measure beside the others'. It is left out and named.
"""

from __future__ import annotations

import numpy as np

from hopper.config import MAX_MOTOR_DELAY_TICKS
from hopper.logs.schema import Log

# Rows a replay reads before the one it starts from: the longest delay line, and one for the rates.
LEAD = MAX_MOTOR_DELAY_TICKS + 1


def far_rows(log: Log) -> np.ndarray:
    """The first row after each gap, in order."""
    return np.searchsorted(log.time, [end for _, end in log.gaps])


def crossed(log: Log, span: tuple[int, int]) -> list[tuple[float, float]]:
    """The gaps (start, end) s that a replay of rows span[0]..span[1]-1 would read across: inside
    the span, or within the LEAD rows before it."""
    a, b = span
    return [gap for gap, row in zip(log.gaps, far_rows(log), strict=True) if a - LEAD < row < b]


def pieces(log: Log, span: tuple[int, int]) -> list[tuple[int, int]]:
    """Rows span[0]..span[1] cut at each gap a replay would read across: (start, stop) pieces of 2
    rows or more, each starting LEAD rows or more past the gap before it."""
    a, b = span
    far = far_rows(log)
    cuts = [int(row) for row in far if a < row < b]
    out = []
    for x, y in zip([a, *cuts], [*cuts, b], strict=True):
        behind = far[(far <= x) & (x < far + LEAD)]
        x = int(behind[-1]) + LEAD if behind.size else x
        if y - x >= 2:
            out.append((x, y))
    return out


def note(log: Log, label: str, span: tuple[int, int], whole: bool) -> str | None:
    """One line on what a replay of `span` (`label`, e.g. "hop 1") does about the gaps it holds: a
    `whole` hop is not scored; anything else is re-anchored at each gap's far side. None: no gap."""
    inside = crossed(log, span)
    if not inside:
        return None
    a, b = span
    missing = sum(end - start for start, end in inside)
    where = ", ".join(f"{start:.3f}-{end:.3f} s" for start, end in inside)
    held = f"holds {len(inside)} gaps" if len(inside) > 1 else "holds a gap"
    then = "not scored" if whole else "re-anchored on the log's state at its far side"
    return (
        f"{label} ({log.time[a]:.3f}-{log.time[b - 1]:.3f} s) {held}, {missing:.3f} s without samples ({where}): {then}"
    )
