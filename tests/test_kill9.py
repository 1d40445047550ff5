"""kill -9 of a recording server: everything up to the last flush reads back with rerun's own reader.

The flush policy is --rrd-flush-s: every that many wall seconds the batch is encoded and written
(hopper.telemetry.writer), so at 1x a killed server loses at most about that much simulation.
"""

from __future__ import annotations

import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import msgspec
import pytest
from hopper.app.dashboard.panels.status import decode_values
from hopper.app.dashboard.probe import ProbeClient
from net import free_port, wait_until
from rrd import RERUN_BINARY, signal_times, verify

pytestmark = pytest.mark.integration  # servers, processes or pools (conftest: the suite in parts)

REPO = Path(__file__).resolve().parent.parent


class StatusProbe(ProbeClient):
    """A probe that also keeps the simulation time of the latest status strip and when it came."""

    latest: tuple[float, float] | None = None  # (simulation s, time.monotonic() at arrival)

    def _decode(self, raw: bytes) -> None:
        super()._decode(raw)
        size = int.from_bytes(raw[0:8], "little")
        compressed = int.from_bytes(raw[8:16], "little")
        payload = self._decompressor.decompress(raw[16 : 16 + compressed], max_output_size=size)
        for message in msgspec.msgpack.decode(payload)["messages"]:
            content = message.get("updates", {}).get("content") if message.get("type") == "GuiUpdateMessage" else None
            shown = decode_values(content)  # the strip's values (its table goes only when its layout changes)
            if shown is not None:
                self.latest = (float(shown["time"]), time.monotonic())


@pytest.mark.parametrize("flush_s", [0.5])  # one case: a server start costs ~10 s here
def test_kill_9_loses_at_most_the_flush_period(tmp_path: Path, flush_s: float) -> None:
    path, port = tmp_path / "killed.rrd", free_port()
    server = subprocess.Popen(
        [sys.executable, "-m", "hopper.app.dashboard.cli", "--port", str(port), "--terrain", "flat",
         "--rrd", str(path), "--rrd-flush-s", str(flush_s), "--sessions-dir", str(tmp_path / "s")],
        cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
    )  # fmt: skip
    out: list[str] = []
    reader = threading.Thread(target=lambda: out.extend(server.stdout), daemon=True)  # type: ignore[arg-type]
    reader.start()
    probe = None
    try:
        # "serving" comes once the scene and the access check exist: a websocket opened while the
        # port merely listens is closed for the browser to reconnect, which this probe does not.
        assert wait_until(lambda: any("serving" in line for line in out), timeout=90), out
        probe = StatusProbe(f"http://127.0.0.1:{port}", open_timeout=10)
        assert wait_until(lambda: probe.latest is not None and probe.latest[0] > 1.5 + flush_s, timeout=60)
        sim_s, seen = probe.latest
        server.send_signal(signal.SIGKILL)
        killed_at = sim_s + (time.monotonic() - seen)  # at 1x; the status strip is 0.2 s old at most
        server.wait(timeout=10)
    finally:
        if probe is not None:
            probe.close()
        if server.poll() is None:
            server.kill()
            server.wait()

    with pytest.warns(Warning, match="no footer"):  # rerun's reader, as the file was left: whole messages
        rows = signal_times(path)
    lost = killed_at - (rows[-1] if len(rows) else 0.0)
    print(f"\nflush every {flush_s:g} s: {len(rows) / 1000:.2f} s of simulation kept, {lost:.2f} s lost at the kill")
    assert len(rows) > 1000 and abs(rows[-1] - rows[0] - (len(rows) - 1) * 1e-3) < 1e-6  # no gap
    assert lost <= flush_s + 0.6, f"lost {lost:.2f} s with a flush every {flush_s} s"

    # No footer: `rerun rrd verify` says so; rerun's own `rrd migrate` adds one, keeping every row.
    unfinished = subprocess.run([RERUN_BINARY, "rrd", "verify", str(path)], capture_output=True, text=True)
    assert "footer" in unfinished.stdout + unfinished.stderr
    copy = tmp_path / "repaired.rrd"
    shutil.copy(path, copy)
    subprocess.run([RERUN_BINARY, "rrd", "migrate", str(copy)], check=True, capture_output=True, timeout=120)
    verify(copy)
    assert len(signal_times(copy)) == len(rows)
