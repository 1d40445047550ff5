"""Event log: disturbances, setting changes, falls and recordings, newest first, with run and time."""

from __future__ import annotations

import dataclasses
import html

import viser
from hopper.app.dashboard.panels.rows import BAND, Rows

from hopper.events import Event, EventKind, Reset

# Lines shown. A restore and its resume take two (three with the gains it brings back): 10 keep a
# tuning session's last 8 kicks, as many as the hop table's rows, in view beside them. The count costs
# nothing per event (a new line rewrites one element of the ring), only the page's first load.
LINES = 10
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
        EventKind.RESTORE,
        EventKind.RESUME,
        EventKind.INJECTION,
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


def line_html(event: Event, text: str) -> str:
    """One line of the log, a table of its own (panels/rows.py)."""
    # Simulation time restarts at every reset: the run number says which run a time belongs to.
    when = f"<span class='hd-dim'>run {event.run}</span> {event.time:.2f} s"
    # A long line is cut with "…" in the side panel: the whole of it shows on hover.
    text = html.escape(text)
    return f"<table class='hd-log'><tr><td>{when}</td><td title='{text}'>{text}</td></tr></table>"


EMPTY = "<table class='hd-log'><tr><td></td><td class='hd-dim'>no events yet</td></tr></table>"


@dataclasses.dataclass
class EventLog:
    """The newest LINES lines, newest first: a new event sends its own line, nothing else."""

    rows: Rows
    empty: viser.GuiHtmlHandle  # "no events yet", until the first

    def add(self, event: Event) -> None:
        text = describe(event)
        if text is None:
            return
        self.rows.add(line_html(event, text))
        self.empty.visible = False

    @property
    def lines(self) -> list[str]:
        """The lines shown, newest first."""
        return list(reversed(self.rows.shown))

    @property
    def content(self) -> str:
        """The log as a page shows it, for tests."""
        return "".join(self.lines) or EMPTY


def build_event_log(gui: viser.GuiApi) -> EventLog:
    rows = Rows(gui, LINES, 0.0, newest_first=True)
    return EventLog(rows, gui.add_html(EMPTY, order=2 * BAND))
