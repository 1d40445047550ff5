"""One stop convention for the CLIs: SIGTERM (and SIGINT) raise KeyboardInterrupt in the main thread."""

from __future__ import annotations

import signal

_stop_requested = False


def _interrupt(signum: int, frame: object) -> None:
    global _stop_requested
    _stop_requested = True
    raise KeyboardInterrupt


def stop_like_ctrl_c() -> None:
    """Make SIGTERM and SIGINT both raise KeyboardInterrupt in the main thread.

    Python's default SIGTERM kills the process without unwinding, which leaves recordings
    unfinalized; raising KeyboardInterrupt instead runs every `with`/`finally` on the way out,
    exactly as Ctrl-C does. SIGINT is set too because a shell starts background jobs with SIGINT
    ignored, and Python then never installs its Ctrl-C handler. Call first thing, from the main
    thread.
    """
    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, _interrupt)


def raise_if_stop_requested() -> None:
    """Raise KeyboardInterrupt again if a stop signal came but its exception was swallowed.

    Some C extensions clear whatever error a lazy import raises: pyarrow's `pa.scalar`, which
    rerun calls when a recording starts, imports dateutil that way, so a signal landing there is
    lost. Call where a stop must not be missed: after start-up, after a run.
    """
    if _stop_requested:
        raise KeyboardInterrupt
