"""Monte Carlo statistics of a sweep over sampled robots: success with its Wilson interval and the
quantiles of landing error, peak pitch, energy and momentum, per gain set or controller.

Success (an episode's): every hop it was asked for completed, no fall, no controller fault, and every
landing within LANDING_LIMIT_DEG, the paper's 3.5 deg. A failed episode's landing error counts as
beyond every bound (inf), so the landing quantiles are those of "lands within x deg".
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pyarrow as pa

from hopper.experiments.outcome import column, failed, success
from hopper.experiments.stress import LANDING_LIMIT_DEG
from hopper.experiments.uncertainty import MODEL_PREFIX

Z_95 = 1.959963984540054  # standard normal quantile of 0.975: a two-sided 95 % interval
QUANTILES = (0.5, 0.9, 0.99)
METRICS = {  # column: (label, unit)
    "worst_landing_deg": ("landing error", "deg"),
    "peak_pitch_deg": ("peak pitch", "deg"),
    "energy_j_per_hop": ("energy per hop", "J"),
    "momentum_used_pct": ("momentum used in flight", "%"),
}
# Columns that tell one robot or terrain of the same gain set from another, never a group.
NOT_GROUPS = ("episode_id", "seed", "sample", "disturbance_size")


def wilson(successes: int, n: int, z: float = Z_95) -> tuple[float, float]:
    """The Wilson score interval of a binomial proportion (Wilson 1927), (low, high) in [0, 1]."""
    if n <= 0:
        return 0.0, 1.0
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    low, high = max(0.0, centre - half), min(1.0, centre + half)
    return (0.0 if successes == 0 else low), (1.0 if successes == n else high)  # exact at the ends, not 1 - 1e-16


def percent(p: float) -> str:
    """A probability in % to one decimal, or to as many (up to 3) as keep a value short of 0 or 100 %
    from printing as one: 8000 successes of 8000 have a lower bound of 99.95 %, not 100.0."""
    for digits in (1, 2, 3):
        text = f"{100 * p:.{digits}f}"
        if 0.0 < p < 1.0 and float(text) in (0.0, 100.0):
            continue
        return text
    return text


def quantile(values: np.ndarray, q: float) -> float:
    """The empirical quantile: the smallest value with at least a share q of the values at or below it (the
    ECDF's inverse, as the report draws it; no interpolation, so a failure's inf stays inf, never nan)."""
    return float(np.quantile(values, q, method="inverted_cdf"))


def landing_or_inf(table: pa.Table) -> np.ndarray:
    """Each episode's worst landing error (deg), inf where it failed (short of its hops, a fall or a
    controller fault: hopper.experiments.outcome.failed)."""
    return np.where(failed(table), np.inf, column(table, "worst_landing_deg").astype(float))


def group_columns(table: pa.Table) -> list[str]:
    """The setting columns that vary, but for the robot, its terrain and what it is sampled from."""
    settings = table.column_names[: table.column_names.index("hops_completed")]
    keep = [c for c in settings if c not in NOT_GROUPS and not c.startswith(MODEL_PREFIX)]
    return [c for c in keep if len(set(column(table, c).tolist())) > 1]


@dataclasses.dataclass(frozen=True)
class GroupStats:
    """One gain set's (or controller's) figures over its sampled robots."""

    label: str
    key: dict[str, Any]
    episodes: int
    successes: int
    interval: tuple[float, float]  # 95 % Wilson, of the success probability
    quantiles: dict[str, tuple[float, ...]]  # METRICS column -> values at QUANTILES
    values: dict[str, np.ndarray]  # METRICS column -> every episode's (the landing's inf where it failed)

    @property
    def probability(self) -> float:
        return self.successes / self.episodes if self.episodes else 0.0


def _label(table: pa.Table, rows: np.ndarray, columns: list[str]) -> str:
    first = int(np.flatnonzero(rows)[0])
    controller = str(column(table, "controller")[first]) if "controller" in table.column_names else "pid"
    parts = [controller]
    if controller == "pid":
        parts += [f"{g} {column(table, g)[first]:g}" for g in ("kp", "ki", "kd")]
    for c in columns:
        if c not in ("controller", "kp", "ki", "kd"):
            v = column(table, c)[first]
            parts.append(f"{c} {v:g}" if isinstance(v, float) else f"{c} {v}")
    return " ".join(parts)


def group_stats(table: pa.Table) -> list[GroupStats]:
    """Per group of varied settings (gains, controller, ...), in the table's order of first appearance."""
    columns = group_columns(table)
    keys = list(zip(*(column(table, c).tolist() for c in columns), strict=True)) if columns else [()] * len(table)
    ok, landing = success(table), landing_or_inf(table)
    out = []
    for key in dict.fromkeys(keys):
        rows = np.array([k == key for k in keys], dtype=bool)
        values = {m: (landing if m == "worst_landing_deg" else column(table, m).astype(float))[rows] for m in METRICS}
        quantiles = {m: tuple(quantile(v, q) for q in QUANTILES) for m, v in values.items()}
        k, n = int(ok[rows].sum()), int(rows.sum())
        out.append(GroupStats(_label(table, rows, columns), dict(zip(columns, key, strict=True)), n, k,
                              wilson(k, n), quantiles, values))  # fmt: skip
    return out


def _number(x: float) -> str:
    return "failed" if math.isinf(x) else f"{x:.3g}"


def summary_lines(table: pa.Table, samples: int, seed: int) -> list[str]:
    """What `hopper-sim sweep` prints for a sweep over sampled robots."""
    qs = "/".join(f"p{round(100 * q)}" for q in QUANTILES)
    lines = [
        f"model uncertainty: {samples} robots drawn (seed {seed}); success = all hops, no fall, no controller fault, "
        f"every landing within {LANDING_LIMIT_DEG:g} deg; 95 % Wilson intervals; quantiles {qs} over episodes"
    ]
    for g in group_stats(table):
        low, high = g.interval
        lines.append(f"{g.label}: success {g.successes}/{g.episodes} = {100 * g.probability:.1f} % "
                     f"[{percent(low)}, {percent(high)}] %")  # fmt: skip
        for m, (label, unit) in METRICS.items():
            lines.append(f"  {label} ({unit}) {qs}: " + " / ".join(map(_number, g.quantiles[m])))
    return lines
