"""Status strip: phase, simulation time, real-time factor (and a warning when behind), hops, wheel."""

from __future__ import annotations

import dataclasses
import html
import math

import viser


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


def gauge_html(fraction: float, capacity_nms: float) -> str:
    """A centre-zero bar: the wheel's momentum against its capacity each way, and the headroom left.

    The fill grows from the middle toward the side the wheel spins; the ticks at +-50 % and the
    colour (green, amber from 50 %, red from 80 %) say how much of the next flight's authority is gone.
    It is re-sent with the strip 5 times a second, so it carries no text the help already gives.
    """
    f = max(-1.0, min(1.0, fraction))
    level = "hd-ok" if abs(f) < 0.5 else "hd-warn" if abs(f) < 0.8 else "hd-bad"
    start = 50.0 if f >= 0 else 50.0 + f * 50.0  # the fill starts at the centre line
    return (
        f"<div class='hd-gauge'><span>−{capacity_nms:.2f}</span>"
        f"<div class='hd-gauge-bar'><div class='hd-gauge-fill {level}' "
        f"style='left:{start:.1f}%;width:{abs(f) * 50:.1f}%'></div><i></i></div>"
        f"<span>+{capacity_nms:.2f} N m s</span></div>"
    )


def status_html(s: Status) -> str:
    if s.paused:
        rtf = "<b class='hd-paused'>paused</b>"
    elif math.isinf(s.speed):
        rtf = f"{s.rtf:.1f}× <span class='hd-dim' title='as fast as the machine allows'>(Max)</span>"
    elif s.behind:
        rtf = f"<b class='hd-behind' title='the machine cannot keep up'>{s.rtf:.2f}× of {s.speed:g}× — behind</b>"
    else:
        rtf = f"{s.rtf:.2f}× <span class='hd-dim'>(asked {s.speed:g}×)</span>"
    rec = " <b class='hd-rec'>● REC</b>" if s.recording else ""
    phase = html.escape(s.phase)
    return (
        "<div class='hd-status'>"
        f"<div><span class='hd-phase hd-{phase}'>{phase}</span>{rec}</div>"
        "<table>"
        f"<tr><td>time</td><td>{s.time:8.2f} s</td><td>real time</td><td>{rtf}</td></tr>"
        f"<tr><td>pitch</td><td>{s.pitch_deg:+6.1f}°</td><td>hops</td><td>{s.hops}</td></tr>"
        f"<tr><td>wheel</td><td>{s.wheel_rpm:+5.0f} rpm</td>"
        f"<td>limit used</td><td>{s.saturation * 100:3.0f} %</td></tr>"
        f"<tr><td>gravity</td><td>{s.gravity:g} m/s²</td>"
        f"<td>capacity</td><td>{s.capacity * 100:+4.0f} % · {s.capacity * s.capacity_nms:+.2f} N m s</td></tr>"
        "</table>"
        f"{gauge_html(s.capacity, s.capacity_nms)}"
        "</div>"
    )


@dataclasses.dataclass
class StatusPanel:
    html: viser.GuiHtmlHandle
    phase: str = ""  # the phase the badge shows ("" before the first show)

    def show(self, status: Status) -> None:
        self.phase = status.phase
        content = status_html(status)
        if content != self.html.content:
            self.html.content = content


def build_status_panel(gui: viser.GuiApi) -> StatusPanel:
    return StatusPanel(html=gui.add_html("<div class='hd-status'>starting…</div>"))
