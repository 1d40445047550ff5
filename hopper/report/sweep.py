"""A sweep's figures: Kp x Kd maps of the worst landing with falls marked, success against gravity and
disturbance size, read from the sweep's Parquet datasets (the `episodes` / `hops` contract).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.dataset as ds
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from hopper.config import GaitParams
from hopper.disturbances import DISTURBANCE_LIMITS
from hopper.experiments import outcome
from hopper.experiments.spec import GAINS
from hopper.experiments.store import worst_landing
from hopper.experiments.stress import LANDING_LIMIT_DEG  # the paper's landing bound (outcome.success)
from hopper.experiments.uncertainty import MODEL_PREFIX
from hopper.report import page, style
from hopper.report.build import Named, Report

REQUIRED = ("kp", "kd", "gravity", "wheel", "disturbance_size", "hops_target", "hops_completed", "fell",
            "worst_landing_deg")  # fmt: skip
# Setting columns of the contract, summarised per value when a sweep varies them.
SETTINGS = ("kp", "ki", "kd", "gravity", "seed", "hops_target", "terrain", "wheel", "sensing", "disturbance",
            "disturbance_size", "controller")  # fmt: skip
RESULTS = ("hops_completed", "fell", "worst_landing_deg", "peak_pitch_deg", "rms_pitch_rate_deg_s",
           "momentum_used_pct", "saturation_s", "sim_time_s", "wall_s", "energy_j_per_hop")  # fmt: skip


@dataclasses.dataclass(frozen=True)
class Sweep:
    """A sweep's episodes (one row each), its hops if found, and its spec's text if found."""

    episodes: pa.Table
    hops: pa.Table | None
    spec: str | None
    source: Path

    def column(self, name: str) -> np.ndarray:
        return self.episodes.column(name).to_numpy(zero_copy_only=False)

    def landing(self) -> np.ndarray:
        """Per episode, its worst landing error (deg); NaN for one that never landed."""
        return worst_landing(self.episodes).to_numpy().astype(float)

    def success(self) -> np.ndarray:
        """Per episode: hopper.experiments.outcome's rule (SUCCESS_RULE), as the Monte Carlo figures count."""
        return outcome.success(self.episodes)

    def flying(self, name: str) -> np.ndarray:
        """Per episode, whether its flight law flies the setting `name`: a gain only the PID's (the other
        controllers' episodes hold the default gains, hopper.experiments.spec.SweepSpec.flown)."""
        if name not in GAINS or "controller" not in self.episodes.column_names:
            return np.ones(self.episodes.num_rows, dtype=bool)
        return self.column("controller") == "pid"

    def values(self, name: str) -> list:
        """The values the setting `name` takes in the episodes that fly it (flying)."""
        return _unique(self.column(name)[self.flying(name)])

    def settings(self) -> list[str]:
        """The contract's setting columns present, and any swept gait parameter (named as in GaitParams)."""
        gait = [f.name for f in dataclasses.fields(GaitParams)]
        return [c for c in (*SETTINGS, *gait) if c in self.episodes.column_names]

    def varied(self) -> list[str]:
        """The setting columns that take more than one value."""
        return [c for c in self.settings() if len(self.values(c)) > 1]

    def drawn(self) -> list[str]:
        """The model parameters drawn per robot (hopper.experiments.uncertainty) that take more than one value."""
        columns = [c for c in self.episodes.column_names if c.startswith(MODEL_PREFIX)]
        return [c[len(MODEL_PREFIX) :] for c in columns if len(_unique(self.column(c))) > 1]

    def varied_text(self) -> str:
        """What the sweep varies, in words: its settings, then the model parameters drawn for its robots."""
        parts = list(self.varied())
        drawn = self.drawn()
        if drawn:
            robots = len(_unique(self.column("sample"))) if "sample" in self.episodes.column_names else "its"
            parts.append(f"{len(drawn)} model parameters drawn for {robots} robots ({', '.join(drawn)})")
        return ", ".join(parts) or "nothing"


def _unique(values: np.ndarray) -> list:
    return sorted(set(values.tolist()), key=lambda v: (str(type(v)), v))


def _dataset(path: Path) -> pa.Table:
    return ds.dataset(path, format="parquet").to_table()


def load(path: Path) -> Sweep:
    """A sweep directory (episodes/, hops/, spec.toml), or a Parquet file or folder of episodes.

    ValueError, one line, for a hops-only dataset or missing columns."""
    path = Path(path)
    spec, hops = None, None
    try:
        if path.is_dir() and (path / "episodes").is_dir():
            episodes = _dataset(path / "episodes")
            if (path / "hops").is_dir():
                hops = _dataset(path / "hops")
            if (path / "spec.toml").is_file():
                spec = (path / "spec.toml").read_text()
        else:
            episodes = _dataset(path)
    except (OSError, pa.ArrowException) as exc:
        raise ValueError(f"{path}: cannot read it as Parquet ({exc})") from None
    names = episodes.column_names
    if "hop" in names and "fell" not in names:
        raise ValueError(f"{path} holds a sweep's hops; give the sweep's directory or its episodes dataset")
    missing = [c for c in REQUIRED if c not in names]
    if missing:
        raise ValueError(f"{path}: not a sweep's episodes dataset (no {', '.join(missing)})")
    if episodes.num_rows == 0:
        raise ValueError(f"{path}: the sweep has no episodes yet")
    return Sweep(episodes, hops, spec, path)


def gain_map(sweep: Sweep, wheel: bool = True) -> Figure:
    """Kp x Kd coloured by the worst landing error over every episode in the cell (other axes and
    seeds pooled); falls marked with their count. Grey, "no landing": every episode in the cell fell before landing.
    Only the PID's episodes: no other controller flies the gains."""
    mask = (sweep.column("wheel").astype(bool) == wheel) & sweep.flying("kp")
    kp_all, kd_all = sweep.column("kp")[mask], sweep.column("kd")[mask]
    landing = sweep.landing()[mask]
    fell = sweep.column("fell")[mask].astype(bool)
    kps, kds = _unique(kp_all), _unique(kd_all)
    worst = np.full((len(kds), len(kps)), np.nan)
    falls = np.zeros_like(worst, dtype=int)
    counts = np.zeros_like(worst, dtype=int)
    for i, kd in enumerate(kds):
        for j, kp in enumerate(kps):
            cell = (kp_all == kp) & (kd_all == kd)
            counts[i, j], falls[i, j] = cell.sum(), fell[cell].sum()
            values = landing[cell]
            if np.isfinite(values).any():
                worst[i, j] = np.nanmax(values)
    title = f"Worst landing error over Kp x Kd ({'wheel on' if wheel else 'wheel off'})"
    fig, (ax,) = style.new_figure(1, height=max(2.6, 0.5 * len(kds) + 1.5), sharex=False, title=title)
    ax.grid(False)
    cmap = style.plt.get_cmap("viridis").with_extremes(bad="#bbbbbb")
    top = max(2 * LANDING_LIMIT_DEG, np.nanmax(worst) if np.isfinite(worst).any() else 0.0)
    image = ax.imshow(np.ma.masked_invalid(worst), origin="lower", aspect="auto", cmap=cmap, vmin=0.0, vmax=top)
    bar = fig.colorbar(image, ax=ax)
    bar.set_label("worst landing pitch error (deg)")
    bar.ax.axhline(LANDING_LIMIT_DEG, color="white", lw=1.5)
    for i in range(len(kds)):
        for j in range(len(kps)):
            text = "no landing" if not np.isfinite(worst[i, j]) else f"{worst[i, j]:.2f}°"
            if falls[i, j]:  # falls: a red frame, a cross in the corner and the count
                text += f"\n{falls[i, j]}/{counts[i, j]} fell"
                ax.add_patch(Rectangle((j - 0.48, i - 0.48), 0.96, 0.96, fill=False, edgecolor=style.LIMIT, lw=2.5))
                ax.plot(j + 0.4, i + 0.36, "X", color=style.LIMIT, markersize=9)
            dark = not np.isfinite(worst[i, j]) or worst[i, j] > 0.6 * top
            ax.text(j, i, text, ha="center", va="center", fontsize=8, color="black" if dark else "white")
    ax.set_xticks(range(len(kps)), [f"{v:g}" for v in kps])
    ax.set_yticks(range(len(kds)), [f"{v:g}" for v in kds])
    ax.set_xlabel("Kp (N m/rad)")
    ax.set_ylabel("Kd (N m s/rad)")
    return fig


def success_against(sweep: Sweep, column: str, label: str) -> Figure:
    """Share of successful episodes (outcome.SUCCESS_RULE) per value of
    `column`, one line per wheel state, with the episode count at each point."""
    fig, (ax,) = style.new_figure(1, height=2.8, sharex=False, title=f"Success rate against {label.split(' (')[0]}")
    _success_lines(ax, sweep, np.ones(sweep.episodes.num_rows, dtype=bool), column, label)
    return fig


def disturbance_kinds(sweep: Sweep) -> np.ndarray:
    """Per episode, its disturbance's kind (a DISTURBANCE_LIMITS key), "" for none and "?" for a
    description that names no known kind (the column holds hopper.experiments.spec.describe's text)."""
    if "disturbance" not in sweep.episodes.column_names:
        return np.where(sweep.column("disturbance_size").astype(float) == 0.0, "", "?")
    first = [text.split(" ", 1)[0] for text in sweep.column("disturbance").astype(str)]
    return np.array([word if word in DISTURBANCE_LIMITS or not word else "?" for word in first])


def success_against_disturbance(sweep: Sweep) -> Figure:
    """Success rate against the disturbance's size, one panel per kind with that kind's unit (an
    N m s kick and an N s push share no axis); the undisturbed episodes are each panel's size 0. An
    episode whose disturbance never happened is left out: its robot met no disturbance to survive."""
    kinds = disturbance_kinds(sweep)
    applied = outcome.applied(sweep.episodes)
    shown = sorted(set(kinds.tolist()) - {""}) or [""]
    fig, axes = style.new_figure(len(shown), height=2.8, sharex=False, title="Success rate against disturbance size")
    for ax, kind in zip(axes, shown, strict=True):
        rows = ((kinds == kind) | (kinds == "")) & applied
        if kind == "?":
            label = "disturbance size (kind and unit not recorded)"
        elif kind:
            label = f"{kind} size ({DISTURBANCE_LIMITS[kind][1]}); 0: undisturbed"
        else:
            label = "disturbance size"
        _success_lines(ax, sweep, rows, "disturbance_size", label)
    return fig


def _success_lines(ax, sweep: Sweep, chosen: np.ndarray, column: str, label: str) -> None:  # noqa: ANN001 (Axes)
    """On `ax`, the success rate of the `chosen` episodes per value of `column`, one line per wheel state."""
    x_all, ok, wheel = sweep.column(column).astype(float), sweep.success(), sweep.column("wheel").astype(bool)
    for state, color in ((True, style.WHEEL_ON), (False, style.WHEEL_OFF)):
        rows = chosen & (wheel == state)
        if not rows.any():
            continue
        xs = _unique(x_all[rows])
        rate = [100.0 * ok[rows & (x_all == x)].mean() for x in xs]
        n = [int((rows & (x_all == x)).sum()) for x in xs]
        name = "wheel on" if state else "wheel off (zero torque, free to spin)"
        ax.plot(xs, rate, "o-", color=color, label=name)
        for x, r, k in zip(xs, rate, n, strict=True):
            ax.annotate(f"n={k}", (x, r), textcoords="offset points", xytext=(0, 6), ha="center", fontsize=7)
    ax.set_ylim(-5, 112)
    ax.set_xlabel(label)
    ax.set_ylabel("successful episodes (%)")
    style.legend_above(ax)


def axis_table(sweep: Sweep) -> page.Section:
    """One line per value of each varied setting: episodes, success, falls, controller faults, and the worst
    landing over the episodes without a fault (after one the PID flew on: its landings are not the controller's)."""
    ok, fell, faulted = sweep.success(), sweep.column("fell").astype(bool), outcome.faulted(sweep.episodes)
    landing = np.where(faulted, np.nan, sweep.landing())
    rows = []
    for name in sweep.varied():
        values = sweep.column(name)
        for v in sweep.values(name):
            sel = sweep.flying(name) & (values == v)
            worst = np.nanmax(landing[sel]) if np.isfinite(landing[sel]).any() else "no landing"
            if sel.any() and faulted[sel].all():
                worst = "every one faulted"
            rows.append([name, v, int(sel.sum()), 100.0 * ok[sel].mean(), int(fell[sel].sum()), worst,
                         int(faulted[sel].sum())])  # fmt: skip
    header = ["setting", "value", "episodes", "success (%)", "falls", "worst landing (deg)", "controller faults"]
    note = f"Success: {outcome.SUCCESS_RULE}. {sweep.episodes.num_rows} episodes, {int(ok.sum())} successful."
    if faulted.any():
        note += " The worst landing leaves out the episodes with a controller fault (they count as failed)."
    for line in (outcome.fault_line(sweep.episodes), outcome.not_applied_line(sweep.episodes)):
        note += f" {line[0].upper()}{line[1:]}." if line else ""
    return page.Section("Per setting value", header=header, rows=rows, note=note)


def sweep_report(sweep: Sweep, title: str) -> Report:
    """The heat map(s), success against gravity and against disturbance size (when the sweep varies
    them), the per-value table and the spec."""
    figures, skipped = [], []
    drawn = "sample" in sweep.episodes.column_names  # robots drawn from distributions (hopper.report.montecarlo)
    one_cell = len(sweep.values("kp")) == len(sweep.values("kd")) == 1
    pid = sweep.flying("kp")
    if drawn and one_cell:
        skipped.append("one Kp x Kd cell: no gain map (the Monte Carlo figures show that gain set)")
    if not pid.any():
        skipped.append("no episode flies the PID: no Kp x Kd map (no other controller flies the gains)")
    wheel = sweep.column("wheel").astype(bool)
    if (wheel & pid).any() and not (drawn and one_cell):
        figures.append(Named("gain_map_wheel_on", "Kp x Kd, wheel on",
                             "Worst landing pitch error over every PID episode in each cell (other settings "
                             "pooled); red crosses and counts: episodes that fell; grey, no landing: every "
                             "episode in the cell fell before its first landing. White line on the scale: 3.5 deg.",
                             gain_map(sweep, True)))  # fmt: skip
    if (~wheel & pid).any():  # zero torque: the gains act on nothing, a map of them would show the seeds
        skipped.append("wheel off: no Kp x Kd map (the gains act through the wheel; the tables give those episodes)")
    for column, label in (("gravity", "gravity (m/s²)"), ("disturbance_size", "disturbance size")):
        if len(_unique(sweep.column(column))) > 1:
            note = f"Episodes with {outcome.SUCCESS_RULE}."
            if column == "disturbance_size":
                figure = success_against_disturbance(sweep)
                note += " One panel per disturbance kind, in its unit; the undisturbed episodes are each one's 0."
                missed = int((~outcome.applied(sweep.episodes)).sum())
                if missed:
                    note += (f" Left out: {missed} episodes whose disturbance was not applied "
                             f"({outcome.NOT_APPLIED}).")  # fmt: skip
            else:
                figure = success_against(sweep, column, label)
            figures.append(Named(f"success_vs_{column}", f"Success rate against {label}", note, figure))
        else:
            skipped.append(f"{column} takes one value ({_unique(sweep.column(column))[0]:g}): no figure against it")
    tables = [axis_table(sweep)]
    if drawn:
        from hopper.report import montecarlo

        drawn, section = montecarlo.figures(sweep.episodes)
        figures, tables = drawn + figures, [section, *tables]
    if skipped:
        tables.append(page.Section("Not drawn", note="; ".join(skipped) + "."))
    if sweep.spec:
        tables.append(page.Section("spec.toml", pre=sweep.spec))
    settings = {
        "source": str(sweep.source),
        "episodes": sweep.episodes.num_rows,
        "hop rows": sweep.hops.num_rows if sweep.hops is not None else "not found",
        **{f"values.{c}": ", ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in sweep.values(c))
           for c in sweep.settings()},
    }  # fmt: skip
    fell = int(pc.sum(sweep.episodes.column("fell").cast(pa.int64())).as_py())
    faults = int(outcome.faulted(sweep.episodes).sum())
    faulted = f", {faults} with a controller fault (failed)" if faults else ""
    subtitle = f"{sweep.episodes.num_rows} episodes, {fell} fell{faulted}; varied: {sweep.varied_text()}"
    return Report(title, subtitle, settings, figures, tables)
