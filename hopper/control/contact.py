"""Debounced foot contact with hysteresis: a foot's touch force becomes a believed on/off."""

from __future__ import annotations

from numba import njit

from hopper.control.phases import DEBOUNCE_OFF_S, DEBOUNCE_ON_S


@njit(cache=True)
def debounce(force: float, time: float, on: bool, pending: float, on_n: float, off_n: float) -> tuple[bool, float]:
    """One foot's contact: on above `on_n`, off below `off_n` (N, hysteresis), believed after a
    hold of DEBOUNCE_ON_S / DEBOUNCE_OFF_S. `pending` is when a change started (s), < 0 if none.

    Returns the new (on, pending).
    """
    changing = force < off_n if on else force > on_n
    if not changing:
        return on, -1.0
    if pending < 0.0:
        return on, time
    if time - pending >= (DEBOUNCE_OFF_S if on else DEBOUNCE_ON_S) - 1e-9:
        return not on, -1.0
    return on, pending
