"""Assemble a report: which figures and tables an input gets, and writing them (PNG, PDF, HTML)."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure

from hopper.config import GaitParams
from hopper.experiments.reduction import SeedPair, median_reduction
from hopper.report import page, run_figures, style
from hopper.report.runs import Run
from hopper.scenarios import scenario_of

HOP_TABLE = (  # HopMetrics key, column heading
    ("index", "hop"),
    ("distance_m", "distance (m)"),
    ("apex_height_m", "apex (m)"),
    ("flight_time_s", "flight (s)"),
    ("peak_pitch_deg", "peak pitch (deg)"),
    ("rms_pitch_rate_deg_s", "RMS rate (deg/s)"),
    ("landing_pitch_deg", "landing pitch (deg)"),
    ("saturation_time_s", "saturation (s)"),
    ("peak_wheel_rpm", "peak wheel (rpm)"),
    ("completed", "completed"),
)


@dataclasses.dataclass(frozen=True)
class Named:
    """A figure with the file name it is written under and its caption."""

    name: str
    title: str
    caption: str
    figure: Figure


@dataclasses.dataclass(frozen=True)
class Report:
    title: str
    subtitle: str
    settings: dict[str, Any]
    figures: list[Named]
    tables: list[page.Section] = dataclasses.field(default_factory=list)


def run_report(on: Sequence[Run], off: Sequence[Run], title: str, subtitle: str) -> Report:
    """The paper's figures: time series of the first wheel-on run (its wheel-off twin beside it),
    per-hop metrics and saturation over every run given."""
    shown = on[0] if on else off[0]
    twin = next((r for r in off if r.seed == shown.seed), None) if shown.wheel else None
    paper = with_scenario(shown.settings)["scenario"] == "paper"
    bands = (
        "green bands: the paper's ranges with the wheel on. "
        if paper
        else f"the paper's ranges with the wheel on ({run_figures.paper_bands()}) are drawn for its own scenario "
        "only (`--scenario paper`): this run's flights are others. "
    )
    figures = [
        Named("translation", "Forward and vertical translation", "Torso CoM over the hop sequence; flights shaded.",
              run_figures.translation(shown)),
        Named("pitch_wheel", "Body pitch and wheel speed",
              "Pitch (left axis) and the wheel's speed relative to the torso (right axis); below, the same "
              "terrain and gait with the wheel off (zero torque, wheel free to spin)." if twin else
              "Pitch (left axis) and the wheel's speed relative to the torso (right axis).",
              run_figures.pitch_and_wheel(shown, twin)),
        Named("wheel_torque", "Wheel torque", "Torque at the wheel with the ±29.5 N m limit (dashed) and the 98 % "
              "saturation threshold (dotted); drawn from the trace (100 Hz), so the saturation metric, taken every "
              "1 ms tick, may count pulses the curve does not show.", run_figures.wheel_torque(shown)),
        Named("hop_metrics", "Per-hop peak pitch and RMS pitch rate, wheel on vs off",
              f"Peak |pitch| and RMS pitch rate over each flight; {bands}Hatched: the flight ended in a fall (its "
              f"peak is the 60 deg fall limit). {run_figures.left_out([*on, *off])}".strip(),
              run_figures.hop_metrics([r for r in on], [r for r in off], paper)),
    ]  # fmt: skip
    if on:
        figures.append(Named("saturation", "Saturation time per hop",
                             "Time with |wheel torque| ≥ 98 % of 29.5 N m in each hop (ground and flight). "
                             f"{run_figures.left_out(on)}".strip(), run_figures.saturation(list(on))))  # fmt: skip
    tables = [hop_table(shown)]
    if on and off:
        tables.append(seed_table(on, off))
    faulted = [r for r in (*on, *off) if r.fault]
    if faulted:  # first: every figure after the fault shows the PID's flights, not the controller's
        tables.insert(0, fault_section(faulted, len(on) + len(off)))
    return Report(title, subtitle, with_scenario(shown.settings), figures, tables)


def with_scenario(settings: dict[str, Any]) -> dict[str, Any]:
    """The settings, led by the name of the gait preset they use (hopper.scenarios)."""
    gait = settings.get("gait")
    if not isinstance(gait, dict):
        return {"scenario": "unknown (no gait in the input)", **settings}
    try:
        name = scenario_of(GaitParams(**gait))
    except (TypeError, ValueError):  # a gait of another version
        name = None
    return {"scenario": name or "a gait of its own", **settings}


def fault_section(faulted: Sequence[Run], runs: int) -> page.Section:
    """The runs whose controller failed mid-run, each with its cause."""
    controller = faulted[0].settings.get("controller", "the controller")
    rows = [[r.label, r.fault] for r in faulted]
    note = (f"{controller} failed in {len(faulted)} of {runs} runs and the built-in PID flew on from the fault: "
            "their later flights are the PID's, not the controller's; such a run counts as failed and is left out "
            "of the per-hop medians and the median reduction.")  # fmt: skip
    return page.Section("Controller faults", header=["run", "cause"], rows=rows, note=note)


def hop_table(run: Run) -> page.Section:
    rows = [[hop[key] for key, _ in HOP_TABLE] for hop in run.hops]
    notes = [] if rows else ["no hop completed"]
    if run.fault:  # drawn as it flew: its hops after the fault are the PID's
        notes.append("its controller faulted and the PID flew on from the fault (Controller faults)")
    return page.Section(f"Hops: {run.label}", header=[h for _, h in HOP_TABLE], rows=rows, note="; ".join(notes))


def seed_table(on: Sequence[Run], off: Sequence[Run]) -> page.Section:
    """Per seed: the worst of each figure with the wheel on, the wheel-off peak and the reduction."""
    off_by_seed = {r.seed: r for r in off}
    rows, pairs = [], []
    for run in sorted(on, key=lambda r: str(r.seed)):
        done = [h for h in run.hops if h["completed"]]
        peak = max((h["peak_pitch_deg"] for h in run.hops), default=0.0)
        twin = off_by_seed.get(run.seed)
        peak_off = max((h["peak_pitch_deg"] for h in twin.hops), default=0.0) if twin else float("nan")
        if twin:
            pairs.append(SeedPair(run.seed, peak, peak_off, faulted_runs=bool(run.fault) + bool(twin.fault)))
        rows.append([
            run.seed, f"{len(done)}{_ended(run)}", peak,
            max((h["rms_pitch_rate_deg_s"] for h in run.hops), default=0.0),
            max((h["landing_pitch_deg"] for h in done), default=0.0),
            max((h["saturation_time_s"] for h in run.hops), default=0.0),
            f"{sum(h['completed'] for h in twin.hops)}{_ended(twin)}" if twin else "",
            peak_off, 100.0 * (peak_off - peak) / peak_off if twin and peak_off > 0 else float("nan"),
        ])  # fmt: skip
    header = ["seed", "on: hops", "peak (deg)", "RMS rate (deg/s)", "landing (deg)", "saturation (s/hop)",
              "off: hops", "off peak (deg)", "reduction (%)"]  # fmt: skip
    note = "Wheel off = zero wheel torque, the wheel free to spin."
    if pairs:  # compare's own line: a seed with a faulted run (its figures the PID's) is left out of it
        line = median_reduction(pairs).line()
        note = f"{line[0].upper()}{line[1:]}."
    return page.Section("Per seed (worst hop of each), wheel on vs off", header=header, rows=rows, note=note)


def _ended(run: Run) -> str:
    return (" fell" if run.fell else "") + (" fault" if run.fault else "")


def write(report: Report, folder: Path) -> list[Path]:
    """Each figure as folder/NAME.png and .pdf, and folder/report.html with them embedded."""
    folder.mkdir(parents=True, exist_ok=True)
    written, sections = [], []
    for named in report.figures:
        written += style.save(named.figure, folder, named.name)
        sections.append(page.Section(named.title, png=style.png_bytes(named.figure), caption=named.caption))
        style.close(named.figure)
    sections += report.tables
    html_path = folder / "report.html"
    html_path.write_text(page.render(report.title, report.subtitle, report.settings, sections), encoding="utf-8")
    return [*written, html_path]
