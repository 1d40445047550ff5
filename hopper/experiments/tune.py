"""Gain search: Optuna's seeded TPE sampler over Kp/Ki/Kd, or any controller's declared params (and
gait fields), for the best worst case.

A candidate's score is its worst case over every tuning seed and gravity: failures (a fall, or
fewer hops than asked) dominate, then the worst landing error against the paper's 3.5 deg, then
the most wheel momentum a flight used against the capacity (what the gains use; the stance's is
left out), and, given an energy weight of W J/hop, the most electrical energy an episode spent per
hop (wheel and legs, hopper.control.energy) against W, so that W J/hop count as much as a 3.5 deg
landing error (the paper's energy-optimal future work, at an exchange rate of the user's). The
defaults are the first candidate, so the best is never worse than them on the tuning set; the
held-out seeds say whether that generalises.
Candidates are evaluated in batches through an executor (hopper.experiments.executor).
With a model (`--robust`), every candidate flies sampled robots and is scored by a quantile over
them (hopper.experiments.robust); the best and the defaults are then judged on robots drawn anew.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import math
import sys
from collections.abc import Callable
from typing import Any

from hopper.config import GAIN_RANGES, Gains, GaitParams, InvalidConfig
from hopper.controllers import Param
from hopper.controllers.loading import declared_params, load_class
from hopper.experiments.executor import Executor, chunks
from hopper.experiments.robust import OBJECTIVES, Objective, RobustScore, describe, robust_score, score_line
from hopper.experiments.spec import GAIT_FIELDS, Episode
from hopper.experiments.stress import LANDING_LIMIT_DEG
from hopper.experiments.uncertainty import ModelAxis, Sample
from hopper.experiments.worker import EpisodeResult, energy_per_hop

# Search ranges (low, high, log scale): a decade around PHYSICS.md's LQR range (kp 340 to 850,
# kd 17 to 31) and the defaults; ki only trims model error in flight.
GAIN_SEARCH: dict[str, tuple[float, float, bool]] = {
    "kp": (100.0, 1500.0, True),  # N m/rad
    "ki": (0.0, 200.0, False),  # N m/(rad s)
    "kd": (5.0, 80.0, True),  # N m s/rad
}
FAILURE_WEIGHT = 10.0  # per failed episode: more than any landing or momentum figure can make up
INVALID_SCORE = 1e6  # a candidate the configuration refuses (e.g. a crouch above the stand height)


@dataclasses.dataclass(frozen=True)
class Score:
    """A candidate's worst case over its episodes (lower `value` is better)."""

    episodes: int
    failures: int  # fell, or fewer hops than asked
    worst_landing_deg: float
    worst_momentum_pct: float  # the most wheel momentum a flight used, % of capacity (momentum_used_pct)
    worst_peak_deg: float
    worst_energy_j_per_hop: float = 0.0  # the most any episode spent per hop, J (energy_per_hop)
    energy_weight: float = 0.0  # J/hop that count as much as a 3.5 deg landing error; 0: energy does not count

    @property
    def value(self) -> float:
        energy = self.worst_energy_j_per_hop / self.energy_weight if self.energy_weight > 0 else 0.0
        return (
            FAILURE_WEIGHT * self.failures
            + self.worst_landing_deg / LANDING_LIMIT_DEG
            + self.worst_momentum_pct / 100.0
            + energy
        )


def score(results: list[EpisodeResult], energy_weight: float = 0.0) -> Score:
    rows = [r.row() for r in results]
    return Score(
        episodes=len(rows),
        failures=sum(r["fell"] or r["hops_completed"] < r["hops_target"] or bool(r["controller_fault"]) for r in rows),
        worst_landing_deg=max(r["worst_landing_deg"] for r in rows),
        worst_momentum_pct=max(r["momentum_used_pct"] for r in rows),
        worst_peak_deg=max(r["peak_pitch_deg"] for r in rows),
        worst_energy_j_per_hop=max(energy_per_hop(r) for r in results),
        energy_weight=energy_weight,
    )


@dataclasses.dataclass(frozen=True, kw_only=True)
class TuneSetup:
    seeds: tuple[int, ...]
    heldout: tuple[int, ...]
    gravities: tuple[float, ...]  # m/s^2
    hops: int
    terrain: str = "crater"
    sensing: str = "ideal"
    ranges: dict[str, tuple[float, float, bool]] = dataclasses.field(default_factory=lambda: dict(GAIN_SEARCH))
    trials: int = 40
    batch: int = 0  # candidates per batch; 0: the executor's workers
    seed: int = 0  # the sampler's
    energy_weight: float = 0.0  # J/hop: the worst energy per hop counts in the score in units of this; 0: not at all
    controller: str = "pid"  # whose params are searched (hopper.controllers); the PID's are kp, ki, kd
    # --robust (hopper.experiments.robust): every candidate flies `model`'s robots, is scored by a quantile
    # over them, and the best and the defaults are judged on `judge`'s robots, drawn with another seed.
    model: ModelAxis | None = None
    judge: ModelAxis | None = None
    mjcf: str | None = None  # a user's MJCF of the robot (SimConfig.model, `--model`); None: the packaged one
    objective: Objective = "landing"
    quantile: float = 0.9

    def __post_init__(self) -> None:
        if not (math.isfinite(self.energy_weight) and self.energy_weight >= 0.0):
            raise ValueError(f"the energy weight (--energy-weight) must be a finite number of J/hop >= 0 "
                             f"(0: energy does not count), got {self.energy_weight!r}")  # fmt: skip
        if self.model is not None:
            self._check_robust()
        elif set(self.seeds) & set(self.heldout):
            raise ValueError(f"held-out seeds overlap the tuning seeds: {sorted(set(self.seeds) & set(self.heldout))}")
        declared = self.declared()
        for name in self.ranges:
            if name not in (declared or GAIN_SEARCH) and name not in GAIT_FIELDS:
                what = f"a param of {self.controller}" if declared else "a gain"
                raise ValueError(f"cannot search {name!r}: not {what} nor a GaitParams field")
        for name, (low, high, _) in self.ranges.items():
            self._check_limits(name, low, high, declared)
        defaults = self.defaults()
        for name, (low, high, _) in self.ranges.items():
            if not low <= defaults[name] <= high:
                raise ValueError(f"{name}'s range [{low:g}, {high:g}] leaves out its default {defaults[name]:g}")

    @staticmethod
    def _check_limits(name: str, low: float, high: float, declared: dict[str, Param]) -> None:
        """A gain's or gait field's range within what a run accepts (run --kd 1e30 is refused), so that
        no candidate is scored INVALID_SCORE for its value alone. A gait bound that depends on
        another field (crouch_height below stand_height) is left to the candidates."""
        span = f"{name}'s range [{low:g}, {high:g}]"
        if not declared and name in GAIN_RANGES:
            r = GAIN_RANGES[name]
            if not (math.isfinite(low) and math.isfinite(high) and r.low <= low and high <= r.high):
                raise ValueError(f"{span} goes beyond the gain's limits [{r.low:g}, {r.high:g}] {r.unit}")
        elif name in GAIT_FIELDS:
            for end in (low, high):
                try:
                    GaitParams(**{name: end})
                except InvalidConfig as exc:
                    if str(exc).startswith(f"{name} "):  # this field's own limit, not another's
                        raise ValueError(f"{span} goes beyond its limits: {exc}") from None

    def _check_robust(self) -> None:
        """Fresh robots for the judgement (the terrain seeds may then repeat), a known objective."""
        if self.judge is None or self.judge.seed == self.model.seed:
            raise ValueError("--robust judges on robots drawn with another seed: a --judge-seed unlike --model-seed")
        if self.judge.distributions != self.model.distributions:
            raise ValueError("the judging robots are drawn from the tuning robots' distributions")
        if self.objective not in OBJECTIVES:
            raise ValueError(f"objective {self.objective!r} is not one of {', '.join(OBJECTIVES)}")
        if not 0.0 < self.quantile < 1.0:
            raise ValueError(f"the quantile must be in (0, 1), got {self.quantile!r}")
        if self.model.sensing() and self.sensing != "realistic":
            raise ValueError(
                "the model samples sensing parameters, which act in realistic sensing only: --sensing realistic"
            )

    def robots(self, judging: bool = False) -> list[tuple[int, Sample]]:
        """(index, sample) of the robots a candidate flies: the nominal one alone without --robust."""
        axis = self.judge if judging else self.model
        return [(-1, ())] if axis is None else [(i, axis.sample(i)) for i in range(axis.samples)]

    def score(self, results: list[EpisodeResult]) -> Score | RobustScore:
        if self.model is None:
            return score(results, self.energy_weight)
        return robust_score(results, self.objective, self.quantile, self.energy_weight)

    def declared(self) -> dict[str, Param]:
        """The controller's declared params by name ({} for the PID, whose params are the gains)."""
        if self.controller == "pid":
            return {}
        return {p.name: p for p in declared_params(load_class(self.controller))}

    def defaults(self) -> dict[str, float]:
        gait = dataclasses.asdict(GaitParams())
        declared = self.declared()
        own = {n: p.default for n, p in declared.items()} if declared else dataclasses.asdict(Gains())
        return {name: (own | gait)[name] for name in (*own, *self.ranges)}

    def episodes(self, params: dict[str, float], seeds: tuple[int, ...], judging: bool = False) -> list[Episode]:
        declared = self.declared()
        gains = {k: v if declared else params.get(k, v) for k, v in dataclasses.asdict(Gains()).items()}
        gait = tuple((k, v) for k, v in params.items() if k in GAIT_FIELDS)
        own = tuple((k, v) for k, v in params.items() if k in declared)
        return [
            Episode(
                **gains,
                gravity=g,
                seed=s,
                hops_target=self.hops,
                terrain=self.terrain,
                wheel=True,
                sensing=self.sensing,
                gait=gait,
                controller=self.controller,
                params=own,
                sample=sample,
                model=model,
                mjcf=self.mjcf,
            )  # fmt: skip
            for g in self.gravities
            for s in seeds
            for sample, model in self.robots(judging)
        ]


@dataclasses.dataclass(frozen=True)
class TuneResult:
    best: dict[str, float]
    defaults: dict[str, float]
    best_score: Score | RobustScore  # on the tuning seeds (and robots)
    default_score: Score | RobustScore
    best_heldout: Score | RobustScore  # on the held-out seeds (the judging robots)
    default_heldout: Score | RobustScore
    history: list[tuple[dict[str, float], float]]  # every candidate and its score value, in order

    @property
    def robust(self) -> bool:
        return isinstance(self.best_score, RobustScore)

    def as_dict(self, setup: TuneSetup) -> dict[str, Any]:
        def s(x: Score | RobustScore) -> dict[str, Any]:
            return {**dataclasses.asdict(x), "value": x.value} | ({"interval": x.interval} if self.robust else {})

        return {
            "setup": {**dataclasses.asdict(setup), "ranges": {k: list(v) for k, v in setup.ranges.items()}},
            "best": self.best, "defaults": self.defaults,
            "tuning": {"best": s(self.best_score), "defaults": s(self.default_score)},
            "heldout": {"best": s(self.best_heldout), "defaults": s(self.default_heldout)},
            "history": [{"params": p, "score": v} for p, v in self.history],
        }  # fmt: skip


def evaluate(
    candidates: list[dict[str, float]],
    seeds: tuple[int, ...],
    setup: TuneSetup,
    executor: Executor,
    judging: bool = False,
    bar: Callable[..., Any] | None = None,
) -> list[Score | RobustScore | None]:
    """Each candidate's score over `seeds` x gravities (x robots) (None if its configuration is refused);
    `bar(total=N)` (a tqdm's maker), if given, counts the N episodes as they finish."""
    valid, episodes = {}, []
    for i, params in enumerate(candidates):
        eps = setup.episodes(params, seeds, judging)
        try:
            eps[0].config()
        except InvalidConfig:
            continue
        valid[i] = eps
        episodes += eps
    unique = list({e.episode_id: e for e in episodes}.values())
    # Made once the count is known: a bar made before printed a stray "judging: 0ep" line.
    counter = bar(total=len(unique)) if bar is not None else None
    results: dict[str, EpisodeResult] = {}
    try:
        for chunk_results in executor.map(chunks(unique, executor.workers)):
            results |= {r.episode.episode_id: r for r in chunk_results}
            if counter is not None:
                counter.update(len(chunk_results))
    finally:
        if counter is not None:
            counter.close()
    return [
        setup.score([results[e.episode_id] for e in valid[i]]) if i in valid else None for i in range(len(candidates))
    ]


def tune(setup: TuneSetup, make_executor: Callable[[list[Episode]], Executor], progress: bool = True) -> TuneResult:
    import optuna
    from optuna.distributions import FloatDistribution
    from tqdm import tqdm

    optuna.logging.set_verbosity(logging.WARNING)
    distributions = {name: FloatDistribution(low, high, log=log) for name, (low, high, log) in setup.ranges.items()}
    study = optuna.create_study(direction="minimize", sampler=optuna.samplers.TPESampler(seed=setup.seed))
    defaults = setup.defaults()
    study.enqueue_trial({name: defaults[name] for name in distributions})
    sample = setup.episodes(defaults, setup.seeds) * setup.trials  # sizes the executor
    executor = make_executor(sample + setup.episodes(defaults, setup.heldout, judging=True) * 2)
    batch = setup.batch or executor.workers
    history: list[tuple[dict[str, float], float]] = []
    scores: list[Score | RobustScore | None] = []
    bar = tqdm(total=setup.trials, desc="candidates", unit="cand", file=sys.stderr, disable=not progress)
    try:
        while len(history) < setup.trials:
            trials = [study.ask(distributions) for _ in range(min(batch, setup.trials - len(history)))]
            for trial, result in zip(trials, evaluate([t.params for t in trials], setup.seeds, setup, executor),
                                     strict=True):  # fmt: skip
                value = result.value if result is not None else INVALID_SCORE
                study.tell(trial, value)
                history.append((dict(trial.params), value))
                scores.append(result)
            bar.update(len(trials))
        best_index = min(range(len(history)), key=lambda i: history[i][1])  # the first of equals
        best = {**defaults, **history[best_index][0]}
        bar.close()
        # The judging can be the longest part (--judge-samples 500: 16,000 episodes): it counts too.
        judged = functools.partial(tqdm, desc="judging", unit="ep", file=sys.stderr, disable=not progress)
        default_heldout, best_heldout = evaluate(
            [defaults, best], setup.heldout, setup, executor, judging=True, bar=judged
        )
    finally:
        bar.close()
        executor.close()
    return TuneResult(
        best=best, defaults=defaults, best_score=scores[best_index], default_score=scores[0],
        best_heldout=best_heldout, default_heldout=default_heldout, history=history,
    )  # fmt: skip


def report_lines(setup: TuneSetup, result: TuneResult) -> list[str]:
    """The gains found and the evidence: worst cases of best vs defaults, tuning and held-out seeds."""
    names = list(result.defaults)
    search = ", ".join(f"{n} [{lo:g}, {hi:g}]{' log' if log else ''}" for n, (lo, hi, log) in setup.ranges.items())
    gravities = ", ".join(f"{g:g}" for g in setup.gravities)
    robots = f" x {setup.model.samples} robots (model seed {setup.model.seed})" if setup.model else ""
    lines = [
        f"Optuna TPE (seed {setup.seed}), {setup.trials} candidates over {search}; each: seeds "
        f"{_seeds(setup.seeds)}{robots} x gravity {gravities} m/s^2, {setup.hops} hops, {setup.terrain}, "
        f"{setup.sensing}"
    ]
    lines += _robust_lines(setup, result) if setup.model else _worst_case_lines(setup, result)
    held_out = "on the judging robots" if setup.model else "on the held-out seeds"
    verdict = "at least as good as" if result.best_heldout.value <= result.default_heldout.value else "WORSE than"
    lines.append(
        f"{held_out} the best gains are {verdict} the defaults "
        f"(score {result.best_heldout.value:.4g} vs {result.default_heldout.value:.4g})"
    )
    if setup.controller == "pid":
        lines.append("best: " + " ".join(f"--{n} {result.best[n]:.6g}" for n in names if n in ("kp", "ki", "kd")))
    else:
        declared = setup.declared()
        flags = " ".join(f"--controller-param {n}={result.best[n]:.6g}" for n in names if n in declared)
        lines.append(f"best: --controller {setup.controller} {flags}")
    return lines


def _robust_lines(setup: TuneSetup, result: TuneResult) -> list[str]:
    """Defaults and best over the tuning robots and the judging ones: success with its interval, quantiles."""
    lines = [describe(setup.objective, setup.quantile, setup.energy_weight)]
    lines.append("quantiles p50/p90/p99 over episodes; success [95 % Wilson]")
    for title, seeds, axis, best, default in (
        ("tuning", setup.seeds, setup.model, result.best_score, result.default_score),
        ("judging", setup.heldout, setup.judge, result.best_heldout, result.default_heldout),
    ):
        lines.append(f"{title}: {axis.samples} robots (model seed {axis.seed}) x seeds {_seeds(seeds)}")
        lines += [score_line("  defaults", default), score_line("  best", best)]
    return lines


def _worst_case_lines(setup: TuneSetup, result: TuneResult) -> list[str]:
    names = list(result.defaults)
    lines = [
        f"score = {FAILURE_WEIGHT:g} x failures + worst landing / {LANDING_LIMIT_DEG:g} deg + worst momentum / 100 %"
        + (f" + worst energy / {setup.energy_weight:g} J/hop" if setup.energy_weight > 0 else " (energy not counted)"),
        f"{'':22}"
        + "".join(f"{n:>{max(10, len(n) + 1)}}" for n in names)
        + f"{'failures':>10}{'landing deg':>13}{'momentum %':>12}{'peak deg':>10}{'J/hop':>9}{'score':>8}",
    ]
    for title, seeds, best, default in (
        ("tuning seeds", setup.seeds, result.best_score, result.default_score),
        ("held-out seeds", setup.heldout, result.best_heldout, result.default_heldout),
    ):
        lines.append(f"{title} {_seeds(seeds)}")
        for label, params, s in (("  defaults", result.defaults, default), ("  best", result.best, best)):
            lines.append(
                f"{label:22}" + "".join(f"{params[n]:>{max(10, len(n) + 1)}.4g}" for n in names)
                + f"{f'{s.failures}/{s.episodes}':>10}{s.worst_landing_deg:>13.3f}{s.worst_momentum_pct:>12.1f}"
                + f"{s.worst_peak_deg:>10.2f}{s.worst_energy_j_per_hop:>9.1f}{s.value:>8.3f}"
            )  # fmt: skip
    return lines


def _seeds(seeds: tuple[int, ...]) -> str:
    if len(seeds) > 2 and list(seeds) == list(range(seeds[0], seeds[-1] + 1)):
        return f"{seeds[0]}-{seeds[-1]}"
    return ",".join(map(str, seeds))
