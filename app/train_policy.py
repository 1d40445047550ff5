"""Train the policy's weights with CMA-ES on the FlightAttitude env, with domain randomisation.

    pip install -e ".[rl]"
    python -m hopper.app.train_policy --seed 0 --out hopper/laws/policy_weights.json

The search starts at the paper's PD (kp 450 N m/rad, kd 30 N m s/rad) on the policy's linear skip
path. Each generation flies every candidate on the same fresh episodes (common random numbers;
`--fixed` keeps one set for the whole run, a deterministic objective):
gravity log-uniform in 0.2-10 m/s^2, crater terrain seeds 10,000-19,999 (the league's and the
acceptance runs' seeds are below), ideal and realistic sensing, random pitch kicks, and a robot
randomised by hopper.mismatch factors and the gyro's bias. Held-out validation episodes judge the
start and the result. Seeded: one seed, the same weights (whatever --workers).
"""

from __future__ import annotations

import argparse
import multiprocessing
import sys
import time
from pathlib import Path

import numpy as np

from hopper.gym_env import FlightAttitudeEnv
from hopper.laws.policy import Weights

EPISODE = {"gravity": (0.2, 10.0), "flights": 2, "kick_probability": 0.5, "randomise": True}
_ENV: FlightAttitudeEnv | None = None


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


def fitness(job: tuple[np.ndarray, int, list[int]]) -> float:
    """Minus the mean return of flat parameters over the episode seeds (CMA-ES minimises)."""
    theta, hidden, seeds = job
    w = Weights.unflat(theta, hidden)
    return -float(np.mean([episode_return(w, s, ("ideal", "realistic")[i % 2]) for i, s in enumerate(seeds)]))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m hopper.app.train_policy", description=__doc__.splitlines()[0])
    p.add_argument("--seed", type=int, default=0, help="seeds CMA-ES and the episodes")
    p.add_argument("--out", type=Path, default=Path("policy_weights.json"), help="weights file to write")
    p.add_argument("--generations", type=int, default=40)
    p.add_argument("--episodes", type=int, default=8, help="training episodes per candidate per generation")
    p.add_argument("--fixed", action="store_true", help="the same training episodes every generation")
    p.add_argument("--popsize", type=int, default=12)
    p.add_argument("--sigma", type=float, default=0.05, help="CMA-ES initial step (parameters are O(1))")
    p.add_argument("--hidden", type=int, default=16)
    p.add_argument("--workers", type=int, default=1, help="processes evaluating candidates")
    args = p.parse_args(argv)
    try:
        import cma
    except ImportError:
        print("train_policy: needs cma: pip install 'hopper-dashboard[rl]'", file=sys.stderr)
        return 2
    start = time.perf_counter()
    x0 = Weights.pd(450.0, 30.0, args.hidden, seed=args.seed).flat()
    es = cma.CMAEvolutionStrategy(x0, args.sigma, {"seed": args.seed + 1, "popsize": args.popsize, "verbose": -9})
    rng = np.random.default_rng(args.seed)
    validation = [int(s) for s in rng.integers(1 << 30, 1 << 31, 16)]
    seeds = [int(s) for s in rng.integers(0, 1 << 30, args.episodes)] if args.fixed else []
    pool = multiprocessing.get_context("spawn").Pool(args.workers) if args.workers > 1 else None
    run = pool.map if pool else lambda f, jobs: list(map(f, jobs))
    pd_score = fitness((x0, args.hidden, validation))
    print(f"PD start: validation return {-pd_score:.3f}", flush=True)
    for gen in range(args.generations):
        if not args.fixed:
            seeds = [int(s) for s in rng.integers(0, 1 << 30, args.episodes)]
        candidates = es.ask()
        scores = run(fitness, [(np.asarray(c), args.hidden, seeds) for c in candidates])
        es.tell(candidates, scores)
        print(f"gen {gen + 1:3d}  best {-min(scores):8.3f}  mean {-np.mean(scores):8.3f}  "
              f"sigma {es.sigma:.4f}  {time.perf_counter() - start:6.0f} s", flush=True)  # fmt: skip
    final = np.asarray(es.mean)
    if args.fixed and es.result.fbest < fitness((final, args.hidden, seeds)):
        final = np.asarray(es.result.xbest)  # the best candidate flown beats the search's mean
    score = fitness((final, args.hidden, validation))
    if pool:
        pool.close()
    elapsed = time.perf_counter() - start
    print(f"trained: validation return {-score:.3f} (PD start {-pd_score:.3f}), {elapsed:.0f} s", flush=True)
    meta = {"seed": args.seed, "generations": args.generations, "episodes": args.episodes, "popsize": args.popsize,
            "sigma": args.sigma, "fixed": args.fixed, "train_s": round(elapsed, 1), "validation_return": -score,
            "pd_validation_return": -pd_score, "episode": {k: v for k, v in EPISODE.items()}}  # fmt: skip
    Weights.unflat(final, args.hidden).save(args.out, meta)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
