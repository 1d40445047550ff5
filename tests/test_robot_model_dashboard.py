"""`hopper-dashboard --model`: a variant is served with its own wheel on the page; a misnamed model exits 2."""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import sys
import threading
from pathlib import Path

import pytest
import variants
from hopper.app.dashboard.probe import ProbeClient
from net import free_port
from test_dashboard_cli import dashboard_process

from hopper.config import SimConfig
from hopper.layout import NAMES
from hopper.model import robot_of
from hopper.robot import PACKAGED

pytestmark = pytest.mark.integration  # servers and processes (conftest: the suite in parts)


def _page_says(probe: ProbeClient, text: str) -> bool:
    """Whether any GUI element's props or updates, as the probe received them, hold `text`."""
    sent = [m.get("props", {}) for m in probe.gui.values()] + list(probe.gui_updates.values())
    return any(text in json.dumps(props, default=repr) for props in sent)  # repr: binary payloads


def test_the_dashboard_flies_and_shows_a_variant(start, tmp_path: Path) -> None:  # noqa: ANN001 (conftest's)
    path = variants.variant(tmp_path)
    robot = robot_of(SimConfig(model=str(path), terrain="flat"))
    assert robot.momentum_capacity > 1.1 * PACKAGED.momentum_capacity  # the gauge must tell them apart
    d = start(model=str(path), terrain="flat")
    assert d.sim.robot == robot and d.sim.config.model == str(path)
    probe = ProbeClient(d.url)
    try:
        gauge = f"+{robot.momentum_capacity:.2f} N m s"  # the status strip's momentum gauge, of its wheel
        assert probe.wait_for(lambda p: p.pose_frames > 5 and _page_says(p, gauge), timeout=60), "no variant page"
        packaged = f"+{PACKAGED.momentum_capacity:.2f} N m s"
        assert not probe.wait_for(lambda p: _page_says(p, packaged), timeout=0.05)  # one look, under its lock
    finally:
        probe.close()


def test_the_cli_serves_a_variant_given_by_a_relative_path_and_stops_cleanly(tmp_path: Path) -> None:
    variants.variant(tmp_path)
    port = free_port()
    process = dashboard_process(
        "--model", "variant.xml", "--port", str(port), "--sessions-dir", str(tmp_path), cwd=tmp_path
    )
    try:
        guard = threading.Timer(120, process.kill)  # a bound for a loaded machine, not a pace
        guard.start()
        lines: list[str] = []
        while not lines or lines[-1] and not lines[-1].startswith("hopper-dashboard: serving"):
            lines.append(process.stdout.readline())
        guard.cancel()
        assert lines[-1].startswith(f"hopper-dashboard: serving http://127.0.0.1:{port}"), lines
        probe = ProbeClient(f"http://127.0.0.1:{port}")
        try:
            assert probe.wait_for(lambda p: p.pose_frames > 5, timeout=60), "the variant's robot never moved"
        finally:
            probe.close()
        process.send_signal(signal.SIGTERM)
        _, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 0 and "Traceback" not in err, err
    # Nothing listens any more (a plain bind may still meet the probe's connection in TIME_WAIT:
    # a websocket's server closes its TCP connection first).
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection(("127.0.0.1", port), timeout=5).close()


def test_the_cli_refuses_a_renamed_actuator_in_one_line(tmp_path: Path) -> None:
    path = variants.renamed_actuator(tmp_path)
    done = subprocess.run(
        [sys.executable, "-m", "hopper.app.dashboard.cli", "--model", str(path), "--port", str(free_port())],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hopper-dashboard: error: argument --model: "), done.stderr
    assert "no actuator 'wheel'" in lines[0] and f"expected {', '.join(NAMES['actuator'])}" in lines[0]
