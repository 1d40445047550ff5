"""CI: the wheel, installed in a clean venv, works outside the checkout (hopper-sim and hopper-dashboard).

Builds the wheel, installs it with its dependencies from the package registry into a new venv
without system site packages, then from a temporary folder elsewhere: checks that `hopper` comes
from the venv, runs `hopper-sim run --hops 2 --json out.json`, starts `hopper-dashboard` on a free
loopback port, fetches its page, stops it with SIGTERM and checks that the port is free again.
Exits non-zero, saying which step failed, on any failure. Run as `python .ci/wheel_check.py`.
"""

from __future__ import annotations

import json
import os
import queue
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
# Left-overs of earlier builds: setuptools would pack a stale build/lib into the wheel.
BUILD_LEFTOVERS = ("build", "dist", "*.egg-info", "__pycache__", ".git", ".*_cache", "sessions", "*.rrd")
BUILD_TIMEOUT_S = 300
INSTALL_TIMEOUT_S = 900  # every dependency, from pip's cache or the registry
RUN_TIMEOUT_S = 300  # the first run in a new venv also compiles the numba kernel
SERVE_TIMEOUT_S = 180
STOP_TIMEOUT_S = 30


class CheckFailed(Exception):
    """One step of the check failed; the message says which and why."""


def step(name: str) -> float:
    print(f"wheel check: {name}", flush=True)
    return time.monotonic()


def done(start: float) -> None:
    print(f"wheel check:   ok ({time.monotonic() - start:.1f} s)", flush=True)


def run(args: list[str | Path], timeout: float, cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    """Run to completion; CheckFailed with its output if it fails or outlives `timeout` s."""
    try:
        result = subprocess.run(
            [str(a) for a in args], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout
        )
    except subprocess.TimeoutExpired:
        raise CheckFailed(f"{' '.join(map(str, args))} took longer than {timeout:g} s") from None
    if result.returncode != 0:
        raise CheckFailed(
            f"{' '.join(map(str, args))} exited {result.returncode}\n{result.stdout[-3000:]}{result.stderr[-3000:]}"
        )
    return result


def clean_env() -> dict[str, str]:
    """This environment without anything that could bring the checkout or another venv in."""
    drop = ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP", "VIRTUAL_ENV", "PYTHONUSERBASE")
    return {k: v for k, v in os.environ.items() if k not in drop}


def build_wheel(work: Path, env: dict[str, str]) -> Path:
    source, out = work / "source", work / "wheels"
    shutil.copytree(REPO, source, ignore=shutil.ignore_patterns(*BUILD_LEFTOVERS))
    run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "-w", out, source], BUILD_TIMEOUT_S, work, env)
    wheels = list(out.glob("hopper_dashboard-*.whl"))
    if len(wheels) != 1:
        raise CheckFailed(f"expected one hopper_dashboard wheel in {out}, found {wheels}")
    return wheels[0]


def make_venv(work: Path, wheel: Path, env: dict[str, str]) -> Path:
    """A new venv (no system site packages) holding the wheel and its dependencies; its bin folder."""
    venv = work / "venv"
    run([sys.executable, "-m", "venv", venv], 120, work, env)
    run([venv / "bin" / "python", "-m", "pip", "install", "--quiet", wheel], INSTALL_TIMEOUT_S, work, env)
    return venv / "bin"


def check_imported_from_venv(bin_dir: Path, cwd: Path, env: dict[str, str]) -> None:
    code = "import hopper, hopper.app, hopper.terrain; print(hopper.__file__); print(hopper.terrain.__file__)"
    out = run([bin_dir / "python", "-c", code], 60, cwd, env).stdout.split()
    venv = bin_dir.parent.resolve()
    for path in map(Path, out):
        if venv not in path.resolve().parents:
            raise CheckFailed(f"hopper was imported from {path}, not from the venv {venv}")
        if REPO in path.resolve().parents:
            raise CheckFailed(f"hopper was imported from the checkout: {path}")
    print(f"wheel check:   hopper from {out[0]}", flush=True)


def check_hopper_sim(bin_dir: Path, cwd: Path, env: dict[str, str]) -> None:
    run([bin_dir / "hopper-sim", "run", "--hops", "2", "--json", "out.json"], RUN_TIMEOUT_S, cwd, env)
    data = json.loads((cwd / "out.json").read_text())
    completed = [hop for hop in data["hops"] if hop["completed"]]
    if data["fell"] or len(completed) != 2 or data["settings"]["hops"] != 2:
        raise CheckFailed(f"hopper-sim's JSON is not two completed hops: {json.dumps(data)[:500]}")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def port_is_free(port: int) -> bool:
    with socket.socket() as s:  # no SO_REUSEADDR: as any other program would bind it
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


def read_lines(stream: object, lines: queue.Queue[str | None]) -> None:
    for line in stream:  # type: ignore[attr-defined]
        lines.put(line)
    lines.put(None)


def wait_for_serving(process: subprocess.Popen[str], lines: queue.Queue[str | None], seen: list[str]) -> None:
    deadline = time.monotonic() + SERVE_TIMEOUT_S
    while time.monotonic() < deadline:
        try:
            line = lines.get(timeout=max(deadline - time.monotonic(), 0.01))
        except queue.Empty:
            break
        if line is None:
            raise CheckFailed(f"hopper-dashboard exited {process.wait()} before serving:\n{''.join(seen)}")
        seen.append(line)
        if "hopper-dashboard: serving http://127.0.0.1:" in line:
            return
    raise CheckFailed(f"hopper-dashboard did not say 'serving' within {SERVE_TIMEOUT_S} s:\n{''.join(seen)}")


def check_hopper_dashboard(bin_dir: Path, cwd: Path, env: dict[str, str]) -> None:
    port = free_port()
    process = subprocess.Popen(
        [str(bin_dir / "hopper-dashboard"), "--port", str(port)],
        cwd=cwd,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    lines: queue.Queue[str | None] = queue.Queue()
    seen: list[str] = []
    threading.Thread(target=read_lines, args=(process.stdout, lines), daemon=True).start()
    try:
        wait_for_serving(process, lines, seen)
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=30) as response:
            if response.status != 200:
                raise CheckFailed(f"GET http://127.0.0.1:{port}/ answered {response.status}")
        process.send_signal(signal.SIGTERM)
        try:
            code = process.wait(timeout=STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            raise CheckFailed(f"hopper-dashboard still running {STOP_TIMEOUT_S} s after SIGTERM") from None
        if code != 0:
            raise CheckFailed(f"hopper-dashboard exited {code} after SIGTERM:\n{''.join(seen)}")
        if not port_is_free(port):
            raise CheckFailed(f"port {port} still bound after hopper-dashboard stopped")
    finally:
        if process.poll() is None:
            process.kill()
            process.wait(timeout=10)


def main() -> int:
    started = time.monotonic()
    env = clean_env()
    with tempfile.TemporaryDirectory(prefix="hopper-wheel-check-") as tmp:
        work = Path(tmp)
        elsewhere = work / "elsewhere"  # outside the checkout: nothing of it on sys.path
        elsewhere.mkdir()
        try:
            t = step("build the wheel")
            wheel = build_wheel(work, env)
            done(t)
            t = step(f"install {wheel.name} into a clean venv")
            bin_dir = make_venv(work, wheel, env)
            done(t)
            t = step("import hopper from the venv, outside the checkout")
            check_imported_from_venv(bin_dir, elsewhere, env)
            done(t)
            t = step("hopper-sim run --hops 2 --json out.json")
            check_hopper_sim(bin_dir, elsewhere, env)
            done(t)
            t = step("hopper-dashboard: serve, GET /, SIGTERM, port freed")
            check_hopper_dashboard(bin_dir, elsewhere, env)
            done(t)
        except CheckFailed as exc:
            print(f"wheel check: FAILED: {exc}", file=sys.stderr, flush=True)
            return 1
    print(f"wheel check: passed in {time.monotonic() - started:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
