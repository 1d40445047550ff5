"""Stop signals: SIGTERM and SIGINT raise KeyboardInterrupt in the main thread, except inside `held()`.

One handler decides, so a signal is never lost between two handlers: `held()` blocks (a recording
being opened, a batch sent, a file finalised) only mark it pending, and the outermost block raises
it as it ends, once the code that owns the file can close it.
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing
import signal
import threading
import time
from collections.abc import Iterator
from typing import TypeVar

T = TypeVar("T")
STOP_SIGNALS = (signal.SIGTERM, signal.SIGINT)

_held = 0  # depth of held() blocks in the main thread
_pending: int | None = None  # the first signal that came inside a held() block, raised as it ends
_requested = False  # a stop signal came at all (raise_if_stop_requested)
# s: the longest a main thread blocked in wait() sleeps through a stop signal. The kernel hands a
# process a signal on whichever of its threads can take it; Python's handler then runs only once
# the main thread wakes, and an untimed wait would never wake (the dashboard hung on a SIGTERM).
WAKE_S = 0.1
POLL_S = 0.01  # s between two looks at an event in wait(): the latency it adds to the event


def _interrupt(signum: int, frame: object) -> None:
    """The handler: plain stores only. It runs in the main thread between two bytecodes, also inside
    a lock's block or inside itself (a second signal): a lock taken here (threading.Event.set) can
    be one that the interrupted frame holds, and then the process hangs (seen: two SIGTERMs at once
    while the dashboard's main thread waited)."""
    global _pending, _requested
    _requested = True
    if _held:
        if _pending is None:
            _pending = signum
        return
    raise KeyboardInterrupt


def stop_like_ctrl_c() -> None:
    """Make SIGTERM and SIGINT both raise KeyboardInterrupt in the main thread (outside held()).

    Python's default SIGTERM kills the process without unwinding, which leaves recordings
    unfinalized; raising KeyboardInterrupt instead runs every `with`/`finally` on the way out,
    exactly as Ctrl-C does. SIGINT is set too because a shell starts background jobs with SIGINT
    ignored, and Python then never installs its Ctrl-C handler. Call first thing, from the main
    thread.
    """
    for signum in STOP_SIGNALS:
        signal.signal(signum, _interrupt)


def raise_if_stop_requested() -> None:
    """Raise KeyboardInterrupt again if a stop signal came but its exception was swallowed.

    Some C extensions clear whatever error a lazy import raises: pyarrow's `pa.scalar`, which
    rerun calls when a recording starts, imports dateutil that way, so a signal landing there is
    lost. Call where a stop must not be missed: after start-up, after a run.
    """
    if _requested:
        raise KeyboardInterrupt


def stop_requested() -> bool:
    """A stop signal has come (held or not): a loop inside held() polls this to end early."""
    return _requested


def wait(event: threading.Event, timeout: float | None = None) -> bool:
    """`event.wait(timeout)` that a stop signal interrupts in the main thread, whichever thread the
    kernel handed it to (see WAKE_S); True if the event was set. It sleeps and looks (is_set takes no
    lock): a stop signal raised inside Event.wait, and a second one as that unwound, left its lock
    released twice (RuntimeError: release unlocked lock, for SIGTERM and SIGINT sent at once)."""
    deadline = math.inf if timeout is None else time.monotonic() + timeout
    while not event.is_set():
        left = deadline - time.monotonic()
        if left <= 0.0:
            return False
        time.sleep(min(POLL_S, left))
    return True


def join(thread: threading.Thread) -> None:
    """`thread.join()` that a stop signal interrupts in the main thread (see wait)."""
    while thread.is_alive():
        thread.join(WAKE_S)


def each(results: Iterator[T]) -> Iterator[T]:
    """The items of a multiprocessing pool's `imap` (or `imap_unordered`), waiting for each in a way
    a stop signal interrupts in the main thread (see wait): a sweep stops at once, not after its
    running episodes."""
    while True:
        try:
            yield results.next(WAKE_S)  # type: ignore[attr-defined] (multiprocessing.pool.IMapIterator)
        except multiprocessing.TimeoutError:
            continue
        except StopIteration:
            return
        except RuntimeError:  # two stop signals inside the iterator's Condition.wait (see wait): a stop
            if _requested:
                raise KeyboardInterrupt from None
            raise


def wait_for_stop() -> None:
    """Block until a stop signal comes, then raise KeyboardInterrupt (inside held() or not). It looks
    every WAKE_S (the handler sets no event: see _interrupt); outside held() the handler raises at once."""
    while not _requested:
        time.sleep(WAKE_S)
    raise KeyboardInterrupt


def clear() -> None:
    """Forget a stop request that was handled, for a process that goes on after it (a test, a REPL)."""
    global _pending, _requested
    _pending, _requested = None, False


@contextlib.contextmanager
def held() -> Iterator[None]:
    """Hold SIGINT and SIGTERM inside the block; the outermost block delivers the first at its end.

    An interrupt in the middle of a send would lose or duplicate part of a batch, and one inside a
    recording's set-up would leave a file that its owner never got to close. Only the main thread
    receives signals; in other threads this does nothing. Where another handler than this
    module's is installed (a library user's script), ours stands in for the outermost block and
    the signal then goes to the user's handler.
    """
    global _held, _pending
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    saved = {s: signal.getsignal(s) for s in STOP_SIGNALS}
    foreign = not _held and any(h is not _interrupt for h in saved.values())
    try:
        if foreign:
            for s in STOP_SIGNALS:
                signal.signal(s, _interrupt)
        _held += 1  # a signal before this store raises here, outside the block: nothing to undo
        try:
            yield
        finally:
            _held -= 1
    finally:
        if foreign:
            for s, handler in saved.items():
                signal.signal(s, handler)
        if not _held and _pending is not None:
            signum, _pending = _pending, None
            if foreign:
                signal.raise_signal(signum)  # to the user's own handler, now restored
            else:
                raise KeyboardInterrupt


@contextlib.contextmanager
def children_ignore_ctrl_c() -> Iterator[None]:
    """Processes spawned inside the block ignore SIGINT from their first instruction on.

    A terminal's Ctrl-C reaches every process of its group, and a spawned pool worker still
    starting its interpreter (before any initializer can ignore it) dies with a traceback. An
    ignored signal stays ignored across exec, so here this process ignores SIGINT while it spawns:
    a Ctrl-C in those few milliseconds is lost (SIGTERM is not). Main thread only.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    saved = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, saved)
