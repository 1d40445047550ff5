"""`hopper-sim tune --robust`: a candidate's score over sampled robots is a quantile, not a worst case.

Objectives (lower is better):
  landing  the Q-quantile of the episodes' worst landing error, a failed episode (fall, hops short,
           controller fault) counting as FAILED_LANDING_DEG: "Q of the robots land within x deg";
  failure  the failure probability (success as hopper.experiments.montecarlo defines it), ties
           broken by the landing quantile (capped at 3.5 deg, weighted below one failure).
With an energy weight of W J/hop, the same quantile of the energy per hop joins the landing figure,
W J/hop counting as much as 3.5 deg (as in the worst-case score): the D term on a noisy gyro costs
energy that a landing quantile alone never sees.
"""

from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np
import pyarrow as pa

from hopper.experiments.montecarlo import QUANTILES, landing_or_inf, percent, success, wilson
from hopper.experiments.montecarlo import quantile as quantile_of
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
    energy_quantile_j: float = 0.0  # J/hop, at `quantile`
    energy_weight: float = 0.0  # J/hop that count as much as a 3.5 deg landing error; 0: energy does not count

    @property
    def landing_figure(self) -> float:
        """The landing quantile (deg), plus the energy's in degrees at the exchange rate of the weight."""
        energy = LANDING_LIMIT_DEG * self.energy_quantile_j / self.energy_weight if self.energy_weight > 0 else 0.0
        return self.landing_quantile_deg + energy

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
            return self.landing_figure
        tie = min(self.landing_figure, LANDING_LIMIT_DEG) / LANDING_LIMIT_DEG / (self.episodes + 1)
        return self.failures / self.episodes + tie


def robust_score(
    results: list[EpisodeResult], objective: Objective, quantile: float, energy_weight: float = 0.0
) -> RobustScore:
    table = pa.Table.from_pylist([r.row() for r in results])
    ok, landing = success(table), landing_or_inf(table)

    def quantiles(values: np.ndarray) -> tuple[float, ...]:
        return tuple(quantile_of(values, q) for q in QUANTILES)

    column = {name: table.column(name).to_numpy(zero_copy_only=False).astype(float)
              for name in ("peak_pitch_deg", "energy_j_per_hop", "momentum_used_pct")}  # fmt: skip
    fault = np.array([bool(r.controller_fault) for r in results])
    capped = np.where(np.isfinite(landing) & ~fault, landing, FAILED_LANDING_DEG)  # a badly landed robot keeps its
    return RobustScore(
        objective=objective, quantile=quantile, episodes=len(results), successes=int(ok.sum()),
        landing_quantile_deg=quantile_of(capped, quantile), landing_deg=quantiles(landing),
        peak_pitch_deg=quantiles(column["peak_pitch_deg"]), energy_j_per_hop=quantiles(column["energy_j_per_hop"]),
        momentum_used_pct=quantiles(column["momentum_used_pct"]),
        energy_quantile_j=quantile_of(column["energy_j_per_hop"], quantile), energy_weight=energy_weight,
    )  # fmt: skip


def describe(objective: Objective, quantile: float, energy_weight: float = 0.0) -> str:
    energy = (f" + {LANDING_LIMIT_DEG:g} deg x its {100 * quantile:g}th percentile energy per hop / {energy_weight:g} J"
              if energy_weight > 0 else " (energy not counted)")  # fmt: skip
    if objective == "landing":
        return (f"score = the {100 * quantile:g}th percentile of the worst landing error over the robots (deg; a fall, "
                f"missing hops or a controller fault count as {FAILED_LANDING_DEG:g} deg){energy}")  # fmt: skip
    return (f"score = failure probability (success: all hops, no fall, landings within {LANDING_LIMIT_DEG:g} deg), "
            f"ties broken by the {100 * quantile:g}th percentile landing error{energy}")  # fmt: skip


def score_line(label: str, s: RobustScore) -> str:
    low, high = s.interval

    def q(values: tuple[float, ...]) -> str:
        return "/".join("failed" if v == float("inf") else f"{v:.3g}" for v in values)

    return (
        f"{label:22}{f'{s.successes}/{s.episodes}':>9} {100 * s.successes / s.episodes:6.1f} % "
        f"[{percent(low):>5s}, {percent(high):>5s}]  landing {q(s.landing_deg)} deg, peak {q(s.peak_pitch_deg)} deg, "
        f"{q(s.energy_j_per_hop)} J/hop, momentum {q(s.momentum_used_pct)} %; score {s.value:.4g}"
    )
