"""A stop signal (SIGINT, as a terminal's Ctrl-C) sent from inside a command at a chosen moment (tests only)."""

from __future__ import annotations

import signal
from collections.abc import Iterable, Iterator

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
