"""Per-hop metrics tables (the same metrics hopper-sim prints), updated at each touchdown: the
hop itself, then its pitch response (hopper.metrics.ResponseMetrics) to the scheduled kick or,
without one, from liftoff."""

from __future__ import annotations

import dataclasses
import html
import itertools
import math

import viser
from hopper.app.dashboard.panels.rows import BAND, Rows

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
    ("wheel_energy_j", "wheel", "J", "{:.0f}"),  # under one "wheel" with the speed (hop_header_html)
    ("leg_energy_j", "legs", "J", "{:.0f}"),
    ("cost_of_transport", "CoT", "", "{:.1f}"),  # dimensionless
)
# What each header means, on hover (hopper.metrics.HopMetrics): the side panel leaves room for a word.
TITLES = {
    "distance_m": "distance since the last touchdown",
    "apex_height_m": "apex above the liftoff height",
    "flight_time_s": "flight time",
    "peak_pitch_deg": "peak |pitch| in flight",
    "rms_pitch_rate_deg_s": "RMS pitch rate in flight",
    "landing_pitch_deg": "|pitch| at touchdown",
    "saturation_time_s": "time at the wheel's torque limit",
    "peak_wheel_rpm": "peak wheel speed",
    "wheel_energy_j": "wheel motor's electrical energy",
    "leg_energy_j": "leg motors' electrical energy",
    "cost_of_transport": "cost of transport: energy / (m g distance)",
}
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
# Order bands in the Hops folder (panels/rows.py): each table's header, rows, then its mean row.
HOPS_AT, RESPONSE_AT = 0.0, 10 * BAND


def _table(inner: str, cls: str = "", stale: bool = False) -> str:
    """One part of a table (its header, a row, its mean) as a table of its own: fixed, equal columns line up.

    Every part of the response table is `hd-resp`, so a page (or a test) can tell the two tables' parts apart.
    """
    classes = " ".join(c for c in ("hd-hops", cls, "hd-stale" if stale else "") if c)
    return f"<table class='{classes}'>{inner}</table>"


def _cell(value: float, fmt: str) -> str:
    return fmt.format(value) if math.isfinite(value) else "–"


def _mark(hop: HopMetrics) -> str:
    return "" if hop.completed else " class='hd-fell' title='ended in a fall'"


def hop_header_html() -> str:
    """Names over units; neighbouring columns of one name (the wheel's rpm and J) share one header."""
    names = []
    for name, group in itertools.groupby(COLUMNS, key=lambda column: column[1]):
        columns = list(group)
        title = html.escape("; ".join(f"{TITLES[f]}, {u}" if u else TITLES[f] for f, _, u, _ in columns))
        span = f" colspan={len(columns)}" if len(columns) > 1 else ""
        names.append(f'<th{span} title="{title}">{name}</th>')
    units = "".join(f'<th title="{html.escape(TITLES[f])}"><span>{u}</span></th>' for f, _, u, _ in COLUMNS)
    return _table(f"<tr class='hd-names'><th>#</th>{''.join(names)}</tr><tr><th></th>{units}</tr>")


def hop_row_html(hop: HopMetrics, stale: bool = False) -> str:
    cells = "".join(f"<td>{_cell(getattr(hop, f), fmt)}</td>" for f, _, _, fmt in COLUMNS)
    return _table(f"<tr{_mark(hop)}><td>{hop.index}</td>{cells}</tr>", stale=stale)


def transport(hops: list[HopMetrics]) -> float:
    """The hops' cost of transport together, as `hopper-sim run` prints it: all their energy over m g
    times all their distance, not a mean of ratios (a short hop's is large, and a hop in place has
    none: NaN). Each hop's m g |d| is its energy over its own figure (the gravity may change between
    hops); a hop in place adds its energy and no distance. NaN if none moved."""
    moved = [h for h in hops if math.isfinite(h.cost_of_transport) and h.cost_of_transport > 0]
    weight_distance = sum((h.wheel_energy_j + h.leg_energy_j) / h.cost_of_transport for h in moved)
    energy = sum(h.wheel_energy_j + h.leg_energy_j for h in hops)
    return energy / weight_distance if weight_distance > 0 else math.nan


def hop_mean_html(hops: list[HopMetrics], stale: bool = False) -> str:
    """The mean of the completed hops (the cost of transport: theirs together), or "no hops yet"; under
    it, when stale, that they are the last run's."""
    done = [h for h in hops if h.completed]
    if done:
        mean = {f: sum(getattr(h, f) for h in done) / len(done) for f, _, _, _ in COLUMNS}
        mean["cost_of_transport"] = transport(done)
        means = "".join(f"<td>{_cell(mean[f], fmt)}</td>" for f, _, _, fmt in COLUMNS)
        row = f"<tr class='hd-mean'><td>x̄</td>{means}</tr>"
    else:
        row = f"<tr><td colspan={len(COLUMNS) + 1} class='hd-empty'>{'no hops yet' if not hops else ''}</td></tr>"
    caption = "<caption>previous run</caption>" if stale else ""
    return _table(f"{caption}{row}", "hd-end", stale)


def _settle(value: float, settled: bool) -> str:
    return f"{value:.2f}" if settled else f"&gt;{value:.2f}"  # a lower bound: still outside 1° at touchdown


def response_header_html(hops: list[HopMetrics]) -> str:
    head = "".join(f"<th>{h}<br><span>{u}</span></th>" for _, h, u, _ in RESPONSE_COLUMNS)
    source = "after the scheduled kick" if any(h.kicked for h in hops) else "from liftoff (no kick scheduled)"
    caption = f"<caption>pitch response {source}; settle: into 1°</caption>"
    return _table(f"{caption}<tr><th>#</th><th>kick<br><span>ms</span></th>{head}</tr>", "hd-response hd-resp")


def response_row_html(hop: HopMetrics, stale: bool = False) -> str:
    """The response of one hop's flight."""
    kick = f"{hop.response_start_s * 1000:.0f}" if hop.kicked else "–"
    cells = "".join(
        f"<td>{_settle(hop.settling_time_s, hop.settled)}</td>"
        if f == "settling_time_s"
        else f"<td>{_cell(getattr(hop, f), fmt)}</td>"
        for f, _, _, fmt in RESPONSE_COLUMNS
    )
    return _table(f"<tr{_mark(hop)}><td>{hop.index}</td><td>{kick}</td>{cells}</tr>", "hd-resp", stale)


def response_mean_html(hops: list[HopMetrics], stale: bool = False) -> str:
    """The mean of the kicked hops (or of every completed hop when none was kicked), or "no hops yet"."""
    done = [h for h in hops if h.completed]
    kicked = [h for h in done if h.kicked]
    if not done:
        empty = "no hops yet" if not hops else ""
        return _table(
            f"<tr><td colspan={len(RESPONSE_COLUMNS) + 2} class='hd-empty'>{empty}</td></tr>", "hd-end hd-resp"
        )
    group = kicked or done
    means = []
    for f, _, _, fmt in RESPONSE_COLUMNS:
        mean = sum(getattr(h, f) for h in group) / len(group)
        settled = all(h.settled for h in group)
        means.append(f"<td>{_settle(mean, settled) if f == 'settling_time_s' else _cell(mean, fmt)}</td>")
    label = "x̄ of the kicked hops" if kicked else "x̄ of all hops (none kicked)"
    row = f"<tr class='hd-mean' title='{label}'><td>x̄</td><td>{'k' if kicked else ''}</td>{''.join(means)}</tr>"
    return _table(row, "hd-end hd-resp", stale)


@dataclasses.dataclass
class HopTable:
    """The hop table and the response table: a new hop sends its two rows and the two means, nothing else."""

    rows: Rows
    mean: viser.GuiHtmlHandle
    response_header: viser.GuiHtmlHandle
    response_rows: Rows
    response_mean: viser.GuiHtmlHandle
    hops: list[HopMetrics] = dataclasses.field(default_factory=list)
    stale: bool = False  # rows from before the last reset, kept dimmed until the next hop

    def add(self, hop: HopMetrics) -> None:
        if self.stale:
            self.hops.clear()
            self.stale = False
            self.hops.append(hop)
            self._render()
            return
        self.hops.append(hop)
        self.rows.add(hop_row_html(hop))
        self.response_rows.add(response_row_html(hop))
        self._render_means()

    def show(self, hops: list[HopMetrics]) -> None:
        """Exactly these hops (the simulation was put back to an earlier moment)."""
        self.hops[:] = hops
        self.stale = False
        self._render()

    def clear(self) -> None:
        """After a reset: keep showing the last run (dimmed) until the first new hop replaces it."""
        if self.hops and not self.stale:
            self.stale = True
            self._render()

    def _render(self) -> None:
        """Every row again (a reset, a restore, the first hop after a reset: not at each hop)."""
        shown = self.hops[-ROWS:]
        self.rows.replace([hop_row_html(h, self.stale) for h in shown])
        self.response_rows.replace([response_row_html(h, self.stale) for h in shown])
        self._render_means()

    def _render_means(self) -> None:
        self.mean.content = hop_mean_html(self.hops, self.stale)
        self.response_mean.content = response_mean_html(self.hops, self.stale)
        self.response_header.content = response_header_html(self.hops)  # sent only when the caption changes

    def html(self) -> str:
        """The two tables as a page shows them, for tests and logs."""
        return (
            hop_header_html()
            + "".join(self.rows.shown)
            + self.mean.content
            + self.response_header.content
            + "".join(self.response_rows.shown)
            + self.response_mean.content
        )


def build_hop_table(gui: viser.GuiApi) -> HopTable:
    gui.add_html(hop_header_html(), order=HOPS_AT)
    rows = Rows(gui, ROWS, HOPS_AT + 1)
    mean = gui.add_html(hop_mean_html([]), order=HOPS_AT + 2 * BAND)
    response_header = gui.add_html(response_header_html([]), order=RESPONSE_AT)
    response_rows = Rows(gui, ROWS, RESPONSE_AT + 1)
    response_mean = gui.add_html(response_mean_html([]), order=RESPONSE_AT + 2 * BAND)
    return HopTable(rows, mean, response_header, response_rows, response_mean)
