"""The replay's figure: pitch and wheel-speed error over time, one line per replay (`hopper-sim replay --out`)."""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure

from hopper.logs.replay import Errors
from hopper.report import style


def error_figure(parts: list[tuple[str, Errors]], name: str) -> Figure:
    """Simulated minus logged pitch (deg) and wheel speed (rad/s) against the log's time (s); each
    replay starts at its own moment from the log's state, so each line starts at zero error."""
    fig, (pitch, wheel) = style.new_figure(2, 2.4, f"Replay of {name}: the log's commands, open loop, from its state")
    for i, (_, e) in enumerate(parts):  # alternate colours: consecutive replays
        color = style.WHEEL_ON if i % 2 == 0 else style.SECOND
        pitch.plot(e.time, np.degrees(e.pitch), color=color, linewidth=0.8)
        wheel.plot(e.time, e.wheel_speed, color=color, linewidth=0.8)
    for ax in (pitch, wheel):
        ax.axhline(0.0, color="#888888", linewidth=0.5)
    total = Errors.concat([e for _, e in parts])
    pitch.set_ylabel("pitch error (deg)")
    pitch.set_title(f"RMS {math.degrees(total.rms('pitch')):.3g} deg over {len(parts)} replay(s)", loc="right")
    wheel.set_ylabel("wheel speed error (rad/s)")
    wheel.set_xlabel("log time (s)")
    wheel.set_title(f"RMS {total.rms('wheel_speed'):.3g} rad/s", loc="right")
    return fig
