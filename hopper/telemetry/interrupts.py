"""Hold Ctrl-C and SIGTERM while a batch is sent or a recording finalised, then deliver them."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator


@contextlib.contextmanager
def deferred_signals() -> Iterator[None]:
    """Hold SIGINT and SIGTERM inside the block, then re-raise the first that arrived.

    An interrupt in the middle of a send would lose or duplicate part of a batch. Only the main
    thread can install handlers; in other threads this does nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    saved = {
        sig: signal.signal(sig, lambda signum, _: pending.append(signum)) for sig in (signal.SIGINT, signal.SIGTERM)
    }
    try:
        yield
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)
        if pending:
            signal.raise_signal(pending[0])
