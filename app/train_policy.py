"""Train the policy's weights with CMA-ES on the FlightAttitude env, with domain randomisation.

    pip install -e ".[rl]"
    python -m hopper.app.train_policy --seed 0 --out hopper/laws/policy_weights.json

The search starts at the paper's PID exactly (hopper.config.Gains: kp, kd, ki on the policy's
linear skip path, the hidden layer's output weights zero). Episodes: gravity log-uniform in
0.2-10 m/s^2, crater terrain seeds 10,000-19,999 (the league's and the acceptance runs' seeds are
below), ideal and realistic sensing alternately, random pitch kicks, and a robot randomised by
hopper.mismatch factors and the gyro's bias. Three disjoint sets of episode seeds:
- training: each generation every candidate flies the same fresh episodes (common random numbers);
- validation: a fixed set on which the start and the search's mean every few generations are
  scored; the best of them is kept (the start among them, so the result never scores below it);
- test: a fixed set used once at the end, on the start and the result alike (paired): the
  reported improvement, as validation has been used for selection.
Seeded: one seed, the same weights (whatever --workers).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import multiprocessing
import multiprocessing.pool
import sys
import time
from pathlib import Path
from types import ModuleType

import numpy as np
from hopper.app.cli_common import EXIT_INTERRUPTED, Parser, at_least, finite, seed, writable_file

from hopper.config import Gains
from hopper.controllers.features import NAMES, SIZE
from hopper.gym_env import FlightAttitudeEnv
from hopper.interrupts import children_ignore_ctrl_c, each, stop_like_ctrl_c
from hopper.laws.policy import Weights

EPISODE = {"gravity": (0.2, 10.0), "flights": 2, "kick_probability": 0.5, "randomise": True}
SENSING = ("ideal", "realistic")  # alternately, by an episode's place in its set
# Episode seeds of the three sets: disjoint ranges.
TRAIN_SEEDS, VALIDATION_SEEDS, TEST_SEEDS = (0, 1 << 30), (1 << 30, 1 << 31), (1 << 31, 3 << 30)
_ENV: FlightAttitudeEnv | None = None
PROG = "train_policy"  # its errors' prefix
MAX_TRAINING_SEED = 2**32 - 2  # CMA-ES's seed is --seed + 1, which numpy's legacy generator takes below 2^32


def episode_return(weights: Weights, seed: int, sensing: str) -> float:
    """One episode's return for `weights`, on the episode `seed` draws (sensing as given)."""
    global _ENV
    if _ENV is None:
        _ENV = FlightAttitudeEnv(**EPISODE)
    obs, _ = _ENV.reset(seed=seed, options={"sensing": sensing})
    total, done = 0.0, False
    while not done:
        obs, reward, terminated, truncated, _ = _ENV.step(np.array([weights.act(obs.astype(float))], np.float32))
        total, done = total + reward, terminated or truncated
    return total


def returns(job: tuple[np.ndarray, int, list[int]]) -> list[float]:
    """The returns of flat parameters on each episode seed, in order."""
    theta, hidden, seeds = job
    w = Weights.unflat(theta, hidden)
    return [episode_return(w, s, SENSING[i % 2]) for i, s in enumerate(seeds)]


def fitness(job: tuple[np.ndarray, int, list[int]]) -> float:
    """Minus the mean return (CMA-ES minimises)."""
    return -float(np.mean(returns(job)))


def paired(start: list[float], trained: list[float]) -> dict:
    """Mean returns and the mean paired difference with its 95 % interval (normal, n >= 30)."""
    d = np.asarray(trained) - np.asarray(start)
    half = 1.96 * float(d.std(ddof=1)) / math.sqrt(len(d))
    return {"episodes": len(d), "start": float(np.mean(start)), "trained": float(np.mean(trained)),
            "difference": float(d.mean()), "ci95": [float(d.mean()) - half, float(d.mean()) + half]}  # fmt: skip


def step_scales(hidden: int) -> np.ndarray:
    """CMA-ES's step per parameter, x --sigma, in Weights.flat's order. A torque offset tilts the
    landing by offset / kp (1 N m: 0.13 deg), so what adds one (skip weights of the inputs that are
    not errors, the hidden units' output weights, b2) steps 10 x less than the gains on pitch, rate
    and integral; at the full step a random draw of those cost 0.01-0.9 of return, the gains' 0.01."""
    lin = np.full(SIZE, 0.1)
    lin[[NAMES.index(n) for n in ("pitch", "rate", "pitch_integral")]] = 1.0
    return Weights(np.ones((hidden, SIZE)), np.ones(hidden), np.full(hidden, 0.1), 0.1, lin).flat()


def draw(rng: np.random.Generator, bounds: tuple[int, int], n: int) -> list[int]:
    return [int(s) for s in rng.integers(*bounds, n)]


def training_seed(text: str) -> int:
    """hopper-sim's seed check, and CMA-ES's bound: it seeds numpy's 32-bit legacy generator with seed + 1."""
    value = seed(text)
    if value > MAX_TRAINING_SEED:
        raise argparse.ArgumentTypeError(
            f"must be at most {MAX_TRAINING_SEED} (CMA-ES takes seed + 1 < 2^32), got {value}"
        )
    return value


def positive(text: str) -> float:
    """A finite number above 0."""
    value = finite(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be above 0, got {text}")
    return value


def parser() -> Parser:
    """hopper-sim's parser and number checks (no abbreviated flags, one-line errors, exit 2), checked
    before any training: a bad --out or --every once failed after it."""
    p = Parser(prog="python -m hopper.app.train_policy", description=__doc__.splitlines()[0], name=PROG)
    p.add_argument("--seed", type=training_seed, default=0, help="seeds CMA-ES and the episodes")
    p.add_argument("--out", type=writable_file, default=Path("policy_weights.json"), help="weights file to write")
    p.add_argument("--generations", type=at_least(1), default=20)
    p.add_argument("--episodes", type=at_least(1), default=12, help="training episodes per candidate per generation")
    p.add_argument("--popsize", type=at_least(2), default=12, help="candidates per generation (CMA-ES needs two)")
    p.add_argument("--sigma", type=positive, default=0.05, help="CMA-ES initial step (parameters are O(1))")
    p.add_argument("--hidden", type=at_least(0), default=16, help="hidden units (0: the linear skip path alone)")
    p.add_argument("--validation", type=at_least(1), default=64, help="validation episodes")
    p.add_argument(
        "--every", type=at_least(1), default=4, help="validate the search's mean every this many generations"
    )
    p.add_argument(
        "--test", type=at_least(2), default=150, help="test episodes, flown once by the start and the result (two "
        "at least: the paired difference's interval needs a spread)"
    )  # fmt: skip
    p.add_argument("--workers", type=at_least(1), default=1, help="processes evaluating candidates")
    return p


def main(argv: list[str] | None = None) -> int:
    """0 trained and written, 2 bad arguments or no cma, 130 interrupted (Ctrl-C or SIGTERM: nothing written)."""
    args = parser().parse_args(argv)
    try:
        import cma
    except ImportError:
        print(f"{PROG}: needs cma: pip install 'hopper-dashboard[rl]'", file=sys.stderr)
        return 2
    stop_like_ctrl_c()
    pool = None
    if args.workers > 1:
        with children_ignore_ctrl_c():  # a terminal's Ctrl-C is the main process's to handle
            pool = multiprocessing.get_context("spawn").Pool(args.workers)
    try:
        return train(args, cma, pool)
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        if pool:
            pool.terminate()


def train(args: argparse.Namespace, cma: ModuleType, pool: multiprocessing.pool.Pool | None) -> int:
    """The search, the test and the weights written; `pool` evaluates the candidates if given."""
    start = time.perf_counter()
    gains = Gains()
    x0 = Weights.pid(gains.kp, gains.kd, gains.ki, args.hidden, seed=args.seed).flat()
    options = {"seed": args.seed + 1, "popsize": args.popsize, "CMA_stds": step_scales(args.hidden), "verbose": -9}
    es = cma.CMAEvolutionStrategy(x0, args.sigma, options)
    rng = np.random.default_rng(args.seed)
    validation, test = draw(rng, VALIDATION_SEEDS, args.validation), draw(rng, TEST_SEEDS, args.test)
    run = (lambda f, jobs: list(each(pool.imap(f, jobs)))) if pool else (lambda f, jobs: list(map(f, jobs)))
    best_score, best, best_gen = fitness((x0, args.hidden, validation)), x0, 0
    print(f"PID start: validation return {-best_score:.4f}", flush=True)
    for gen in range(1, args.generations + 1):
        seeds = draw(rng, TRAIN_SEEDS, args.episodes)
        candidates = es.ask()
        scores = run(fitness, [(np.asarray(c), args.hidden, seeds) for c in candidates])
        es.tell(candidates, scores)
        line = f"gen {gen:3d}  best {-min(scores):8.4f}  mean {-np.mean(scores):8.4f}  sigma {es.sigma:.4f}"
        if gen % args.every == 0 or gen == args.generations:
            mean = np.array(es.mean)
            score = fitness((mean, args.hidden, validation))
            line += f"  validation {-score:8.4f}"
            if score < best_score:
                best_score, best, best_gen = score, mean, gen
        print(f"{line}  {time.perf_counter() - start:6.0f} s", flush=True)
    # The test set, once: start and result on the same episodes, one process per side if there are two.
    start_returns, trained_returns = run(returns, [(x0, args.hidden, test), (best, args.hidden, test)])
    judged = paired(start_returns, trained_returns)
    elapsed = time.perf_counter() - start
    lo, hi = judged["ci95"]
    print(f"kept generation {best_gen} (validation {-best_score:.4f}); test on {args.test} episodes: "
          f"start {judged['start']:.4f}, trained {judged['trained']:.4f}, paired difference "
          f"{judged['difference']:+.4f} (95 % {lo:+.4f} to {hi:+.4f}); {elapsed:.0f} s", flush=True)  # fmt: skip
    meta = {"seed": args.seed, "generations": args.generations, "episodes": args.episodes, "popsize": args.popsize,
            "sigma": args.sigma, "validation": args.validation, "every": args.every, "kept_generation": best_gen,
            "validation_return": -best_score, "test": judged, "start": {"pid": dataclasses.asdict(gains)},
            "train_s": round(elapsed, 1), "episode": dict(EPISODE)}  # fmt: skip
    Weights.unflat(best, args.hidden).save(args.out, meta)
    print(f"wrote {args.out}; fly it: hopper-sim run --controller policy:{args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
