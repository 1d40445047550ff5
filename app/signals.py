"""One stop convention for the CLIs: SIGTERM (and SIGINT) raise KeyboardInterrupt in the main thread."""

from __future__ import annotations

import signal


def stop_like_ctrl_c() -> None:
    """Make SIGTERM and SIGINT both raise KeyboardInterrupt in the main thread.

    Python's default SIGTERM kills the process without unwinding, which leaves recordings
    unfinalized; raising KeyboardInterrupt instead runs every `with`/`finally` on the way out,
    exactly as Ctrl-C does. SIGINT is set too because a shell starts background jobs with SIGINT
    ignored, and Python then never installs its Ctrl-C handler. Call first thing, from the main
    thread.
    """
    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, signal.default_int_handler)
