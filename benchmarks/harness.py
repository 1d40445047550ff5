"""Shared parts of the benchmarks: interleaved ratios; for the load and soak runs, headless clients in
child processes, error capture, RTF windows.

Clients run in child processes (browsers are separate processes too), a thread per client slot,
each speaking viser's real protocol through hopper.app.dashboard.probe.ProbeClient. A slot that stays keeps
one connection for the whole run; the others connect, stay a random while and leave, again and
again. Each child prints one JSON line: every session with its scene updates per second.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import random
import statistics
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TextIO

ROOT = Path(__file__).resolve().parent.parent
CHURN_STAY_S = (2.0, 20.0)  # s a leaving client stays connected, drawn uniformly
CHURN_GAP_S = (0.5, 5.0)  # s before it connects again
MEASURE_AFTER_S = 1.0  # s after a session's first pose before its rate is measured (the initial scene)


# -- ratios on a noisy machine (STYLE.md item 30) --------------------------------------------------
MIN_ROUNDS = 5


@dataclasses.dataclass(frozen=True)
class Ratio:
    """A ratio measured once per round, each round's two sides taken one right after the other."""

    rounds: tuple[float, ...]

    @property
    def median(self) -> float:
        return statistics.median(self.rounds)

    @property
    def low(self) -> float:
        return min(self.rounds)

    @property
    def high(self) -> float:
        return max(self.rounds)

    def __str__(self) -> str:
        return f"{self.median:.3f} median ({self.low:.3f}-{self.high:.3f} over {len(self.rounds)} rounds)"


def interleaved(sides: dict[str, Callable[[], float]], rounds: int) -> dict[str, list[float]]:
    """Each side's figure (a rate, say) once per round, the sides in turn: ABAB... `rounds` (>= MIN_ROUNDS)
    times. The machine's load moves over seconds: sides measured apart in time are not comparable."""
    if rounds < MIN_ROUNDS:
        raise SystemExit(f"--rounds must be at least {MIN_ROUNDS}: a median of fewer says little, got {rounds}")
    figures: dict[str, list[float]] = {name: [] for name in sides}
    for _ in range(rounds):
        for name, measure in sides.items():
            figures[name].append(measure())
    return figures


def ratio(top: list[float], bottom: list[float]) -> Ratio:
    """Round by round top / bottom (lists from interleaved())."""
    return Ratio(tuple(a / b for a, b in zip(top, bottom, strict=True)))


def spread(values: list[float], digits: int = 0) -> str:
    """A figure's median and range: '41,200 (35,100-44,900)'."""
    f = f",.{digits}f"
    return f"{statistics.median(values):{f}} ({min(values):{f}}-{max(values):{f}})"


# -- the child: client slots ---------------------------------------------------------------------
def _slot(url: str, index: int, stay: bool, seed: int, start: float, settle: float, end: float) -> dict:
    """One client slot until `end` (time.monotonic()): its sessions and errors."""
    from hopper.app.dashboard.probe import ProbeClient

    rng = random.Random(seed * 1000 + index)
    sessions: list[dict[str, Any]] = []
    errors: list[str] = []
    if not stay:
        time.sleep(rng.uniform(0.0, CHURN_GAP_S[1]))  # spread the first connections
    while time.monotonic() < end - 1.0:
        try:
            client = ProbeClient(url)
        except Exception as exc:
            errors.append(f"slot {index}: connect failed: {type(exc).__name__}: {exc}")
            time.sleep(1.0)
            continue
        try:
            if not client.wait_for(lambda p: p.pose_frames > 0, timeout=30):
                errors.append(f"slot {index}: no pose within 30 s of connecting")
                continue
            first_pose = time.monotonic()
            leave = end if stay else min(end, first_pose + rng.uniform(*CHURN_STAY_S))
            begin = max(first_pose + MEASURE_AFTER_S, start + settle if stay else 0.0)
            time.sleep(max(0.0, begin - time.monotonic()))
            _, _, poses0 = client.snapshot()
            t0 = time.monotonic()
            time.sleep(max(0.0, leave - t0))
            _, _, poses1 = client.snapshot()
            t1 = time.monotonic()
            if client.closed:
                errors.append(f"slot {index}: the server closed the connection")
            if t1 - t0 > 1.0:
                sessions.append(
                    {"slot": index, "stay": stay, "seconds": t1 - t0, "updates_per_s": (poses1 - poses0) / (t1 - t0)}
                )
        finally:
            client.close()
        if not stay:
            time.sleep(rng.uniform(*CHURN_GAP_S))
    return {"sessions": sessions, "errors": errors}


def clients_main(url: str, plan: dict) -> None:
    """Child process: run the plan's slots, print one JSON line with every session and error."""
    start = time.monotonic()
    end = start + plan["seconds"]
    results: list[dict] = [{} for _ in plan["slots"]]

    def run(i: int, slot: dict) -> None:
        results[i] = _slot(url, slot["index"], slot["stay"], plan["seed"], start, plan["settle"], end)

    threads = [threading.Thread(target=run, args=(i, s), daemon=True) for i, s in enumerate(plan["slots"])]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=plan["seconds"] + 90)
    sessions = [s for r in results for s in r.get("sessions", [])]
    errors = [e for r in results for e in r.get("errors", [])]
    print(json.dumps({"sessions": sessions, "errors": errors}), flush=True)


def spawn_clients(url: str, slots: list[dict], seconds: float, settle: float, seed: int) -> subprocess.Popen:
    plan = {"slots": slots, "seconds": seconds, "settle": settle, "seed": seed}
    return subprocess.Popen(
        [sys.executable, "-m", "benchmarks.harness", url, json.dumps(plan)], stdout=subprocess.PIPE, text=True, cwd=ROOT
    )


def collect(children: list[subprocess.Popen], timeout: float) -> dict:
    """Every child's sessions and errors, merged."""
    merged: dict[str, list] = {"sessions": [], "errors": []}
    for child in children:
        out, _ = child.communicate(timeout=timeout)
        lines = [line for line in out.strip().splitlines() if line.startswith("{")]
        if child.returncode != 0 or not lines:
            merged["errors"].append(f"client process exited {child.returncode} without results")
            continue
        result = json.loads(lines[-1])
        merged["sessions"] += result["sessions"]
        merged["errors"] += result["errors"]
    return merged


# -- the server side -----------------------------------------------------------------------------
class ErrorLog(logging.Handler):
    """Counts log records at WARNING and above, and tracebacks printed to stderr (viser prints its own)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.records: list[str] = []
        self.errors = 0
        self.tracebacks = 0

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(f"{record.levelname} {record.name}: {record.getMessage()}"[:300])
        self.errors += record.levelno >= logging.ERROR

    def install(self) -> ErrorLog:
        """Start counting; uninstall() puts logging, stderr and the thread hook back."""
        self._saved = (sys.stderr, threading.excepthook)
        logging.getLogger().addHandler(self)
        sys.stderr = _Tee(sys.stderr, self)
        previous = threading.excepthook

        def hook(args: threading.ExceptHookArgs) -> None:
            name = args.thread.name if args.thread else "?"
            self.records.append(f"thread {name}: {args.exc_type.__name__}: {args.exc_value}")
            self.errors += 1
            previous(args)

        threading.excepthook = hook
        return self

    def uninstall(self) -> None:
        logging.getLogger().removeHandler(self)
        sys.stderr, threading.excepthook = self._saved


class _Tee:
    """stderr that also counts tracebacks."""

    def __init__(self, inner: TextIO, log: ErrorLog) -> None:
        self._inner, self._log = inner, log

    def write(self, text: str) -> int:
        if "Traceback (most recent call last)" in text:
            self._log.tracebacks += 1
            self._log.records.append("a traceback on stderr")
        return self._inner.write(text)

    def flush(self) -> None:
        self._inner.flush()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)


class RtfSampler:
    """Samples the pacer's step count every `period` s on a thread: the RTF overall and per window."""

    def __init__(self, dashboard: Any, period: float = 1.0) -> None:
        self._d, self._period = dashboard, period
        self.samples: list[tuple[float, int]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="rtf-sampler", daemon=True)

    def start(self) -> RtfSampler:
        self._thread.start()
        return self

    def _run(self) -> None:
        while not self._stop.is_set():
            self.samples.append((time.perf_counter(), self._d.pacer._steps))
            self._stop.wait(self._period)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()
        self.samples.append((time.perf_counter(), self._d.pacer._steps))

    def rtf(self, window_s: float | None = None) -> tuple[float, float]:
        """(RTF over all samples, worst RTF over windows of `window_s`), divided by the asked speed."""
        pacer, s = self._d.pacer, self.samples
        scale = pacer.timestep / pacer.speed
        overall = (s[-1][1] - s[0][1]) * scale / (s[-1][0] - s[0][0])
        if not window_s:
            return overall, overall
        worst, j = overall, 0
        for i in range(len(s)):
            while j < len(s) and s[j][0] - s[i][0] < window_s:
                j += 1
            if j == len(s):
                break
            worst = min(worst, (s[j][1] - s[i][1]) * scale / (s[j][0] - s[i][0]))
        return overall, worst


def free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    clients_main(sys.argv[1], json.loads(sys.argv[2]))
