"""A stop signal (SIGINT, as a terminal's Ctrl-C) sent from inside a command at a chosen moment (tests only)."""

from __future__ import annotations

import multiprocessing.pool
import signal
import types
from collections.abc import Iterable, Iterator

import pytest

from hopper.experiments import executor
from hopper.experiments.worker import EpisodeResult


def ctrl_c() -> None:
    signal.raise_signal(signal.SIGINT)  # through the CLI's handler, as a terminal's Ctrl-C


class StopAt(executor.InProcess):
    """The in-process executor (one episode a chunk here), sending Ctrl-C at `moment`: `first` once the
    first chunk's results are taken (one of several episodes done), `last` once the last chunk's are
    (before the command has closed the executor), `close` as it is closed (every result in)."""

    def __init__(self, moment: str) -> None:
        super().__init__()
        self.moment = moment

    def map(self, chunks: Iterable[executor.Chunk]) -> Iterator[list[EpisodeResult]]:
        chunks = list(chunks)
        for i, results in enumerate(super().map(chunks)):
            yield results  # the command takes them before it asks for the next
            if (self.moment, i) in (("first", 0), ("last", len(chunks) - 1)):
                ctrl_c()

    def close(self) -> None:
        if self.moment == "close":
            ctrl_c()


def pool_stopping_after(monkeypatch: pytest.MonkeyPatch, item: int | None) -> None:
    """hopper-sim's spawned pool (stress, envelope) on threads of this process, where the test sends
    its signal, and Ctrl-C once the command has taken result `item` (from 0; None: never)."""
    from hopper.app import sim_cli

    monkeypatch.setattr(sim_cli.multiprocessing, "get_context", lambda method: types.SimpleNamespace(
        Pool=multiprocessing.pool.ThreadPool))  # fmt: skip
    each = sim_cli.each

    def stop_at(results):  # noqa: ANN001, ANN202 (a pool's imap, each's items)
        for i, outcome in enumerate(each(results)):
            yield outcome  # the command takes it before it asks for the next
            if i == item:
                ctrl_c()

    monkeypatch.setattr(sim_cli, "each", stop_at)
