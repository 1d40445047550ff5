"""The paper's figures of a run (Sec. V): translation, pitch with wheel rpm, wheel torque, hop metrics."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

from hopper.config import SATURATION_FRACTION
from hopper.report import style
from hopper.report.runs import Run, wheel_label

# The paper's reported ranges (Sec. V-B, V-D), drawn as references.
PAPER_PEAK_DEG = (15.0, 20.0)
PAPER_RMS_DEG_S = (40.0, 55.0)
PAPER_LANDING_DEG = 3.5
PAPER_SATURATION_S = 0.9


def _shade_flights(ax, run: Run) -> None:  # noqa: ANN001 (matplotlib Axes)
    for k, (up, down) in enumerate(run.flights()):
        ax.axvspan(up, down, color=style.FLIGHT, zorder=0, label="flight" if k == 0 else None)


def _mark_fall(ax, run: Run, values: np.ndarray) -> None:  # noqa: ANN001
    if run.fell and len(values):
        ax.plot(run.trace["t_s"][-1], values[-1], "x", color=style.LIMIT, markersize=9, mew=2, label="fall")


def translation(run: Run) -> Figure:
    """Forward (x) and vertical (z) torso position over the hop sequence (paper Fig. 3)."""
    fig, (ax_x, ax_z) = style.new_figure(2, title=f"Torso translation over the hops ({run.label})")
    t = run.trace["t_s"]
    for ax, key, label in ((ax_x, "x_m", "forward x (m)"), (ax_z, "z_m", "vertical z (m)")):
        _shade_flights(ax, run)
        ax.plot(t, run.trace[key], color=style.WHEEL_ON if run.wheel else style.WHEEL_OFF, lw=1.2, label="torso CoM")
        _mark_fall(ax, run, run.trace[key])
        ax.set_ylabel(label)
    for hop in run.hops:
        down = hop["touchdown_time_s"]
        ax_x.annotate(f"{hop['index']}", (down, np.interp(down, t, run.trace["x_m"])), textcoords="offset points",
                      xytext=(2, 4), fontsize=7, color="#555555")  # fmt: skip
    ax_x.legend(loc="upper left")
    ax_z.set_xlabel("simulation time (s)")
    return fig


def pitch_and_wheel(on: Run, off: Run | None = None) -> Figure:
    """Body pitch with the wheel's speed (paper Fig. 4a); below, pitch with the wheel on vs off."""
    rows = 2 if off is not None else 1
    fig, axes = style.new_figure(rows, height=2.6, title=f"Body pitch and reaction-wheel speed ({on.label})")
    ax = axes[0]
    _shade_flights(ax, on)
    ax.plot(on.trace["t_s"], on.trace["pitch_deg"], color=style.WHEEL_ON, lw=1.2, label="pitch")
    _mark_fall(ax, on, on.trace["pitch_deg"])
    ax.set_ylabel("pitch (deg, + nose down)")
    twin = ax.twinx()
    twin.plot(on.trace["t_s"], on.trace["wheel_rpm"], color=style.SECOND, lw=0.9, alpha=0.85, label="wheel speed")
    twin.set_ylabel("wheel speed (rpm, rel. torso)", color=style.SECOND)
    twin.tick_params(axis="y", colors=style.SECOND)
    twin.spines["right"].set_visible(True)
    lines = ax.get_legend_handles_labels()
    more = twin.get_legend_handles_labels()
    style.legend_above(ax, lines[0] + more[0], lines[1] + more[1])
    if off is not None:
        ax2 = axes[1]
        ax2.plot(on.trace["t_s"], on.trace["pitch_deg"], color=style.WHEEL_ON, lw=1.2, label=on.label)
        ax2.plot(off.trace["t_s"], off.trace["pitch_deg"], color=style.WHEEL_OFF, lw=1.2, label=off.label)
        _mark_fall(ax2, off, off.trace["pitch_deg"])
        _mark_fall(ax2, on, on.trace["pitch_deg"])
        ax2.set_ylabel("pitch (deg, + nose down)")
        ax2.legend(loc="lower right")
        ax2.set_title("wheel on vs off, same terrain and gait", fontsize=9, loc="right")
    axes[-1].set_xlabel("simulation time (s)")
    return fig


def wheel_torque(run: Run) -> Figure:
    """Wheel torque with the flown robot's limit (+-29.5 N m on the packaged one) and the saturation
    threshold (paper Fig. 4b); without the limit lines if the run's model cannot be read now."""
    limit = run.wheel_torque_limit()
    unknown = "" if limit is not None else f", limit unknown: cannot read {run.settings.get('model')}"
    fig, (ax,) = style.new_figure(1, height=2.8, title=f"Reaction-wheel torque ({run.label}{unknown})")
    _shade_flights(ax, run)
    ax.plot(run.trace["t_s"], run.trace["wheel_torque_nm"], color=style.WHEEL_ON, lw=0.9, label="wheel torque")
    if limit is not None:
        for sign in (1, -1):
            ax.axhline(sign * limit, color=style.LIMIT, ls="--", lw=1,
                       label=f"limit ±{limit:.4g} N m" if sign > 0 else None)  # fmt: skip
            ax.axhline(sign * SATURATION_FRACTION * limit, color=style.LIMIT, ls=":", lw=0.8,
                       label=f"saturated ≥ {SATURATION_FRACTION:.0%}" if sign > 0 else None)  # fmt: skip
        ax.set_ylim(-1.15 * limit, 1.15 * limit)
    ax.set_ylabel("torque at the wheel (N m)")
    ax.set_xlabel("simulation time (s)")
    style.legend_above(ax)
    return fig


def _per_hop(runs: Sequence[Run], key: str) -> tuple[np.ndarray, list[np.ndarray]]:
    """Hop numbers 1..n and, for each, the values of `key` over the runs that reached that hop."""
    n = max((len(r.hops) for r in runs), default=0)
    values = [np.array([r.hops[i][key] for r in runs if len(r.hops) > i], dtype=float) for i in range(n)]
    return np.arange(1, n + 1), values


def flown(runs: Sequence[Run]) -> list[Run]:
    """The runs whose controller flew them to the end. A run whose controller faulted is a failure and
    its later flights are the PID's (hopper.experiments.outcome's rule): the per-hop medians leave it out."""
    return [r for r in runs if not r.fault]


def left_out(runs: Sequence[Run]) -> str:
    """The faulted runs the per-hop medians leave out, in a sentence for a caption; "" if none."""
    faulted = [r for r in runs if r.fault]
    if not faulted:
        return ""
    which = ", ".join(f"seed {r.seed} wheel {'on' if r.wheel else 'off'}" for r in faulted)  # as compare says it
    text = (f"Left out of the medians: {_runs(len(faulted))} whose controller faulted ({which}), as the PID flew on "
            "from the fault: their figures are not the controller's.")  # fmt: skip
    for wheel in (True, False):
        group = [r for r in runs if r.wheel is wheel]
        if group and not flown(group):
            text += f" {wheel_label(wheel).capitalize()}: every run faulted, so no bars."
    return text


def _runs(n: int) -> str:
    return f"{n} run{'s' if n != 1 else ''}"


def _bars(ax, runs: Sequence[Run], key: str, offset: float, color: str, label: str) -> None:  # noqa: ANN001
    """Median per hop over the runs the controller flew to the end (flown), whiskers from the lowest to
    the highest; hatched if any run ended that hop in a fall (its value is then the flight that fell).
    A group whose every run faulted gets a line saying so instead of bars."""
    kept = flown(runs)
    faulted, runs = len(runs) - len(kept), kept
    if faulted and not runs:
        ax.text(0.5, 0.6 if offset <= 0 else 0.4, f"{label}: no bars, the controller faulted in every run "
                f"({faulted}) and the PID flew on", transform=ax.transAxes, ha="center", va="center", color=color,
                fontsize=9, bbox={"facecolor": "white", "edgecolor": color, "boxstyle": "round"})  # fmt: skip
    hops, values = _per_hop(runs, key)
    if not len(hops):
        return
    med = np.array([np.median(v) for v in values])
    low = med - np.array([v.min() for v in values])
    high = np.array([v.max() for v in values]) - med
    fell = [any(len(r.hops) > i and not r.hops[i]["completed"] for r in runs) for i in range(len(hops))]
    bars = ax.bar(hops + offset, med, width=0.38, color=color, label=label, yerr=(low, high) if len(runs) > 1 else None,
                  error_kw={"elinewidth": 0.8, "capsize": 2, "ecolor": "#333333"})  # fmt: skip
    for bar, f, m in zip(bars, fell, med, strict=True):
        if not f:  # the value over the bar: small ones would not show against the paper's band
            ax.annotate(f"{m:.3g}", (bar.get_x() + bar.get_width() / 2, bar.get_height()), ha="center",
                        textcoords="offset points", xytext=(0, 2), fontsize=6, color="#333333")  # fmt: skip
        else:
            bar.set_hatch("///")
            bar.set_edgecolor("black")
            ax.annotate("fell", (bar.get_x() + bar.get_width() / 2, bar.get_height()), ha="center",
                        textcoords="offset points", xytext=(0, 2), fontsize=7)  # fmt: skip


def paper_bands() -> str:
    """The paper's per-hop ranges with the wheel on, in words."""
    (p0, p1), (r0, r1) = PAPER_PEAK_DEG, PAPER_RMS_DEG_S
    return f"peak pitch {p0:g} to {p1:g} deg, RMS pitch rate {r0:g} to {r1:g} deg/s"


def hop_metrics(on: Sequence[Run], off: Sequence[Run] = (), paper: bool = True) -> Figure:
    """Per-hop peak mid-air pitch and RMS pitch rate, wheel on vs off, with the paper's ranges when the
    runs fly the `paper`'s scenario (paper Fig. 5; in another, its flights are other flights, and its
    band would set the scale). With several runs (seeds), bars are medians and whiskers the range, over
    the runs the controller flew to the end (flown)."""
    what = _over(on or off, [*on, *off])
    states = "wheel on vs off" if on and off else ("wheel on" if on else "wheel off")
    fig, (ax_p, ax_r) = style.new_figure(2, height=2.5, title=f"Per-hop flight metrics, {states} ({what})")
    for ax, key, unit, band in (
        (ax_p, "peak_pitch_deg", "peak mid-air pitch (deg)", PAPER_PEAK_DEG),
        (ax_r, "rms_pitch_rate_deg_s", "RMS pitch rate in flight (deg/s)", PAPER_RMS_DEG_S),
    ):
        if paper:
            ax.axhspan(*band, color=style.PAPER, alpha=0.15, label=f"paper, wheel on: {band[0]:g} to {band[1]:g}")
        _bars(ax, on, key, -0.2 if off else 0.0, style.WHEEL_ON, "wheel on")
        if off:
            _bars(ax, off, key, 0.2, style.WHEEL_OFF, "wheel off (zero torque, free to spin)")
        ax.set_ylabel(unit)
        style.legend_above(ax)
    ax_r.set_xlabel("hop")
    hops = _per_hop(flown([*on, *off]), "peak_pitch_deg")[0]
    ax_r.set_xticks(hops)
    if len(hops):  # each hop's slot whole, though one group has no bars there (a fall, a fault)
        ax_r.set_xlim(0.5, len(hops) + 0.5)
    return fig


def _over(group: Sequence[Run], runs: Sequence[Run]) -> str:
    """What a figure's bars are over: its seeds (one group's count) or its one run's, and how many of
    `runs` faulted and were left out."""
    what = f"over {len(group)} seeds" if len(group) > 1 else group[0].label.split(",")[0]
    faulted = len(runs) - len(flown(runs))
    return f"{what}, {_runs(faulted)} that faulted left out" if faulted else what


def saturation(on: Sequence[Run]) -> Figure:
    """Wheel saturation time per hop (|torque| >= 98 % of the limit), with the paper's 0.9 s bound."""
    fig, (ax,) = style.new_figure(1, height=2.6, title=f"Wheel saturation time per hop ({_over(on, on)})")
    _bars(ax, on, "saturation_time_s", 0.0, style.WHEEL_ON, "wheel on")
    ax.axhline(
        PAPER_SATURATION_S, color=style.PAPER, ls="--", lw=1, label=f"paper: under {PAPER_SATURATION_S:g} s per hop"
    )
    hops, values = _per_hop(flown(on), "saturation_time_s")
    top = max((v.max() for v in values), default=0.0)
    ax.set_ylim(0, max(1.1 * PAPER_SATURATION_S, 1.2 * top))
    ax.set_xticks(hops)
    ax.set_xlabel("hop")
    ax.set_ylabel("saturation time (s)")
    style.legend_above(ax)
    if top == 0.0 and flown(on):
        ax.text(0.5, 0.5, "no saturation in any hop", transform=ax.transAxes, ha="center", color="#555555")
    return fig
