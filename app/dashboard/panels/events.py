"""Event log: disturbances, setting changes, falls and recordings, newest first, with run and time."""

from __future__ import annotations

import collections
import dataclasses
import html

import viser

from hopper.events import Event, EventKind, Reset

LINES = 7
SHOWN = frozenset(
    {
        EventKind.DISTURBANCE,
        EventKind.DISTURBANCE_ARMED,
        EventKind.GAINS,
        EventKind.WHEEL,
        EventKind.GRAVITY,
        EventKind.TERRAIN,
        EventKind.FALL,
        EventKind.DIVERGED,
        EventKind.RESET,
        EventKind.COMMAND_FAILED,
        EventKind.RECORDING,
        EventKind.SENSING,
        EventKind.OPERATOR,
        EventKind.CONTROLLER,
        EventKind.CONTROLLER_FAILED,
    }
)
QUIET_RESETS = ("start", "terrain", "diverged")  # the event that caused them is shown already


def describe(event: Event) -> str | None:
    """One line for the log, or None for events it does not show (hops have their own table)."""
    if event.kind not in SHOWN:
        return None
    if isinstance(event.payload, Reset) and event.payload.reason in QUIET_RESETS:
        return None
    return event.describe()


@dataclasses.dataclass
class EventLog:
    html: viser.GuiHtmlHandle
    lines: collections.deque[str] = dataclasses.field(default_factory=lambda: collections.deque(maxlen=LINES))

    def add(self, event: Event) -> None:
        text = describe(event)
        if text is None:
            return
        # Simulation time restarts at every reset: the run number says which run a time belongs to.
        when = f"<span class='hd-dim'>run {event.run}</span> {event.time:.2f} s"
        self.lines.appendleft(f"<tr><td>{when}</td><td>{html.escape(text)}</td></tr>")
        self.html.content = _html(self.lines)


def _html(lines: collections.deque[str]) -> str:
    body = "".join(lines) or "<tr><td></td><td class='hd-dim'>no events yet</td></tr>"
    return f"<table class='hd-log'>{body}</table>"


def build_event_log(gui: viser.GuiApi) -> EventLog:
    return EventLog(html=gui.add_html(_html(collections.deque())))
