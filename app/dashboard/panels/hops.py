"""Per-hop metrics table (the same metrics hopper-sim prints), updated at each touchdown."""

from __future__ import annotations

import dataclasses
import math

import viser

from hopper.metrics import HopMetrics

# (HopMetrics field, header, unit, format); the paper's targets are in static/help.md.
COLUMNS = (
    ("distance_m", "dist", "m", "{:.2f}"),
    ("apex_height_m", "apex", "m", "{:.2f}"),
    ("flight_time_s", "flight", "s", "{:.2f}"),
    ("peak_pitch_deg", "peak", "°", "{:.1f}"),
    ("rms_pitch_rate_deg_s", "rms", "°/s", "{:.0f}"),
    ("landing_pitch_deg", "land", "°", "{:.1f}"),
    ("saturation_time_s", "sat", "s", "{:.2f}"),
    ("peak_wheel_rpm", "wheel", "rpm", "{:.0f}"),
)
ROWS = 8  # newest hops shown; the mean covers every hop since the last reset


@dataclasses.dataclass
class HopTable:
    table: viser.GuiHtmlHandle
    hops: list[HopMetrics] = dataclasses.field(default_factory=list)
    stale: bool = False  # rows from before the last reset, kept dimmed until the next hop

    def add(self, hop: HopMetrics) -> None:
        if self.stale:
            self.hops.clear()
            self.stale = False
        self.hops.append(hop)
        self.table.content = hop_table_html(self.hops)

    def show(self, hops: list[HopMetrics]) -> None:
        """Exactly these hops (the simulation was put back to an earlier moment)."""
        self.hops[:] = hops
        self.stale = False
        self.table.content = hop_table_html(self.hops)

    def clear(self) -> None:
        """After a reset: keep showing the last run (dimmed) until the first new hop replaces it."""
        if self.hops and not self.stale:
            self.stale = True
            self.table.content = hop_table_html(self.hops, stale=True)


def _cell(value: float, fmt: str) -> str:
    return fmt.format(value) if math.isfinite(value) else "–"


def hop_table_html(hops: list[HopMetrics], stale: bool = False) -> str:
    """An HTML table: one row per hop (newest last), then the mean of completed hops."""
    head = "".join(f"<th>{h}<br><span>{u}</span></th>" for _, h, u, _ in COLUMNS)
    rows = []
    for hop in hops[-ROWS:]:
        cells = "".join(f"<td>{_cell(getattr(hop, f), fmt)}</td>" for f, _, _, fmt in COLUMNS)
        mark = "" if hop.completed else " class='hd-fell' title='ended in a fall'"
        rows.append(f"<tr{mark}><td>{hop.index}</td>{cells}</tr>")
    done = [h for h in hops if h.completed]
    if done:
        means = "".join(
            f"<td>{_cell(sum(getattr(h, f) for h in done) / len(done), fmt)}</td>" for f, _, _, fmt in COLUMNS
        )
        rows.append(f"<tr class='hd-mean'><td>x̄</td>{means}</tr>")
    if not rows:
        rows.append(f"<tr><td colspan={len(COLUMNS) + 1} class='hd-empty'>no hops yet</td></tr>")
    caption = "<caption>previous run</caption>" if stale else ""
    cls = "hd-hops hd-stale" if stale else "hd-hops"
    return f"<table class='{cls}'>{caption}<tr><th>#</th>{head}</tr>{''.join(rows)}</table>"


def build_hop_table(gui: viser.GuiApi) -> HopTable:
    return HopTable(table=gui.add_html(hop_table_html([])))
