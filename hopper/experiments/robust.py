"""`hopper-sim tune --robust`: a candidate's score over sampled robots is a quantile, not a worst case.

Objectives (lower is better):
  landing  the Q-quantile of the episodes' worst landing error, a failed episode (fall, hops short,
           controller fault) counting as FAILED_LANDING_DEG: "Q of the robots land within x deg";
  failure  the failure probability (success as hopper.experiments.montecarlo defines it), ties
           broken by the landing quantile (capped at 3.5 deg, weighted below one failure).
"""

from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np
import pyarrow as pa

from hopper.experiments.montecarlo import QUANTILES, landing_or_inf, success, wilson
from hopper.experiments.stress import LANDING_LIMIT_DEG
from hopper.experiments.worker import EpisodeResult

Objective = Literal["landing", "failure"]
OBJECTIVES: tuple[Objective, ...] = ("landing", "failure")
FAILED_LANDING_DEG = 90.0  # a failed episode's landing error in the landing quantile: the torso on its side


@dataclasses.dataclass(frozen=True)
class RobustScore:
    """A candidate over its sampled robots: the objective's value and the figures a report shows."""

    objective: Objective
    quantile: float
    episodes: int
    successes: int
    landing_quantile_deg: float  # at `quantile`, failures as FAILED_LANDING_DEG
    landing_deg: tuple[float, ...]  # at montecarlo.QUANTILES, failures as inf
    peak_pitch_deg: tuple[float, ...]
    energy_j_per_hop: tuple[float, ...]
    momentum_used_pct: tuple[float, ...]

    @property
    def failures(self) -> int:
        return self.episodes - self.successes

    @property
    def interval(self) -> tuple[float, float]:
        """95 % Wilson interval of the success probability."""
        return wilson(self.successes, self.episodes)

    @property
    def value(self) -> float:
        if self.objective == "landing":
            return self.landing_quantile_deg
        tie = min(self.landing_quantile_deg, LANDING_LIMIT_DEG) / LANDING_LIMIT_DEG / (self.episodes + 1)
        return self.failures / self.episodes + tie


def robust_score(results: list[EpisodeResult], objective: Objective, quantile: float) -> RobustScore:
    table = pa.Table.from_pylist([r.row() for r in results])
    ok, landing = success(table), landing_or_inf(table)

    def quantiles(values: np.ndarray) -> tuple[float, ...]:
        return tuple(float(np.quantile(values, q)) for q in QUANTILES)

    column = {name: table.column(name).to_numpy(zero_copy_only=False).astype(float)
              for name in ("peak_pitch_deg", "energy_j_per_hop", "momentum_used_pct")}  # fmt: skip
    fault = np.array([bool(r.controller_fault) for r in results])
    capped = np.where(np.isfinite(landing) & ~fault, landing, FAILED_LANDING_DEG)  # a badly landed robot keeps its
    return RobustScore(
        objective=objective, quantile=quantile, episodes=len(results), successes=int(ok.sum()),
        landing_quantile_deg=float(np.quantile(capped, quantile)), landing_deg=quantiles(landing),
        peak_pitch_deg=quantiles(column["peak_pitch_deg"]), energy_j_per_hop=quantiles(column["energy_j_per_hop"]),
        momentum_used_pct=quantiles(column["momentum_used_pct"]),
    )  # fmt: skip


def describe(objective: Objective, quantile: float) -> str:
    if objective == "landing":
        return (f"score = the {100 * quantile:g}th percentile of the worst landing error over the robots (deg; a fall, "
                f"missing hops or a controller fault count as {FAILED_LANDING_DEG:g} deg)")  # fmt: skip
    return (f"score = failure probability (success: all hops, no fall, landings within {LANDING_LIMIT_DEG:g} deg), "
            f"ties broken by the {100 * quantile:g}th percentile landing error")  # fmt: skip


def score_line(label: str, s: RobustScore) -> str:
    low, high = s.interval

    def q(values: tuple[float, ...]) -> str:
        return "/".join("fell" if v == float("inf") else f"{v:.3g}" for v in values)

    return (
        f"{label:22}{f'{s.successes}/{s.episodes}':>9} {100 * s.successes / s.episodes:6.1f} % "
        f"[{100 * low:5.1f}, {100 * high:5.1f}]  landing {q(s.landing_deg)} deg, peak {q(s.peak_pitch_deg)} deg, "
        f"{q(s.energy_j_per_hop)} J/hop, momentum {q(s.momentum_used_pct)} %; score {s.value:.4g}"
    )
