"""Per-hop metrics tables (the same metrics hopper-sim prints), updated at each touchdown: the
hop itself, then its pitch response (hopper.metrics.ResponseMetrics) to the scheduled kick or,
without one, from liftoff."""

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
    # Electrical energy over the hop, ground and flight (hopper.control.energy), and its cost of transport.
    ("wheel_energy_j", "E wheel", "J", "{:.0f}"),
    ("leg_energy_j", "E legs", "J", "{:.0f}"),
    ("cost_of_transport", "CoT", "", "{:.1f}"),  # dimensionless
)
# The response: from the scheduled kick (its delay after liftoff in the "kick" column) or the liftoff.
RESPONSE_COLUMNS = (
    ("response_peak_deg", "peak", "°", "{:.1f}"),
    ("overshoot_deg", "over", "°", "{:.2f}"),
    ("settling_time_s", "settle", "s", "{:.2f}"),
    ("peak_wheel_torque_nm", "torque", "N m", "{:.1f}"),
    ("peak_momentum_pct", "moment", "%", "{:.0f}"),
    ("landing_error_deg", "land", "°", "{:+.2f}"),
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
        self.table.content = hop_table_html(self.hops) + response_table_html(self.hops)

    def show(self, hops: list[HopMetrics]) -> None:
        """Exactly these hops (the simulation was put back to an earlier moment)."""
        self.hops[:] = hops
        self.stale = False
        self.table.content = hop_table_html(self.hops)

    def clear(self) -> None:
        """After a reset: keep showing the last run (dimmed) until the first new hop replaces it."""
        if self.hops and not self.stale:
            self.stale = True
            self.table.content = hop_table_html(self.hops, stale=True) + response_table_html(self.hops, stale=True)


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


def _settle(value: float, settled: bool) -> str:
    return f"{value:.2f}" if settled else f"&gt;{value:.2f}"  # a lower bound: still outside 1° at touchdown


def response_table_html(hops: list[HopMetrics], stale: bool = False) -> str:
    """The response of each hop's flight (newest last), then the mean of the kicked hops (or of
    every completed hop when none was kicked)."""
    head = "".join(f"<th>{h}<br><span>{u}</span></th>" for _, h, u, _ in RESPONSE_COLUMNS)
    rows = []
    for hop in hops[-ROWS:]:
        kick = f"{hop.response_start_s * 1000:.0f}" if hop.kicked else "–"
        cells = "".join(
            f"<td>{_settle(hop.settling_time_s, hop.settled)}</td>"
            if f == "settling_time_s"
            else f"<td>{_cell(getattr(hop, f), fmt)}</td>"
            for f, _, _, fmt in RESPONSE_COLUMNS
        )
        mark = "" if hop.completed else " class='hd-fell' title='ended in a fall'"
        rows.append(f"<tr{mark}><td>{hop.index}</td><td>{kick}</td>{cells}</tr>")
    done = [h for h in hops if h.completed]
    kicked = [h for h in done if h.kicked]
    if done:
        group = kicked or done
        means = []
        for f, _, _, fmt in RESPONSE_COLUMNS:
            mean = sum(getattr(h, f) for h in group) / len(group)
            settled = all(h.settled for h in group)
            means.append(f"<td>{_settle(mean, settled) if f == 'settling_time_s' else _cell(mean, fmt)}</td>")
        label = "x̄ of the kicked hops" if kicked else "x̄ of all hops (none kicked)"
        rows.append(
            f"<tr class='hd-mean' title='{label}'><td>x̄</td><td>{'k' if kicked else ''}</td>{''.join(means)}</tr>"
        )
    if not rows:
        rows.append(f"<tr><td colspan={len(RESPONSE_COLUMNS) + 2} class='hd-empty'>no hops yet</td></tr>")
    source = "after the scheduled kick" if any(h.kicked for h in hops) else "from liftoff (no kick scheduled)"
    caption = f"<caption>pitch response {source}; settle: into 1°</caption>"
    cls = "hd-hops hd-response hd-stale" if stale else "hd-hops hd-response"
    head = f"<tr><th>#</th><th>kick<br><span>ms</span></th>{head}</tr>"
    return f"<table class='{cls}'>{caption}{head}{''.join(rows)}</table>"


def build_hop_table(gui: viser.GuiApi) -> HopTable:
    return HopTable(table=gui.add_html(hop_table_html([]) + response_table_html([])))
