"""Event log: disturbances and setting changes with their simulation time and size, newest first."""

from __future__ import annotations

import collections
import dataclasses
import html
import math

import viser

from hopper.sim import Event

LINES = 7
_NAMES = {
    "pitch_kick": "pitch kick",
    "push_forward": "push ▶",
    "push_backward": "push ◀",
    "torque_pulse": "torque pulse",
}


def describe(event: Event) -> str | None:
    """One line for the log, or None for events it does not show."""
    d = event.data
    if event.kind == "disturbance":
        extra = f" for {d['duration_s']:g} s" if "duration_s" in d else ""
        return f"{_NAMES.get(d['kind'], d['kind'])} {d['magnitude']:+g} {d['unit']}{extra}"
    if event.kind == "disturbance_armed":
        return f"{_NAMES.get(d['kind'], d['kind'])} {d['magnitude']:+g} {d['unit']} armed for the next flight"
    if event.kind == "gains":
        return f"gains Kp {d['kp']:g}, Ki {d['ki']:g}, Kd {d['kd']:g}"
    if event.kind == "wheel":
        return "wheel on" if d["enabled"] else "wheel off (free spinning)"
    if event.kind == "gravity":
        return f"gravity {d['gravity']:g} m/s²"
    if event.kind == "terrain":
        return f"terrain {d['kind']}, seed {d['seed']}"
    if event.kind == "fall":
        return f"fell (pitch {d['pitch_deg']:+.0f}°)" if math.isfinite(d.get("pitch_deg", 0.0)) else "fell"
    if event.kind == "diverged":
        return f"diverged ({d.get('reason', '?')}), reset"
    if event.kind == "reset" and d.get("reason") not in ("start", "terrain", "diverged"):
        return f"reset ({d.get('reason', 'user')})"
    return None


@dataclasses.dataclass
class EventLog:
    html: viser.GuiHtmlHandle
    lines: collections.deque[str] = dataclasses.field(default_factory=lambda: collections.deque(maxlen=LINES))

    def add(self, event: Event) -> None:
        text = describe(event)
        if text is None:
            return
        self.lines.appendleft(f"<tr><td>{event.time:.2f} s</td><td>{html.escape(text)}</td></tr>")
        self.html.content = _html(self.lines)


def _html(lines: collections.deque[str]) -> str:
    body = "".join(lines) or "<tr><td></td><td class='hd-dim'>no events yet</td></tr>"
    return f"<table class='hd-log'>{body}</table>"


def build_event_log(gui: viser.GuiApi) -> EventLog:
    return EventLog(html=gui.add_html(_html(collections.deque())))
