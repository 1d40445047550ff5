"""The league's figure and table (`hopper-sim league --json`): one bar per controller and figure.

The flight figures (landing to saturation) are over each controller's episodes without a controller fault
(hopper.experiments.league); a controller whose every episode faulted has none, and says so."""

from __future__ import annotations

import math
from typing import Any

from matplotlib.figure import Figure

from hopper.report import page, style
from hopper.report.build import Named, Report

PANELS = (  # row key, axis label (units), what a lower bar means
    ("success_pct", "episodes passed (%)", "higher is better"),
    ("landing_p95_deg", "landing |pitch| p95 (deg)", "lower is better"),
    ("energy_j", "energy per hop (J)", "lower is better"),
    ("compute_us", "compute per call (us)", "lower is better"),
)
CONTROLLER_COLORS = (style.WHEEL_ON, style.SECOND, style.PAPER, style.WHEEL_OFF, "#6a4c93", "#555555")
COLUMNS = (  # row key, heading
    ("controller", "controller"), ("success_pct", "ok (%)"), ("falls", "falls"), ("faults", "faults"),
    ("landing_p50_deg", "landing p50 (deg)"), ("landing_p95_deg", "p95 (deg)"), ("landing_max_deg", "max (deg)"),
    ("peak_pitch_deg", "peak pitch (deg)"), ("rms_rate_deg_s", "RMS rate (deg/s)"), ("energy_j", "energy (J/hop)"),
    ("saturation_s", "saturation (s/hop)"), ("compute_us", "compute (us/call)"),
)  # fmt: skip


COMPILED = "compiled (in the ~1 us kernel tick)"  # a compute of 0: no Python call to time (the league's rule)
ALL_FAULTED = "every episode faulted"  # no flight figure is the controller's: the PID flew on from each fault


def name(spec: str) -> str:
    """A controller's spec as a bar's label: a file spec by its file's name."""
    return spec.rpartition("/")[2]


def cell(row: dict[str, Any], key: str) -> Any:
    """A row's value for the table: the controller by its name, a compute of 0 as compiled."""
    if key == "controller":
        return name(row[key])
    if key == "compute_us" and row[key] == 0:
        return COMPILED
    if row[key] is None or (isinstance(row[key], float) and math.isnan(row[key])):  # NaN: an older league JSON
        return ALL_FAULTED if _all_faulted(row) else "n/a"
    return row[key]


def _all_faulted(row: dict[str, Any]) -> bool:
    return row.get("flown") == 0 and row["episodes"] > 0


def left_out_note(rows: list[dict[str, Any]]) -> str:
    """What the flight figures leave out: each controller's faulted episodes; "" where none faulted. A league
    JSON written before they were left out (no `flown`) says its figures include them."""
    faulted = [r for r in rows if r["faults"]]
    if not faulted:
        return ""
    older = [name(r["controller"]) for r in faulted if "flown" not in r]
    if older:
        return (f"The flight figures of {', '.join(older)} include their faulted episodes, whose later flights are the "
                "PID's (a league JSON written before they were left out).")  # fmt: skip
    which = ", ".join(f"{name(r['controller'])} {r['faults']} of {r['episodes']}" for r in faulted)
    return (f"The landing, peak pitch, RMS rate, energy and saturation leave out the episodes with a controller "
            f"fault (the PID flew on from each; they count as failed): {which}.")  # fmt: skip


def bars(rows: list[dict[str, Any]]) -> Figure:
    """Success, landing p95, energy and compute per controller, side by side."""
    fig, axes = style.new_figure(rows=len(PANELS), height=1.9, title="League: every controller on one battery")
    labels = [name(r["controller"]) for r in rows]
    colors = [CONTROLLER_COLORS[i % len(CONTROLLER_COLORS)] for i in range(len(rows))]
    for ax, (key, label, better) in zip(axes, PANELS, strict=True):
        raw = [r[key] if r[key] is not None else math.nan for r in rows]
        values = [v if math.isfinite(v) else 0.0 for v in raw]
        ax.bar(range(len(rows)), values, color=colors)
        ax.set_ylabel(label, fontsize=8)
        ax.set_title(better, fontsize=7, loc="right")
        for i, (v, r) in enumerate(zip(raw, rows, strict=True)):
            text = f"{v:.3g}" if math.isfinite(v) else ("all faulted" if _all_faulted(r) else "n/a")
            if key == "compute_us" and r[key] == 0:
                text = COMPILED
            ax.annotate(text, (i, values[i]), ha="center", va="bottom", fontsize=7)
    axes[-1].set_xticks(range(len(rows)), labels, rotation=0, fontsize=8)
    return fig


def league_report(document: dict[str, Any], title: str) -> Report:
    """The league document's figure, its table, and each controller's worst failure."""
    rows = document["rows"]
    worst = "; ".join(f"{name(r['controller'])}: {r['worst']}" for r in rows if r["worst"]) or "no failures"
    left = left_out_note(rows)
    table = page.Section(
        "The league",
        header=[h for _, h in COLUMNS],
        rows=[[cell(r, k) for k, _ in COLUMNS] for r in rows],
        note=f"{worst}. {left}" if left else worst,
    )
    episodes = rows[0]["episodes"] if rows else 0
    caption = f"{episodes} episodes per controller, realistic sensing. {left}".strip()
    figure = Named("league", "League", caption, bars(rows))
    subtitle = f"{len(rows)} controllers, {episodes} episodes each (hopper-sim league, version {document['version']})"
    return Report(title, subtitle, {"controllers": [r["controller"] for r in rows]}, [figure], [table])
