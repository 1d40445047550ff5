"""A disk slower than the recording: the recording says it is behind, says when it caught up, loses nothing.

The disk is slowed in the file's own writer (hopper.telemetry.writer.PipedFile._store takes the
time a disk of SLOW_BPS would) once the recording is open: the pipe from rerun stays full, as on a
disk that takes the bytes slower than they come, and rerun's own channel then holds the loop back
to the disk's pace. The waits are on the notices themselves; the test gives the disk its speed back.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from clients import connect, titles
from net import wait_until
from rrd import signal_times, verify

from hopper.config import SimConfig
from hopper.sim import Simulation
from hopper.telemetry import Telemetry
from hopper.telemetry.writer import PipedFile

pytestmark = pytest.mark.integration  # a server, and the file's writer thread (conftest: the suite in parts)

WAIT_S = 120.0  # a bound on each wait for a notice, never reached when things work


SLOW_BPS = 200e3  # bytes/s: a recording at 1x sends ~70 kB/s, at 16x 1.1 MB/s, unpaced ~7 MB/s


class Disk:
    """The writer's disk speed: `bps` bytes/s, None for as fast as the real one."""

    bps: float | None = None


@pytest.fixture
def disk(monkeypatch: pytest.MonkeyPatch) -> Disk:
    speed = Disk()
    store = PipedFile._store

    def timed(self: PipedFile, data: memoryview) -> None:
        if speed.bps is not None:
            time.sleep(len(data) / speed.bps)  # the fault: a write takes as long as on a slow disk
        store(self, data)

    monkeypatch.setattr(PipedFile, "_store", timed)
    yield speed
    speed.bps = None  # a failed test must not leave a recording's close() waiting on it


def test_a_slow_disk_is_said_behind_then_caught_up_and_the_file_has_every_tick(tmp_path: Path, disk: Disk) -> None:
    sim = Simulation(SimConfig(terrain="flat"))
    path, notices = tmp_path / "slow.rrd", []
    with Telemetry(sim, path=path, flush_s=0.05, behind_s=0.5, on_lag=notices.append) as recording:
        disk.bps = SLOW_BPS
        deadline = time.monotonic() + WAIT_S
        while not notices and time.monotonic() < deadline:  # steps until the notice (1 kHz: the pipe fills)
            sim.step()
        assert notices and notices[0] is not None, "a slow disk was never said behind"
        assert "the disk takes the recording's data slower than it comes" in notices[0]
        assert recording.behind == notices[0]
        print(f"\nbehind after {sim.data.time:.1f} s simulated: {notices[0]}")
        disk.bps = None
        while len(notices) < 2 and time.monotonic() < deadline:
            sim.step()
        assert notices[1:] == [None] and recording.behind is None, notices
        ticks = round(sim.data.time / sim.model.opt.timestep)
    verify(path)
    assert len(signal_times(path)) == ticks  # nothing lost while the disk was slow


def test_the_dashboard_notifies_a_recording_behind_and_caught_up(start, disk: Disk, probes) -> None:  # noqa: ANN001
    dashboard = start(speed=16.0)
    probes.append(client := connect(dashboard))
    client.set_gui_value("Record", True)
    assert wait_until(lambda: dashboard.recorder.progress()[1] > 0), "Record did not start a recording"
    disk.bps = SLOW_BPS
    assert client.wait_for(lambda p: "Recording behind" in titles(p), timeout=WAIT_S), titles(client)
    body = client.notifications[titles(client).index("Recording behind")]["body"]
    assert "the disk takes the recording's data slower than it comes" in body, body
    assert "Behind:" in dashboard.layout.record.info.content
    start_s = dashboard.sim.data.time
    assert wait_until(lambda: dashboard.sim.data.time > start_s + 1.0), "the simulation stopped"
    disk.bps = None
    assert client.wait_for(lambda p: "Recording caught up" in titles(p), timeout=WAIT_S), titles(client)
    assert wait_until(lambda: "Behind:" not in dashboard.layout.record.info.content)
    client.set_gui_value("Stop recording", True)
    assert client.wait_for(lambda p: "Recording saved" in titles(p), timeout=WAIT_S), titles(client)
    verify(*dashboard.recorder.progress()[:1])
