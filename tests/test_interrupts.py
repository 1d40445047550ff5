"""A stop signal at any moment of a recorded run: KeyboardInterrupt, and every file verifies."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from multiprocessing.pool import ThreadPool
from pathlib import Path

import pytest
from hopper.app import episode, recordings
from hopper.app.recordings import FileLimits
from net import wait_until
from rrd import verify

from hopper import interrupts
from hopper.config import SimConfig
from hopper.telemetry import recorder, scene, writer

# The code a stop can cut short with a file open: the CLI's run, the recorder, its writer.
WATCHED = {m.__file__ for m in (episode, interrupts, recordings, recorder, scene, writer)}


@pytest.fixture
def stop_handlers() -> Iterator[None]:
    """The CLI's stop handlers for the test, the previous ones (and no stop request) after it."""
    saved = {s: signal.getsignal(s) for s in interrupts.STOP_SIGNALS}
    interrupts.stop_like_ctrl_c()
    yield
    for s, handler in saved.items():
        signal.signal(s, handler)
    interrupts.clear()


def record(path: Path, names: list[str], at: int | None = None, **limits: float) -> None:
    """A recorded one-hop run that sends SIGTERM at its `at`-th line executed in WATCHED;
    the function of each line executed is appended to `names`."""

    def local(frame, event, arg):  # noqa: ANN001, ANN202 - sys.settrace's signature
        if event == "line":
            names.append(frame.f_code.co_name)
            if len(names) == at:
                signal.raise_signal(signal.SIGTERM)  # through the real handler, as a kill would
        return local

    def tracer(frame, event, arg):  # noqa: ANN001, ANN202
        return local if frame.f_code.co_filename in WATCHED else None

    sys.settrace(tracer)
    try:
        episode.simulate(SimConfig(terrain="flat"), 1, path, trace=False, limits=FileLimits(**limits))
    finally:
        sys.settrace(None)


@pytest.mark.parametrize("rollover", [False, True], ids=["one-file", "rollover"])
def test_a_stop_at_any_line_of_a_recorded_run_leaves_files_that_verify(
    tmp_path: Path, stop_handlers: None, rollover: bool
) -> None:
    # No flush by wall time (flush_s at its 60 s most): the batches go by count, so the run executes the same lines as
    # the dry one whatever the machine's load (a loaded run flushed more often, and a stop chosen near
    # the dry run's end came after the real run's). Rollover is by simulation time.
    options = {"flush_s": 60.0} | ({"max_min": 0.4 / 60} if rollover else {})  # a 1.5 s hop in four parts
    dry: list[str] = []
    record(tmp_path / "dry.rrd", dry, **options)
    assert len(dry) > 1000 and "_open_part" in dry, len(dry)
    # Every 15th line of the set-up, the sends, the switches and the finalising; 20 of the ticks' hot path.
    rare = [i for i, name in enumerate(dry, 1) if name != "tick"]
    ticks = [i for i, name in enumerate(dry, 1) if name == "tick"]
    moments = sorted(rare[::15] + ticks[:: len(ticks) // 20])
    files: list[Path] = []
    for i, at in enumerate(moments):
        path = tmp_path / f"at-{i}.rrd"
        names: list[str] = []
        with pytest.raises(KeyboardInterrupt):
            record(path, names, at, **options)
        interrupts.clear()
        made = sorted(tmp_path.glob(f"at-{i}*.rrd"))
        # No file only if the stop came before the recording's set-up began (it waits out a set-up).
        assert made or "_limits" not in names, f"a stop at line {at} ({dry[at - 1]}) left no file"
        files += made
    assert not list(tmp_path.glob(".*.reserve")), "a reserve file was left behind"
    verify(*files)


def _signal_from_another_thread_once_main_waits(release: threading.Event) -> threading.Thread:
    """A thread that, once the main thread blocks in a wait, takes a SIGTERM on itself (as the
    kernel may hand a process's signal to any thread) and, if the main thread sleeps on through it
    for 30 s, sets `release` so the test fails instead of hanging."""
    main = threading.main_thread().ident

    def blocked() -> bool:  # in one of interrupts' waits (its own sleep, or threading's below it)
        frame = sys._current_frames().get(main)
        while frame is not None and frame.f_code.co_filename != interrupts.__file__:
            frame = frame.f_back
        return frame is not None

    def run() -> None:
        if not wait_until(blocked, timeout=30):  # fail, not hang
            release.set()
            return
        signal.pthread_kill(threading.get_ident(), signal.SIGTERM)
        if not wait_until(interrupts.stop_requested, timeout=30):
            release.set()

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


@pytest.mark.parametrize("timeout", [None, 600.0])
def test_a_stop_signal_taken_by_another_thread_interrupts_a_wait(stop_handlers: None, timeout: float | None) -> None:
    release = threading.Event()
    helper = _signal_from_another_thread_once_main_waits(release)
    with pytest.raises(KeyboardInterrupt):
        interrupts.wait(release, timeout)
    helper.join(30)
    assert not release.is_set(), "the wait slept through the signal until the release"


def test_a_stop_signal_taken_by_another_thread_interrupts_a_join(stop_handlers: None) -> None:
    release = threading.Event()
    waiter = threading.Thread(target=release.wait, daemon=True)
    waiter.start()
    helper = _signal_from_another_thread_once_main_waits(release)
    with pytest.raises(KeyboardInterrupt):
        interrupts.join(waiter)
    helper.join(30)
    assert not release.is_set(), "the join slept through the signal until the thread ended"
    release.set()
    waiter.join(30)
    assert not waiter.is_alive()


def test_a_stop_signal_taken_by_another_thread_interrupts_a_pools_results(stop_handlers: None) -> None:
    release = threading.Event()
    with ThreadPool(1) as pool:  # the same result iterator as a process pool's
        results = pool.imap(lambda _: release.wait(), [0])
        helper = _signal_from_another_thread_once_main_waits(release)
        with pytest.raises(KeyboardInterrupt):
            list(interrupts.each(results))
        helper.join(30)
        assert not release.is_set(), "the results slept through the signal until the release"
        release.set()
        assert list(interrupts.each(pool.imap(lambda n: n * n, range(5)))) == [0, 1, 4, 9, 16]


def test_wait_says_whether_the_event_came_within_the_timeout() -> None:
    event = threading.Event()
    assert interrupts.wait(event, 0.0) is False
    assert interrupts.wait(event, 0.3) is False
    event.set()
    assert interrupts.wait(event, 0.0) is True and interrupts.wait(event) is True


def test_importing_the_simulation_starts_no_process() -> None:
    """`import mujoco` loads glfw, which probes its library in a Python subprocess: a pool worker
    stopped while importing left the probe to print a BrokenPipeError into a command's stderr after
    a clean Ctrl-C (train_policy's Ctrl-C test, 4 of 40 under load). Nothing here renders through
    MuJoCo's OpenGL, so hopper turns it off unless MUJOCO_GL says otherwise."""
    probe = (
        "import subprocess\n"
        "started = []\n"
        "popen = subprocess.Popen\n"
        "subprocess.Popen = lambda *a, **k: started.append(a) or popen(*a, **k)\n"
        "import hopper.sim, hopper.app.episode\n"
        "print(len(started))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "0", result.stdout


NESTED = """
import signal, sys
from hopper import interrupts

interrupts.stop_like_ctrl_c()
handler = interrupts._interrupt.__code__
for k in range(1, 30):
    seen = 0

    def local(frame, event, arg):
        global seen
        if event == "line":
            seen += 1
            if seen == k:  # the k-th line the first signal's handling runs, in the handler or what it calls
                signal.raise_signal(signal.SIGTERM)
        return local

    def within(frame):
        while frame is not None:
            if frame.f_code is handler:
                return True
            frame = frame.f_back
        return False

    sys.settrace(lambda frame, event, arg: local if within(frame) else None)
    try:
        signal.raise_signal(signal.SIGTERM)
    except KeyboardInterrupt:
        pass
    finally:
        sys.settrace(None)
    interrupts.clear()
print("stopped every time")
"""


def test_a_second_stop_signal_while_the_handler_runs_does_not_hang_the_process() -> None:
    """Two SIGTERMs at once (`timeout` forwarding one and a `pkill` sending another) hung a served
    dashboard: the handler set a threading.Event, the second signal ran the handler again inside that
    Event's lock, and it waited on itself for good. Here the second comes at each line the first's
    handling runs."""
    done = subprocess.run([sys.executable, "-c", NESTED], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == "stopped every time", done.stderr[-2000:]


AT_ONCE = """
import os, signal, sys, threading, time
from multiprocessing.pool import ThreadPool
from hopper import interrupts

interrupts.stop_like_ctrl_c()
release, pool = threading.Event(), ThreadPool(1)
waits = {
    "wait": lambda: interrupts.wait(release),
    "each": lambda: list(interrupts.each(pool.imap(lambda _: release.wait(), [0]))),
}


def both():
    time.sleep(0.05)  # a head start only: main is in its wait or about to be; either way both must stop it
    os.kill(os.getpid(), signal.SIGTERM)
    os.kill(os.getpid(), signal.SIGINT)


came = []  # what the wait raised, then what the second signal raised (wherever it landed)
threading.Thread(target=both, daemon=True).start()
try:
    try:
        waits[sys.argv[1]]()
    except BaseException as exc:
        came.append(type(exc).__name__)
        raise
except BaseException as exc:
    came.append(type(exc).__name__)
while True:  # say what came first and end here: the second signal's handler may run at any later call
    try:
        os.write(1, came[0].encode())
        os._exit(0)
    except KeyboardInterrupt:
        continue
"""


def test_two_stop_signals_at_once_stop_a_wait_as_one() -> None:
    """SIGTERM and SIGINT sent at once while the main thread waited on an Event (the dashboard's
    serve) or on a pool's results: the first raised inside Condition.wait, the second as that
    unwound, before the lock was taken back, and Event.wait's `with` then released it a second time:
    RuntimeError (release unlocked lock), a traceback and exit 1 instead of a stop."""
    came = {
        wait: [subprocess.run([sys.executable, "-c", AT_ONCE, wait], capture_output=True, text=True, timeout=120)
               for _ in range(8)]
        for wait in ("wait", "each")
    }  # fmt: skip
    for wait, runs in came.items():
        assert [(r.returncode, r.stdout) for r in runs] == [(0, "KeyboardInterrupt")] * len(runs), wait
