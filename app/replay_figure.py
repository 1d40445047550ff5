"""The replay's figure: pitch and wheel-speed error over time, one line per replay (`hopper-sim replay --out`)."""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure

from hopper.logs.replay import Errors
from hopper.logs.schema import GAP_FACTOR
from hopper.report import style


def broken(time: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`time` (s) and `values` with a NaN put in wherever consecutive samples are more than GAP_FACTOR
    median periods apart (a gap in the log): matplotlib then draws no line across it."""
    if time.size < 3:
        return time, values
    step = np.diff(time)
    jumps = np.flatnonzero(step > GAP_FACTOR * np.median(step)) + 1
    return np.insert(time.astype(float), jumps, np.nan), np.insert(values.astype(float), jumps, np.nan)


def error_figure(parts: list[tuple[str, Errors]], name: str) -> Figure:
    """Simulated minus logged pitch (deg) and wheel speed (rad/s) against the log's time (s); each
    replay starts at its own moment from the log's state, so each line starts at zero error. A gap in
    the log breaks its line (a replay re-anchored at the gap's far side starts again there)."""
    fig, (pitch, wheel) = style.new_figure(2, 2.4, f"Replay of {name}: the log's commands, open loop, from its state")
    for i, (_, e) in enumerate(parts):  # alternate colours: consecutive replays
        color = style.WHEEL_ON if i % 2 == 0 else style.SECOND
        pitch.plot(*broken(e.time, np.degrees(e.pitch)), color=color, linewidth=0.8)
        wheel.plot(*broken(e.time, e.wheel_speed), color=color, linewidth=0.8)
    for ax in (pitch, wheel):
        ax.axhline(0.0, color="#888888", linewidth=0.5)
    total = Errors.concat([e for _, e in parts])
    pitch.set_ylabel("pitch error (deg)")
    pitch.set_title(f"RMS {math.degrees(total.rms('pitch')):.3g} deg over {len(parts)} replay(s)", loc="right")
    wheel.set_ylabel("wheel speed error (rad/s)")
    wheel.set_xlabel("log time (s)")
    wheel.set_title(f"RMS {total.rms('wheel_speed'):.3g} rad/s", loc="right")
    return fig
