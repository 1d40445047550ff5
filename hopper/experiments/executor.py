"""Where episodes run: in this process, a local process pool, or Ray actors (locally or on a cluster).

Every executor runs chunks of episodes on `Worker`s (one per process, model built once) and yields
each chunk's results as it completes. Ray is the engine for large sweeps and clusters; for small
jobs its start-up (13-14 s here: ray.init 10 s, actors 3.5 s) would dominate, so `choose`
keeps them on the plain local path (benchmarks/bench_sweep.py measures where the line is).
"""

from __future__ import annotations

import logging
import math
import multiprocessing
import os
import signal
import socket
import sys
import threading
import time
from collections.abc import Iterable, Iterator
from typing import Literal, Protocol

from hopper.config import MOON_GRAVITY
from hopper.errors import HopperError
from hopper.experiments.spec import Episode
from hopper.experiments.worker import EpisodeResult, Worker
from hopper.interrupts import children_ignore_ctrl_c, each, held

Kind = Literal["auto", "local", "ray"]
Chunk = list[Episode]

# Sizing jobs (measured here with benchmarks/bench_sweep.py; the machine's speed only shifts them).
HOP_SIM_S = 3.1  # s of simulated time per hop on the Moon (ground + flight), ~ 1/sqrt(g) elsewhere
STEP_CPU_S = 15e-6  # s of one core per 1 kHz control tick (closed loop, ideal sensing)
# Ray's start-up is 13-14 s here (ray.init ~10 s, the actors 3.5 s). Below this much work per core
# a local pool, which needs no ray.init, finishes first; above it, Ray's start-up is a tenth of the
# run or less. Conservative: under load bench_sweep.py --line measured the pool at 11.5 s against
# Ray's 13 s (a line at 17 s of work per core), 24 s against 28 s at the heaviest (44 s).
RAY_MIN_WORK_PER_CORE_S = 120.0
# Below this much work (s of one core) a job runs in this process: a pool's spawned processes, each
# importing MuJoCo, took 1.2 s to start here, about what two workers would save on 2.4 s of work.
POOL_MIN_WORK_S = 2.0
# s a pool's shutdown may take before its workers are killed (SIGKILL): idle workers end at their
# sentinel and busy ones at SIGTERM within milliseconds; only one that ignores SIGTERM takes longer.
STOP_S = 5.0
CHUNK_CPU_S = 1.0  # s of work per chunk: Ray's per-call cost (~1 ms) is noise, and Ctrl-C loses little
IN_FLIGHT_PER_WORKER = 2  # chunks queued per Ray actor, so it never waits for the driver


def estimated_cpu_s(episode: Episode) -> float:
    """Rough single-core seconds to simulate `episode` (it may fall sooner)."""
    sim_s = episode.hops_target * HOP_SIM_S * math.sqrt(MOON_GRAVITY / episode.gravity)
    return sim_s / 1e-3 * STEP_CPU_S


def chunks(episodes: list[Episode], workers: int) -> list[Chunk]:
    """Consecutive episodes (same terrain mostly: the spec orders terrain and seed outermost) in chunks
    of about CHUNK_CPU_S, and at least 4 per worker so that the last chunks finish together."""
    if not episodes:
        return []
    total = sum(map(estimated_cpu_s, episodes))
    count = max(1, min(len(episodes), max(round(total / CHUNK_CPU_S), 4 * workers)))
    size = math.ceil(len(episodes) / count)
    return [episodes[i : i + size] for i in range(0, len(episodes), size)]


class Executor(Protocol):
    workers: int
    name: str

    def map(self, chunks: Iterable[Chunk]) -> Iterator[list[EpisodeResult]]:
        """Each chunk's results as it completes (any order)."""
        ...

    def close(self) -> None: ...


class ExecutorError(HopperError, RuntimeError):
    """An executor that cannot start (e.g. no Ray cluster at the address), in one line."""


class InProcess:
    """One worker in this process: no start-up at all, one core. `why` says why not more, for the
    user ("" when no more were to be had)."""

    name, workers = "in-process", 1

    def __init__(self, why: str = "") -> None:
        self.worker = Worker()
        self.why = why

    def map(self, chunks: Iterable[Chunk]) -> Iterator[list[EpisodeResult]]:
        for chunk in chunks:
            yield self.worker.run_chunk(chunk)

    def close(self) -> None:
        pass


_process_worker: Worker | None = None


def _start_process_worker() -> None:
    """Build the worker's simulation; it ignores Ctrl-C from its start (children_ignore_ctrl_c)."""
    global _process_worker
    _process_worker = Worker()
    _process_worker.warm()


def _run_in_process_worker(chunk: Chunk) -> list[EpisodeResult]:
    assert _process_worker is not None
    return _process_worker.run_chunk(chunk)


class LocalPool:
    """A pool of spawned processes on this machine, one Worker each (the plain local path)."""

    name = "local pool"

    def __init__(self, workers: int) -> None:
        self.workers = workers
        context = multiprocessing.get_context("spawn")  # no fork of a process holding MuJoCo or threads
        before = set(multiprocessing.active_children())
        with children_ignore_ctrl_c():
            self.pool = context.Pool(workers, initializer=_start_process_worker)
        # Its workers, all started by Pool(): the children this process gained there (Pool keeps its list private).
        self.processes = [p for p in multiprocessing.active_children() if p not in before]

    def map(self, chunks: Iterable[Chunk]) -> Iterator[list[EpisodeResult]]:
        yield from each(self.pool.imap_unordered(_run_in_process_worker, chunks))

    def close(self) -> None:
        """End the workers: at the end they are idle; on Ctrl-C nothing they do is wanted.

        Pool.terminate sends SIGTERM, then joins each worker without a timeout: a worker that ignores
        SIGTERM (a user's law that set it so, a library's handler stuck in C) hung it, Ctrl-C included.
        So it runs in a thread given STOP_S; the workers still alive then are killed, as stderr says.
        Stop signals wait for the end of this bounded close (hopper.interrupts.held)."""
        with held():
            stopper = threading.Thread(target=self.pool.terminate, name="pool terminate", daemon=True)
            stopper.start()
            stopper.join(STOP_S)
            if not stopper.is_alive():
                return
            wedged = [p for p in self.processes if p.is_alive()]
            for process in wedged:
                process.kill()
            if wedged:
                pids = ", ".join(str(p.pid) for p in wedged)
                print(f"{self.name}: worker{'s' if len(wedged) > 1 else ''} {pids} did not stop within {STOP_S:g} s "
                      "of SIGTERM: killed", file=sys.stderr)  # fmt: skip
                stopper.join(STOP_S)
            if stopper.is_alive():  # e.g. a worker in uninterruptible sleep: nothing more this process can do
                print(f"{self.name}: its shutdown still hangs (a worker SIGKILL cannot end yet): left behind",
                      file=sys.stderr)  # fmt: skip


# s, the probe of a named Ray cluster before ray.init, TCP connect and handshake together: a head
# answers both in about a millisecond (its GCS's SETTINGS came back in 0.7 ms here).
PROBE_S = 5.0
# HTTP/2's client preface and an empty SETTINGS frame (RFC 9113, 3.4): a Ray head's GCS and its Ray
# Client server are gRPC servers, which must answer with a SETTINGS frame of their own.
HTTP2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes([0, 0, 0, 0x4, 0, 0, 0, 0, 0])
SETTINGS = 0x4  # the frame type in byte 3 of a frame's 9-byte header


def unreachable(address: str, timeout_s: float = PROBE_S) -> str | None:
    """Why HOST:PORT (or ray://HOST:PORT) is no Ray head to join, where ray.init would retry for
    minutes: nothing accepts a TCP connection, or what does gives no gRPC (HTTP/2) handshake, within
    `timeout_s` in all. None if it answers as gRPC does, or for an address Ray resolves itself (auto,
    local). With RAY_USE_TLS the handshake would be TLS's, which this does not speak: TCP only then."""
    host, sep, port = address.removeprefix("ray://").rpartition(":")
    if not sep or not port.isdigit() or not host:
        return None
    if not 0 < int(port) < 65536:  # socket's own words for it: "connection refused"
        return f"port {port} is not a TCP port (1 to 65535)"
    deadline = time.monotonic() + timeout_s
    try:
        connection = socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s)
    except TimeoutError:
        return f"no answer within {timeout_s:g} s"
    except OSError as exc:  # refused, unreachable, an unknown host
        return (exc.strerror or str(exc)).lower()
    with connection:
        if os.environ.get("RAY_USE_TLS", "0").lower() in ("1", "true"):
            return None
        try:
            why = no_grpc(connection, deadline - time.monotonic())
        except TimeoutError:
            why = f"gave no gRPC handshake within {timeout_s:g} s"
    return f"it accepts TCP but {why}: not a Ray head" if why else None


def no_grpc(connection: socket.socket, timeout_s: float) -> str | None:
    """What a connected peer did instead of answering HTTP/2's client preface with a SETTINGS frame,
    as every gRPC server must (a Ray head's GCS and Ray Client server are); None if it answered.
    TimeoutError if it said nothing within `timeout_s`."""
    connection.settimeout(max(timeout_s, 1e-3))
    head = b""
    try:
        connection.sendall(HTTP2_PREFACE)
        while len(head) < 9 and (chunk := connection.recv(9 - len(head))):
            head += chunk
    except TimeoutError:
        raise  # an OSError too: the caller says how long it waited
    except OSError as exc:  # reset
        return f"broke the gRPC handshake off ({(exc.strerror or str(exc)).lower()})"
    if len(head) < 9:
        return "closed the connection without a gRPC handshake"
    return None if head[3] == SETTINGS else "answered without a gRPC handshake"


def check_address(address: str | None) -> None:
    """ExecutorError, in one line, if `address` (else RAY_ADDRESS) names a Ray head that is not there
    (unreachable); nothing without either."""
    connect = address or os.environ.get("RAY_ADDRESS")
    why = unreachable(connect) if connect else None
    if why:  # ray.init retries a closed port for minutes, warning as it goes
        raise ExecutorError(f"cannot reach the Ray cluster at {connect}: {why}")


class RayExecutor:
    """Ray actors, one per CPU of the cluster (a local one unless `address` or RAY_ADDRESS says where).

    Each actor is a Worker: it builds the model at its first episode and reuses it for every chunk.
    """

    name = "ray"

    def __init__(self, address: str | None = None, workers: int | None = None) -> None:
        start = time.perf_counter()
        connect = address or os.environ.get("RAY_ADDRESS")
        check_address(connect)
        import ray

        # ray.init replaces the SIGTERM handler with one that exits 1 (or 15); keep the caller's
        # (the CLIs turn SIGTERM into Ctrl-C so that results are written and the exit is 130).
        sigterm = signal.getsignal(signal.SIGTERM) if threading.current_thread() is threading.main_thread() else None
        options = {"include_dashboard": False, "log_to_driver": False, "logging_level": logging.ERROR}
        where = f"the Ray cluster at {connect}" if connect else "a local Ray"
        # Whatever stops the start-up, Ray is shut down here, not left to the interpreter's exit. A Ctrl-C
        # waits for ray.init to return (held): one that landed as it made its core worker left that
        # worker out of ray.shutdown's reach, and the process crashed at exit (SIGSEGV, in Ray's C++).
        try:
            with held():
                if connect:
                    ray.init(address=connect, **options)
                else:  # "local": a new instance of our own, never one that `ray start` left running here
                    ray.init(address="local", num_cpus=workers or os.cpu_count() or 1, **options)
        except (ConnectionError, RuntimeError, ValueError, ray.exceptions.RayError) as exc:  # AuthenticationError
            _shut_down(ray)
            raise ExecutorError(f"cannot start or reach {where}{_auth_hint(exc)}: {_first_line(exc)}") from None
        # SIGTERM meets the handler ray.init sets while it runs, which held() cannot defer: it exits 15
        # (or 1), here a stop as Ctrl-C is. (One as the core worker is made can still crash Ray's exit.)
        except SystemExit:
            _shut_down(ray)
            raise KeyboardInterrupt from None
        except BaseException:
            _shut_down(ray)
            raise
        finally:
            if sigterm is not None:
                signal.signal(signal.SIGTERM, sigterm)
        self.ray = ray
        self.address = connect or "local"
        try:
            cpus = int(ray.cluster_resources().get("CPU", 1))
            self.workers = max(1, min(workers or cpus, cpus))
            remote = ray.remote(num_cpus=1)(Worker)
            self.actors = [remote.remote() for _ in range(self.workers)]
            ray.get([a.warm.remote() for a in self.actors])  # every actor is up, its model built
        except BaseException as exc:
            _shut_down(ray)
            if isinstance(exc, ray.exceptions.RayError):  # e.g. a node whose Python has no hopper (README)
                raise ExecutorError(f"the workers of {where} cannot start: {_first_line(exc)}") from None
            raise
        self.startup_s = time.perf_counter() - start

    def map(self, chunks: Iterable[Chunk]) -> Iterator[list[EpisodeResult]]:
        ray, queue = self.ray, iter(chunks)
        running: dict[object, object] = {}  # object ref -> actor

        def submit(actor: object) -> None:
            chunk = next(queue, None)
            if chunk is not None:
                running[actor.run_chunk.remote(chunk)] = actor  # type: ignore[attr-defined]

        for actor in self.actors:
            for _ in range(IN_FLIGHT_PER_WORKER):
                submit(actor)
        while running:
            (ref,), _ = ray.wait(list(running), num_returns=1)
            actor = running.pop(ref)
            submit(actor)
            yield ray.get(ref)

    def close(self) -> None:
        _shut_down(self.ray)  # actors are not detached: they end with this driver


def _shut_down(ray: object) -> None:
    """ray.shutdown(), which takes about a second, not cut short by a second Ctrl-C (it comes after)."""
    with held():
        ray.shutdown()  # type: ignore[attr-defined]


def _first_line(exc: BaseException) -> str:
    """The first line of what `exc` says (of an AuthenticationError, without Ray's paragraph of help)."""
    return (str(getattr(exc, "message", exc)).strip().splitlines() or [type(exc).__name__])[0]


def _auth_hint(exc: BaseException) -> str:
    """A hint if `exc` or what caused it is Ray's token authentication refusing us: ray.init's
    ConnectionError says only "Failed to connect", its cause says why."""
    while exc is not None:
        if "uthentica" in str(exc):
            return " (token authentication? see the README)"
        exc = exc.__cause__ or exc.__context__  # type: ignore[assignment]
    return ""


def choose(kind: Kind, episodes: list[Episode], workers: int | None = None, address: str | None = None) -> Executor:
    """The executor for a job: Ray when asked, when a cluster is named, or when the job is big enough;
    otherwise the local path (in this process for one worker or a tiny job)."""
    cores = workers or os.cpu_count() or 1
    if kind == "local" or (kind == "auto" and not (address or os.environ.get("RAY_ADDRESS"))):
        work = sum(map(estimated_cpu_s, episodes))
        if kind == "auto" and work / cores >= RAY_MIN_WORK_PER_CORE_S:
            return RayExecutor(address, workers)
        if min(cores, len(episodes)) > 1 and work >= POOL_MIN_WORK_S:
            return LocalPool(min(cores, len(episodes)))
        return InProcess(in_process_why(len(episodes), work, cores, workers))
    return RayExecutor(address, workers)


def in_process_why(episodes: int, work_s: float, cores: int, asked: int | None) -> str:
    """Why a job that `cores` workers could share runs in this process, in words; "" for one core
    (--workers 1 or a one-core machine), where there is nothing to explain."""
    if cores <= 1:
        return ""
    why = f"about {work_s:.1f} s of work, too little for a pool of processes to repay its start-up (~1 s)"
    if episodes == 1:
        why = "one episode"
    return why + (f"; --workers {asked} not used" if asked else "")
