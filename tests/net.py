"""Loopback helpers shared by the dashboard tests."""

from __future__ import annotations

import socket
import time
from collections.abc import Callable


def free_port() -> int:
    """A port on 127.0.0.1 that nothing listens on right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_until(predicate: Callable[[], object], timeout: float = 60.0) -> bool:
    """Poll `predicate` until it is truthy or `timeout` s pass; True if it became truthy.

    The wait is on the event; `timeout` only bounds a failure. It was 10 s, and with the load
    average at 12 on 2 cores a gain sent by a probe took longer than that to reach the loop (a
    GUI message, a callback on viser's thread pool, the loop's queue): nothing was lost, all of it
    was slow. No test waits for something not to happen with it.
    """
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return False


def port_is_free(port: int) -> bool:
    """Whether a plain bind (no SO_REUSEADDR: what any other program would do) to the port works."""
    with socket.socket() as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True
