"""A full disk mid-recording: the recording stops with a notification, the file verifies, the dashboard goes on.

The disk is a real 2 MB tmpfs (mounting one needs root or CAP_SYS_ADMIN): the writes hit a real
ENOSPC, the same path a full disk takes. RLIMIT_FSIZE would raise EFBIG instead, and a loop device
needs root as well; where the mount is refused the test says so and skips.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest
from clients import connect, titles
from hopper.app.dashboard.config import DashboardConfig
from hopper.app.dashboard.server import Dashboard
from net import free_port, wait_until
from rrd import signal_times, verify

pytestmark = pytest.mark.integration  # servers, processes or pools (conftest: the suite in parts)

SIZE = "2m"  # the terrain and robot take ~1.1 MB, the reserve 0.5 MB: a few seconds of data fit


@pytest.fixture
def small_disk(tmp_path: Path):
    folder = tmp_path / "small"
    folder.mkdir()
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={SIZE}", "tmpfs", str(folder)], capture_output=True, text=True
    )
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a {SIZE} tmpfs here (needs root): {mounted.stderr.strip()}")
    try:
        yield folder
    finally:
        subprocess.run(["umount", "-l", str(folder)], check=False)


def test_full_disk_stops_the_recording_and_the_dashboard_goes_on(small_disk: Path) -> None:
    config = DashboardConfig(port=free_port(), sessions_dir=small_disk, speed=4.0)
    with Dashboard(config, verbose=False) as dashboard:
        client = connect(dashboard)
        try:
            client.set_gui_value("Record", True)
            assert wait_until(lambda: dashboard.recorder.active), "Record did not start a recording"
            assert client.wait_for(lambda p: "Recording failed" in titles(p), timeout=90), titles(client)
            body = client.notifications[titles(client).index("Recording failed")]["body"]
            print(f"\nnotification: {body}")
            assert "No space left on device" in body and "is complete" in body, body
            assert not dashboard.recorder.active
            assert "Recording failed" in dashboard.layout.record.info.content

            # The simulation and the page go on.
            t, frames = dashboard.sim.time, dashboard.frames
            assert wait_until(lambda: dashboard.sim.time > t + 1.0 and dashboard.frames > frames + 10)

            # What was written verifies and reads back; the reserve is gone.
            files = sorted(small_disk.glob("*.rrd"))
            assert len(files) == 1 and not list(small_disk.glob(".*reserve")), os.listdir(small_disk)
            verify(files[0])
            rows = signal_times(files[0])
            print(f"recorded {len(rows) / 1000:.1f} s of simulation in {files[0].stat().st_size / 1e6:.2f} MB")
            assert len(rows) > 500

            # Room again: recording works again.
            files[0].unlink()
            client.set_gui_value("Record", True)
            panel = dashboard.layout.record.info
            assert wait_until(lambda: dashboard.recorder.active and "Recording to" in panel.content)
            dashboard.recorder.stop()
            assert wait_until(lambda: not dashboard.recorder.active and "Saved" in panel.content)
            verify(*small_disk.glob("*.rrd"))
        finally:
            client.close()
