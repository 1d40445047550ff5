"""Status strip: phase, simulation time, real-time factor (and a warning when behind), hops, wheel.

The strip is a table of labels around nine values that change five times a second. viser's HTML
element re-sends its whole content when set (630 bytes, 2.4 kB/s a client compressed), so the
strip is two elements: the table itself (the *frame*), sent only when its layout changes (paused,
Max, behind, recording, gravity, another robot), and a hidden one that carries the values alone
(`<template data-hd-status='[...]'>`, about 100 bytes). static/status.js, run in each page as it connects,
writes the values into the frame's cells marked `data-v` (their index in FIELDS) as each arrives.
Both are viser's shared elements, so they go in the frame's atomic batch with the poses and a new
page gets the latest of each; until its script runs, a page shows the values the frame was sent with.
"""

from __future__ import annotations

import dataclasses
import html
import json
import math
from typing import Any

import viser
from hopper.app.dashboard import assets
from hopper.app.dashboard import viser_compat as compat

# The values the page script writes, by index (each cell's data-v): the phase sets its badge's colour
# too, the gauge its fill ("level left% width%").
FIELDS = ("phase", "time", "rtf", "pitch", "hops", "wheel", "limit", "capacity", "gauge")
GAUGE = FIELDS.index("gauge")
BLANK = ("",) * len(FIELDS)  # no values: a frame_html of them is the strip's layout alone
VALUES = "data-hd-status"  # the hidden element's attribute that holds the values (a JSON list)


@dataclasses.dataclass(frozen=True)
class Status:
    """One snapshot of what the status strip shows (plain values, taken on the loop thread)."""

    phase: str
    time: float  # s of simulation
    rtf: float  # simulated s per wall s
    speed: float  # asked, x real time (math.inf: Max)
    paused: bool
    behind: bool
    hops: int
    pitch_deg: float
    wheel_rpm: float
    saturation: float  # 0..1
    capacity: float  # -1..1, the wheel's momentum as a fraction of its capacity (signed)
    capacity_nms: float  # N m s, the capacity itself: (I_w + armature) * no-load speed
    gravity: float  # m/s^2
    recording: bool


def _signed(x: float, decimals: int) -> str:
    """`x` with its sign, "+0" rather than "-0" for what rounds to zero."""
    return f"{round(x, decimals) + 0.0:+.{decimals}f}"  # + 0.0 turns -0.0 into 0.0


def values(s: Status) -> tuple[str, ...]:
    """The strip's changing values as shown, in FIELDS order (unpadded: HTML collapses the spaces)."""
    f = max(-1.0, min(1.0, s.capacity))
    level = "hd-ok" if abs(f) < 0.5 else "hd-warn" if abs(f) < 0.8 else "hd-bad"
    start = 50.0 if f >= 0 else 50.0 + f * 50.0  # the fill starts at the centre line
    return (
        s.phase,
        f"{s.time:.2f}",
        f"{s.rtf:.1f}" if math.isinf(s.speed) else f"{s.rtf:.2f}",
        _signed(s.pitch_deg, 1),
        f"{s.hops}",
        _signed(s.wheel_rpm, 0),
        f"{s.saturation * 100:.0f}",
        f"{_signed(s.capacity * 100, 0)} % · {_signed(s.capacity * s.capacity_nms, 2)}",
        f"{level} {start:.1f} {abs(f) * 50:.1f}",
    )


def _cell(i: int, shown: tuple[str, ...]) -> str:
    return f"<span data-v='{i}'>{html.escape(shown[i])}</span>"


def gauge_html(shown: tuple[str, ...], capacity_nms: float) -> str:
    """A centre-zero bar: the wheel's momentum against its capacity each way, and the headroom left.

    The fill grows from the middle toward the side the wheel spins; the ticks at +-50 % and the
    colour (green, amber from 50 %, red from 80 %) say how much of the next flight's authority is gone.
    """
    level, left, width = (shown[GAUGE] or " 50.0 0.0").split(" ")
    return (
        f"<div class='hd-gauge'><span>−{capacity_nms:.2f}</span>"
        f"<div class='hd-gauge-bar'><div class='hd-gauge-fill {level}' data-v='{GAUGE}' "
        f"style='left:{left}%;width:{width}%'></div><i></i></div>"
        f"<span>+{capacity_nms:.2f} N m s</span></div>"
    )


def frame_html(s: Status, shown: tuple[str, ...]) -> str:
    """The strip with the values `shown` in its cells (blanks: its layout alone, to tell a change of it)."""
    c = {name: _cell(i, shown) for i, name in enumerate(FIELDS)}
    if s.paused:
        rtf = "<b class='hd-paused'>paused</b>"
    elif math.isinf(s.speed):
        rtf = f"{c['rtf']}× <span class='hd-dim' title='as fast as the machine allows'>(Max)</span>"
    elif s.behind:
        rtf = f"<b class='hd-behind' title='the machine cannot keep up'>{c['rtf']}× of {s.speed:g}× — behind</b>"
    else:
        rtf = f"{c['rtf']}× <span class='hd-dim'>(asked {s.speed:g}×)</span>"
    rec = " <b class='hd-rec'>● REC</b>" if s.recording else ""
    phase = html.escape(shown[0])
    return (
        "<div class='hd-status'>"
        f"<div><span class='hd-phase hd-{phase}' data-v='0'>{phase}</span>{rec}</div>"
        "<table>"
        f"<tr><td>time</td><td>{c['time']} s</td><td>real time</td><td>{rtf}</td></tr>"
        f"<tr><td>pitch</td><td>{c['pitch']}°</td><td>hops</td><td>{c['hops']}</td></tr>"
        f"<tr><td>wheel</td><td>{c['wheel']} rpm</td>"
        f"<td>limit used</td><td>{c['limit']} %</td></tr>"
        f"<tr><td>gravity</td><td>{s.gravity:g} m/s²</td>"
        f"<td>capacity</td><td>{c['capacity']} N m s</td></tr>"
        "</table>"
        f"{gauge_html(shown, s.capacity_nms)}"
        "</div>"
    )


def status_html(s: Status) -> str:
    """The strip as a page shows it: the frame with the current values in it."""
    return frame_html(s, values(s))


def values_html(shown: tuple[str, ...]) -> str:
    """The hidden element that carries the values (a template: it takes no room in the panel)."""
    text = json.dumps(shown, ensure_ascii=False, separators=(",", ":"))
    return (
        f"<template {VALUES}='{text.replace('&', '&amp;').replace(chr(39), '&#39;').replace('<', '&lt;')}'></template>"
    )


def decode_values(content: Any) -> dict[str, str] | None:
    """The values (by FIELDS name) a hidden element's `content` carries; None if it carries none."""
    if not isinstance(content, str) or f"<template {VALUES}='" not in content:
        return None
    text = html.unescape(content.split("='", 1)[1].rsplit("'>", 1)[0])
    return dict(zip(FIELDS, json.loads(text), strict=True))


@dataclasses.dataclass
class StatusPanel:
    frame: viser.GuiHtmlHandle
    carrier: viser.GuiHtmlHandle  # the hidden element with the values
    status: Status | None = None  # the status the page shows (None before the first show)
    layout: str = ""  # the frame's layout last sent (frame_html with BLANK values)

    @property
    def phase(self) -> str:
        """The phase the badge shows ("" before the first show)."""
        return "" if self.status is None else self.status.phase

    @property
    def shown(self) -> str:
        """The strip as the pages show it: what status.js makes of the frame and the values sent."""
        return self.frame.content if self.status is None else status_html(self.status)

    def show(self, status: Status) -> None:
        self.status, shown = status, values(status)
        carried = values_html(shown)
        if carried != self.carrier.content:
            self.carrier.content = carried
        layout = frame_html(status, BLANK)
        if layout != self.layout:  # a new layout: the frame again, with the values it now holds
            self.layout = layout
            self.frame.content = frame_html(status, shown)


def build_status_panel(server: viser.ViserServer) -> StatusPanel:
    """The strip, and its page script run in each page as it connects."""
    gui = server.gui
    panel = StatusPanel(frame=gui.add_html("<div class='hd-status'>starting…</div>"), carrier=gui.add_html(""))
    server.on_client_connect(lambda client: compat.run_javascript(client, assets.status_runtime()))
    return panel
