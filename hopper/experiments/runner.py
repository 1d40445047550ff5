"""Run a sweep: skip the done episodes, stream the rest through an executor into the store."""

from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Callable
from pathlib import Path

from hopper.experiments.executor import Executor, chunks
from hopper.experiments.spec import Episode, SweepSpec
from hopper.experiments.store import SweepStore
from hopper.interrupts import clear


@dataclasses.dataclass(frozen=True)
class SweepRun:
    total: int  # episodes in the spec
    skipped: int  # already done by an earlier run
    ran: int  # done by this run
    wall_s: float  # this run's, start-up and shut-down included
    startup_s: float  # the executor's start-up (Ray's: ray.init and the actors)
    work_s: float  # from the executor ready to the last result written
    executor: str
    workers: int


def pending(spec: SweepSpec, done: set[str]) -> list[Episode]:
    return [e for e in spec.episodes() if e.episode_id not in done]


def run_sweep(
    spec: SweepSpec,
    out: Path,
    make_executor: Callable[[list[Episode]], Executor],
    progress: bool = True,
    announce: Callable[[str], None] = lambda line: print(line, file=sys.stderr),
) -> SweepRun:
    """Run what OUT does not hold yet. OUT is created once the executor has started; results are
    written as they come, and on the way out too: an interrupted run (KeyboardInterrupt propagates)
    keeps every episode it finished. A stop that comes once every episode is written (as the executor
    ends or closes) interrupts nothing: the run returns, complete."""
    from tqdm import tqdm

    start = time.perf_counter()
    store = SweepStore(out, spec)
    done = store.check()
    todo = pending(spec, done)
    skipped = spec.size - len(todo)
    if skipped:
        announce(f"{out}: {skipped} of {spec.size} episodes already done, {len(todo)} to run")
    if not todo:
        return SweepRun(spec.size, skipped, 0, time.perf_counter() - start, 0.0, 0.0, "none", 0)
    # The executor first: one that cannot start (Ray's ray.init or its actors) leaves OUT as it was,
    # not a new sweep folder without episodes that the next command would resume.
    executor = make_executor(todo)
    try:
        store.create()
    except BaseException:
        executor.close()
        raise
    ready = time.perf_counter()
    startup = getattr(executor, "startup_s", 0.0)
    why = getattr(executor, "why", "")  # InProcess's: why not the workers asked for
    announce(
        f"running {len(todo)} episode{'s' if len(todo) != 1 else ''} on {executor.name} ({workers(executor.workers)})"
        + (f": {why}" if why else "")
    )
    bar = tqdm(total=spec.size, initial=skipped, desc="episodes", unit="ep", file=sys.stderr, disable=not progress)
    ran, finished = 0, ready
    try:
        try:
            for results in executor.map(chunks(todo, executor.workers)):
                store.add(results)
                ran += len(results)
                bar.update(len(results))
        finally:  # Ctrl-C included: what finished is kept
            try:
                store.flush()
                finished = time.perf_counter()
                bar.close()
            finally:
                executor.close()
    except KeyboardInterrupt:
        if store.written < len(todo):
            raise
        # The stop came once every episode was written (as the executor ended or closed): it cut nothing
        # short, and a rerun would find nothing to do. The sweep is complete and ends as one.
        clear()
        announce(late_stop(out))
    wall = time.perf_counter() - start
    return SweepRun(spec.size, skipped, ran, wall, startup, finished - ready, executor.name, executor.workers)


def late_stop(out: Path) -> str:
    """What a stop signal that came after the sweep in OUT had written every episode did: nothing."""
    return f"{out}: the stop came after every episode was written: the sweep is complete"


def workers(n: int) -> str:
    """'1 worker', '2 workers'."""
    return f"{n} worker" + ("s" if n != 1 else "")
