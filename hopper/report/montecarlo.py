"""A sweep over sampled robots drawn: success probability with its Wilson interval per gain set, the
distributions of landing error, peak pitch, energy and momentum, and the landing error against each
sampled parameter (hopper.experiments.montecarlo computes the figures)."""

from __future__ import annotations

import math

import numpy as np
import pyarrow as pa
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from hopper.experiments.montecarlo import METRICS, QUANTILES, GroupStats, group_stats, landing_or_inf, success
from hopper.experiments.outcome import SUCCESS_RULE
from hopper.experiments.stress import LANDING_LIMIT_DEG
from hopper.experiments.uncertainty import MODEL_PREFIX, params
from hopper.report import page, style
from hopper.report.build import Named

COLOURS = (style.WHEEL_ON, style.SECOND, style.PAPER, "#7b4ea3", "#555555", style.WHEEL_OFF)
FAILED = style.LIMIT


def success_probability(stats: list[GroupStats]) -> Figure:
    """Per gain set: the success probability (dot) and its 95 % Wilson interval (bar), with k/n."""
    fig, (ax,) = style.new_figure(1, height=0.45 * len(stats) + 1.3, sharex=False,
                                  title="Success probability over the sampled robots")  # fmt: skip
    for i, g in enumerate(stats):
        low, high = g.interval
        colour = COLOURS[i % len(COLOURS)]
        ax.plot([100 * low, 100 * high], [i, i], color=colour, lw=3, solid_capstyle="butt")
        ax.plot(100 * g.probability, i, "o", color=colour, markersize=7, markeredgecolor="white")
        ax.annotate(
            f"{g.successes}/{g.episodes}: {100 * g.probability:.1f} % [{100 * low:.1f}, {100 * high:.1f}]",
            (100 * low, i),
            textcoords="offset points",
            xytext=(0, 6),
            fontsize=8,
        )  # above, inside the axes
    ax.set_yticks(range(len(stats)), [g.label for g in stats])
    ax.set_ylim(-0.7, len(stats) - 0.3)
    ax.invert_yaxis()
    lowest = min(100 * g.interval[0] for g in stats)
    ax.set_xlim(max(0.0, math.floor(lowest / 10) * 10 - 10), 101)
    ax.set_xlabel(f"success probability (%): {SUCCESS_RULE}; bars: 95 % Wilson interval")
    return fig


def distributions(stats: list[GroupStats]) -> Figure:
    """Empirical CDFs (share of episodes at or below x) of each METRICS column, one line per gain set;
    a failed episode's landing error lies beyond the axis, so that curve ends below 100 %."""
    fig = style.plt.figure(figsize=(style.WIDTH, 5.4))
    fig.suptitle("Distributions over the sampled robots (empirical CDF)", fontsize=11)
    axes = fig.subplots(2, 2)
    for ax, (column, (label, unit)) in zip(axes.flat, METRICS.items(), strict=True):
        ax.grid(True, **style.GRID)
        for i, g in enumerate(stats):
            values = np.sort(g.values[column])
            finite = values[np.isfinite(values)]
            share = 100.0 * np.arange(1, finite.size + 1) / values.size
            ax.step(finite, share, where="post", color=COLOURS[i % len(COLOURS)], label=g.label)
        if column == "worst_landing_deg":
            ax.axvline(LANDING_LIMIT_DEG, color=style.LIMIT, lw=1, ls="--", label=f"{LANDING_LIMIT_DEG:g} deg")
            ax.set_xlabel("worst landing error of an episode (deg); failed episodes beyond the axis")
        else:
            ax.set_xlabel(f"{label} ({unit})" + (" of the episode, at most" if column != "energy_j_per_hop" else
                                                 ", the episode's mean"))  # fmt: skip
        ax.set_ylabel("episodes at or below (%)")
        ax.set_ylim(0, 102)
    style.legend_above(axes.flat[0])
    return fig


def against_parameters(episodes: pa.Table, stats: list[GroupStats]) -> Figure:
    """The first gain set's worst landing error against each sampled parameter; failed episodes as
    red crosses on the top edge. Which uncertainty the landing is sensitive to shows as a trend."""
    names = [c[len(MODEL_PREFIX) :] for c in episodes.column_names if c.startswith(MODEL_PREFIX)]
    key = stats[0].key
    rows = np.ones(episodes.num_rows, dtype=bool)
    for column, value in key.items():
        rows &= np.array([v == value for v in episodes.column(column).to_pylist()])
    landing, ok = landing_or_inf(episodes)[rows], success(episodes)[rows]
    cols = 4
    nrows = math.ceil(len(names) / cols)
    fig = style.plt.figure(figsize=(style.WIDTH, 1.9 * nrows + 0.8))
    fig.suptitle(f"Worst landing error against each sampled parameter ({stats[0].label})", fontsize=11)
    axes = np.atleast_1d(fig.subplots(nrows, cols, sharey=True, squeeze=False)).ravel()
    finite = landing[np.isfinite(landing)]
    top = max(LANDING_LIMIT_DEG, float(finite.max()) if finite.size else 0.0) * 1.08
    table = params()
    for ax, name in zip(axes, names, strict=False):
        x = episodes.column(MODEL_PREFIX + name).to_numpy(zero_copy_only=False)[rows]
        ax.grid(True, **style.GRID)
        good = np.isfinite(landing)
        ax.plot(x[good & ok], landing[good & ok], ".", color=style.WHEEL_ON, markersize=3)
        ax.plot(x[good & ~ok], landing[good & ~ok], ".", color=FAILED, markersize=5)
        ax.plot(x[~good], np.full((~good).sum(), top), "x", color=FAILED, markersize=5)
        ax.axhline(LANDING_LIMIT_DEG, color=style.LIMIT, lw=0.8, ls="--")
        ax.axvline(table[name].nominal, color="#888888", lw=0.8)  # the datasheet robot's value
        ax.xaxis.set_major_locator(MaxNLocator(4))
        unit = table[name].unit
        ax.set_xlabel(f"{name} ({unit})" if unit else name, fontsize=8)
        ax.tick_params(labelsize=7)
        ax.set_ylim(0, top * 1.04)
    for ax in axes[len(names) :]:
        ax.set_visible(False)
    for ax in axes[::cols]:
        ax.set_ylabel("landing (deg)", fontsize=8)
    return fig


def table(stats: list[GroupStats]) -> page.Section:
    qs = "/".join(f"p{round(100 * q)}" for q in QUANTILES)
    header = ["gain set", "episodes", "success", "success (%)", "95 % Wilson (%)",
              *(f"{label} {qs} ({unit})" for label, unit in METRICS.values())]  # fmt: skip
    rows = []
    for g in stats:
        low, high = g.interval
        figures = [" / ".join("failed" if math.isinf(v) else f"{v:.3g}" for v in g.quantiles[m]) for m in METRICS]
        rows.append([g.label, g.episodes, g.successes, 100 * g.probability, f"{100 * low:.1f} - {100 * high:.1f}",
                     *figures])  # fmt: skip
    note = (f"Success: {SUCCESS_RULE}. "
            "Quantiles over episodes (one robot each); a failed episode's landing error counts as beyond any bound "
            "('failed').")  # fmt: skip
    return page.Section("Monte Carlo over the sampled robots", header=header, rows=rows, note=note)


def figures(episodes: pa.Table) -> tuple[list[Named], page.Section]:
    """The Monte Carlo figures and table of a sweep's episodes (it has a `sample` column)."""
    stats = group_stats(episodes)
    n = stats[0].episodes
    named = [
        Named("mc_success", "Success probability", f"Share of successful episodes per gain set over its {n} sampled "
              "robots, with the 95 % Wilson score interval.", success_probability(stats)),
        Named("mc_distributions", "Distributions over the sampled robots",
              "Empirical CDFs of each episode's worst landing error, peak mid-air pitch, mean electrical energy per "
              "hop (wheel and legs, braking not recovered) and peak wheel momentum a flight used (% of capacity).",
              distributions(stats)),
        Named("mc_parameters", "Landing error against each sampled parameter",
              "One dot per robot of the first gain set; red: failed (crosses on the top edge: fell, hops short or a "
              "controller fault). "
              "Dashed: 3.5 deg; grey: the nominal robot's value.", against_parameters(episodes, stats)),
    ]  # fmt: skip
    return named, table(stats)
