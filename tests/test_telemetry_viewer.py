"""Live rerun viewers (hopper.app.rerun_viewer): no display, the loopback web viewer, the hopper-sim flag."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from urllib.parse import parse_qs, urlparse

import psutil
import pytest
from hopper.app.rerun_viewer import ViewerError, open_viewer
from threads import signal_a_thread_not_main

from hopper.config import SimConfig
from hopper.sim import Simulation
from hopper.telemetry import Telemetry

pytestmark = pytest.mark.integration  # servers, processes or pools (conftest: the suite in parts)

RERUN = [sys.executable, "-m", "rerun_cli"]


def _listening(port: int) -> list[str]:
    return [c.laddr.ip for c in psutil.net_connections("tcp") if c.status == "LISTEN" and c.laddr.port == port]


def _ports_of(url: str) -> tuple[int, int]:
    """(web viewer port, gRPC port) of a served viewer's URL, both checked to be on 127.0.0.1."""
    web = urlparse(url)
    grpc = urlparse(parse_qs(web.query)["url"][0])
    assert web.hostname == grpc.hostname == "127.0.0.1"
    assert web.port is not None and grpc.port is not None
    return web.port, grpc.port


def _wait_freed(ports: tuple[int, ...], timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while any(_listening(p) for p in ports) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_listening(p) for p in ports), ports


def _without_display(env: dict[str, str]) -> dict[str, str]:
    return {k: v for k, v in env.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}


def test_off_is_no_viewer() -> None:
    viewer = open_viewer("off")
    assert viewer.sinks == () and viewer.url is None
    viewer.close()


def test_spawn_without_display_fails_clearly(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    with pytest.raises(ViewerError, match="needs a display"):
        open_viewer("spawn")


def test_hopper_sim_spawn_without_display_fails_in_one_line() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "hopper.app.sim_cli", "run", "--hops", "1", "--rerun-viewer", "spawn"],
        capture_output=True,
        text=True,
        env=_without_display(dict(os.environ)),
        timeout=120,
    )
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and result.stderr.startswith("hopper-sim: error: spawning a rerun viewer")


def test_serve_binds_loopback_only_and_frees_its_ports() -> None:
    sim = Simulation(SimConfig(terrain="flat"))
    viewer = open_viewer("serve")
    process = viewer.process
    assert viewer.url is not None and process is not None
    ports = _ports_of(viewer.url)
    with Telemetry(sim, sinks=viewer.sinks, on_close=viewer.close):
        for port in ports:
            assert _listening(port) == ["127.0.0.1"], port
        for _ in range(100):
            sim.step()
    assert process.poll() is not None and viewer.process is None  # closing the recording stopped it
    _wait_freed(ports)


@pytest.mark.parametrize("to", ["the process", "a thread not main"])  # the kernel may pick any thread
def test_hopper_sim_serve_prints_the_url_and_stops_on_ctrl_c(tmp_path: Path, to: str) -> None:
    rrd = tmp_path / "served.rrd"
    child = subprocess.Popen(
        [sys.executable, "-m", "hopper.app.sim_cli", "run", "--hops", "1", "--terrain", "flat"]
        + ["--rrd", str(rrd), "--rerun-viewer", "serve"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert child.stderr is not None
        # Until the run is done and served (readline gives '' if the child ends first). Other lines
        # may come between, e.g. a loaded machine's "recording: the disk takes ... slower" notice.
        lines = [child.stderr.readline()]
        while lines[-1] and lines[-1].strip() != "serving the recording until Ctrl-C":
            lines.append(child.stderr.readline())
        assert lines[-1], f"the run ended without serving: {lines}"
        url = [line for line in lines if line.startswith("rerun web viewer: http://127.0.0.1:")]
        assert url, lines
        ports = _ports_of(url[0].split(": ", 1)[1].strip())
        for port in ports:
            assert _listening(port) == ["127.0.0.1"], port
        if to == "the process":
            child.send_signal(signal.SIGINT)
        else:
            signal_a_thread_not_main(child.pid, signal.SIGINT)
        assert child.wait(timeout=60) == 130
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    _wait_freed(ports)
    subprocess.run([*RERUN, "rrd", "verify", str(rrd)], check=True, capture_output=True)
