"""`hopper-dashboard` as a user runs it: real processes, one-line errors, clean stops."""

from __future__ import annotations

import dataclasses
import os
import signal
import socket
import subprocess
import sys
import threading
import urllib.request
from pathlib import Path

import pytest
from hopper.app.dashboard.cli import parse
from hopper.app.dashboard.config import DashboardConfig, check_sessions_dir
from hopper.app.dashboard.pacing import MAX
from net import free_port, port_is_free, wait_until
from rrd import verify
from threads import signal_a_thread_not_main

from hopper.config import GRAVITY_PRESETS

pytestmark = pytest.mark.integration  # servers, processes or pools (conftest: the suite in parts)

REPO = Path(__file__).resolve().parent.parent


def size(path: Path) -> int:
    """Bytes in `path`, 0 while it is missing (the start-up check creates and removes it)."""
    try:
        return path.stat().st_size
    except FileNotFoundError:
        return 0


def verify_recording(path: Path) -> None:
    """`rerun rrd verify` accepts the file: it was closed, footer and all."""
    verify(path)


def cli(*args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hopper.app.dashboard.cli", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=REPO,
    )


def _ended(process: subprocess.Popen[str]) -> str:
    """Stop the process if it still runs; its exit status and the end of what it wrote."""
    if process.poll() is None:
        process.kill()
    out, err = process.communicate(timeout=30)
    return f"exit {process.returncode}; stdout {out[-300:]!r}; stderr {err[-600:]!r}"


def dashboard_process(*args: str, cwd: Path = REPO) -> subprocess.Popen[str]:
    """hopper-dashboard running in the background (in folder `cwd`), its output piped."""
    return subprocess.Popen(
        [sys.executable, "-m", "hopper.app.dashboard.cli", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=cwd,
    )


@pytest.mark.parametrize(
    "args, message",
    [
        (["--kp", "-1"], "kp must be a finite number in [0, 2000] N m/rad"),
        (["--kd", "nan"], "kd must be a finite number"),
        (["--terrain", "moon"], "invalid choice 'moon'"),
        (["--port", "abc"], "--port"),
        (["--port", "70000"], "port must be an integer in [1, 65535]"),
        (["--speed", "99"], "speed must be in [0.1, 64] x real time, or max"),
        (["--speed", "fast"], "invalid speed 'fast' (a number, x real time, or max)"),
        (["--seed", "-3"], "seed must be a non-negative integer"),
        (["--host", "not a host"], "host must be an IP address"),
        (["--rrd", "/nonexistent/dir/run.rrd"], "does not exist"),
        (["--rrd", "run.txt"], "must name a .rrd file"),
        (["--rerun-viewer", "sometimes"], "invalid choice"),
        (["--lighting", "dim"], "invalid choice 'dim' (choose from full, no-shadows, simple)"),
        (["--gravity", "Jupiter"], "'Jupiter' is neither m/s^2 nor one of moon, mars, ceres, earth"),
        (["--gravity", "9.8"], "gravity must be one of the presets (moon 1.625, mars 3.72, ceres 0.28, earth 9.81"),
        (["--bogus"], "unrecognized arguments: --bogus"),
        (["--sess", "runs"], "unrecognized arguments: --sess runs"),  # no abbreviation of --sessions-dir
        (["--sessions-dir", "/proc/foo"], "cannot use sessions folder '/proc/foo'"),
        (["--sessions-dir", "README.md/sessions"], "cannot use sessions folder 'README.md/sessions'"),
    ],
)
def test_bad_arguments_give_one_line_and_exit_2(args: list[str], message: str) -> None:
    result = cli(*args)
    assert result.returncode == 2, result
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("hopper-dashboard: error: ") and message in lines[0], lines[0]
    assert "Traceback" not in result.stderr + result.stdout


@pytest.mark.parametrize("seed", ["-3", "x", str(2**64)])
def test_a_bad_seed_is_refused_as_hopper_sim_refuses_it(seed: str) -> None:
    """--seed is hopper-sim's check (cli_common.seed): the same line, the same bounds. 2^64 was a
    traceback (the IMU's seed is a uint64) once the dashboard had begun to build."""
    dashboard = cli("--seed", seed, "--port", str(free_port()))
    sim = subprocess.run([sys.executable, "-m", "hopper.app.sim_cli", "run", "--seed", seed],
                         capture_output=True, text=True, timeout=60, cwd=REPO)  # fmt: skip
    assert dashboard.returncode == sim.returncode == 2, dashboard.stderr
    assert sim.stderr.count("\n") == 1 and sim.stderr.startswith("hopper-sim: error: argument --seed: "), sim.stderr
    assert dashboard.stderr == sim.stderr.replace("hopper-sim", "hopper-dashboard", 1)
    assert parse(["--seed", str(2**64 - 1)]).seed == 2**64 - 1  # the largest both take


def test_help_shows_every_setting_with_its_unit_and_default() -> None:
    result = cli("--help")
    assert result.returncode == 0, result.stderr
    for field in dataclasses.fields(DashboardConfig):
        assert f"--{field.name.replace('_', '-')}" in result.stdout, field.name
    text = " ".join(result.stdout.split())  # as wrapped for any terminal width
    assert "N m/rad (default: 450.0)" in text and "x real time (default: 1.0)" in text
    assert "exit status: 0 stopped by Ctrl-C or SIGTERM" in text


def test_no_flags_give_the_default_config_and_flags_reach_their_fields() -> None:
    assert parse([]) == DashboardConfig()
    config = parse(["--kp", "500", "--rerun-viewer", "serve", "--sessions-dir", "runs", "--rrd", "a.rrd"])
    assert config.kp == 500.0 and config.rerun_viewer == "serve"
    assert config.sessions_dir == Path("runs") and config.rrd == Path("a.rrd")
    assert parse(["--speed", "max"]).speed == MAX and parse(["--speed", "Max"]).speed == MAX
    assert parse(["--speed", "16"]).speed == 16.0
    assert parse(["--gravity", "Earth"]).sim_config().gravity == GRAVITY_PRESETS["earth"]
    assert parse(["--gravity", "9.81"]).gravity == GRAVITY_PRESETS["earth"]  # a preset's m/s^2, as hopper-sim takes it


def test_a_sessions_folder_is_made_in_a_folder_that_exists_and_probed_and_left_empty(tmp_path: Path) -> None:
    folder = tmp_path / "sessions"
    assert check_sessions_dir(folder) == folder
    assert folder.is_dir() and not any(folder.iterdir())
    assert check_sessions_dir(folder) == folder  # an existing, writable folder is fine too


def test_a_sessions_folder_whose_parent_is_missing_is_refused_in_one_line_and_nothing_is_made(tmp_path: Path) -> None:
    """It made the whole path (/nonexistent/dir/sessions: both folders) where every output path of
    hopper-sim refuses a missing parent: one rule now, the last folder alone may be made."""
    folder = tmp_path / "missing" / "sessions"
    result = cli("--sessions-dir", str(folder), "--port", str(free_port()))
    assert result.returncode == 2, result
    assert result.stderr == (
        f"hopper-dashboard: error: cannot use sessions folder '{folder}': folder {folder.parent} does not exist\n"
    ), result.stderr
    assert not any(tmp_path.iterdir()), "a folder was made"


def test_the_default_sessions_folder_is_made_in_the_folder_it_runs_in(tmp_path: Path) -> None:
    """A fresh clone has no sessions/: the default (relative to the working folder, which exists) is made."""
    port = free_port()
    process = dashboard_process("--port", str(port), cwd=tmp_path)
    try:
        for line in process.stdout:
            if "serving" in line:
                break
        else:
            raise AssertionError(f"the dashboard never served: {_ended(process)}")
        assert (tmp_path / "sessions").is_dir()
        process.send_signal(signal.SIGTERM)
        _, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 0, err[-2000:]
    assert port_is_free(port)


def test_a_port_in_use_gives_one_line_and_exit_2(tmp_path: Path) -> None:
    with socket.socket() as blocker:
        blocker.bind(("127.0.0.1", 0))
        blocker.listen()
        result = cli("--port", str(blocker.getsockname()[1]), "--sessions-dir", str(tmp_path))
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [result.stderr.strip()]
    assert "cannot serve on 127.0.0.1" in result.stderr and "Traceback" not in result.stderr


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_stops_cleanly_finalizes_the_recording_and_frees_the_port(tmp_path: Path, signum: int) -> None:
    pytest.importorskip("hopper.telemetry")
    port, rrd = free_port(), tmp_path / "run.rrd"
    process = dashboard_process("--port", str(port), "--rrd", str(rrd), "--sessions-dir", str(tmp_path))
    try:
        # The serving line comes once the loop runs (readline gives '' if the process ends first: then
        # it says why); a bound for a loaded machine, not a pace: a dashboard silent that long is killed.
        guard = threading.Timer(120, process.kill)
        guard.start()
        lines = []  # viser's banner, then ours
        while not lines or lines[-1] and not lines[-1].startswith("hopper-dashboard: serving"):
            lines.append(process.stdout.readline())
        guard.cancel()
        assert lines[-1].startswith("hopper-dashboard: serving http://127.0.0.1:"), f"never served: {_ended(process)}"
        # Some simulation into the recording: a batch written after the loop started, whatever the pace.
        started = size(rrd)
        assert wait_until(lambda: size(rrd) > started, timeout=120), "the recording did not grow"
        process.send_signal(signum)
        out, err = process.communicate(timeout=60)
        out = "".join(lines) + out
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 0, err
    assert "serving http://127.0.0.1:" in out and "stopped" in out
    assert "Traceback" not in err
    assert rrd.stat().st_size > 10_000
    verify_recording(rrd)
    assert port_is_free(port)


@pytest.mark.parametrize("to", ["the process", "a thread not main"])
def test_sigterm_right_after_serving_exits_0(tmp_path: Path, to: str) -> None:
    """The loop analysis linearizes a flight on a worker thread just after start-up; a SIGTERM then
    must wait for it, not let the interpreter exit under a thread in MuJoCo (it crashed: -11, 8 of 8).
    The kernel may deliver a process's signal on any of its threads; Python's handler then waits for
    the main thread to wake, and in an untimed wait it never did (CI: a hang, about 1 run in 100)."""
    for _ in range(3):
        port = free_port()
        process = dashboard_process("--port", str(port), "--sessions-dir", str(tmp_path))
        try:
            for line in process.stdout:  # the banner's last line comes once everything is built
                if "serving" in line:
                    break
            else:
                raise AssertionError(f"the dashboard never served: {_ended(process)}")
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=30) as page:  # as a user would
                assert page.status == 200
            if to == "the process":
                process.send_signal(signal.SIGTERM)
            else:
                signal_a_thread_not_main(process.pid, signal.SIGTERM)
            out, err = process.communicate(timeout=60)
        finally:
            if process.poll() is None:
                process.kill()
        assert process.returncode == 0, (process.returncode, err[-2000:])
        assert "Traceback" not in err and "stopped" in out
        assert port_is_free(port)


def test_sigterm_while_starting_up_stops_cleanly_and_finalizes_the_recording(tmp_path: Path) -> None:
    pytest.importorskip("hopper.telemetry")
    rrd, port = tmp_path / "run.rrd", free_port()
    process = dashboard_process("--port", str(port), "--rrd", str(rrd), "--sessions-dir", str(tmp_path))
    try:  # the recording has begun (its file has content) but the server is still being built
        assert wait_until(lambda: size(rrd) > 0, timeout=60), "no recording started"
        process.send_signal(signal.SIGTERM)
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 0, (process.returncode, err)
    assert "Traceback" not in err and "stopped" in out
    verify_recording(rrd)


@pytest.mark.parametrize("closed", ["before it starts", "after its first line"])
def test_a_reader_that_goes_away_stops_it_quietly_with_141(tmp_path: Path, closed: str) -> None:
    """`hopper-dashboard | head -1`: the server stops as on Ctrl-C (recording closed, port freed) and
    exits 141 (128 + SIGPIPE) without a traceback. viser's banner comes first, printed by rich (which
    exits 1 on a closed pipe), then our serving line once the scene is built: closed before the start,
    the banner finds it; after the first line, our own lines do."""
    pytest.importorskip("hopper.telemetry")
    port, rrd = free_port(), tmp_path / "run.rrd"
    read, write = os.pipe()
    if closed == "before it starts":
        os.close(read)
    process = subprocess.Popen(
        [sys.executable, "-m", "hopper.app.dashboard.cli", "--port", str(port), "--rrd", str(rrd)]
        + ["--sessions-dir", str(tmp_path)],
        stdout=write,
        stderr=subprocess.PIPE,
        text=True,
        cwd=REPO,
    )
    os.close(write)
    try:
        if closed == "after its first line":
            with open(read, "rb", buffering=0) as out:  # unbuffered: readline takes exactly one line
                assert out.readline(), f"no output: {_ended(process)}"
        _, err = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 141, (process.returncode, err[-2000:])
    assert "Traceback" not in err and "BrokenPipeError" not in err, err[-2000:]
    verify_recording(rrd)
    assert port_is_free(port)


def test_a_gravity_its_robot_is_too_weak_for_is_served_with_a_note_naming_the_fix(tmp_path: Path) -> None:
    """hopper-dashboard --gravity earth flies the paper's robot at Earth, as hopper-sim run does,
    and says on its output, as run does, that its legs cap the hop there and how to size it."""
    port = free_port()
    process = dashboard_process("--gravity", "earth", "--port", str(port), "--sessions-dir", str(tmp_path))
    try:
        lines = []
        for line in process.stdout:  # the note follows the serving line
            lines.append(line)
            if "note:" in line:
                break
        else:
            raise AssertionError(f"no note: {lines} {_ended(process)}")
        process.send_signal(signal.SIGTERM)
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 0 and "stopped" in out, err[-2000:]
    assert lines[-2].startswith("hopper-dashboard: serving http://127.0.0.1:")
    assert lines[-1].startswith("hopper-dashboard: note: at 9.81 m/s^2 this robot's 30 N m legs cap the hop at ")
    assert "`hopper-sim size --gravity 9.81 --out FILE` writes it sized for this gravity, for --model" in lines[-1]
