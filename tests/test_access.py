"""Access off loopback: a token required to start, checked when a websocket opens, and never leaked.

Servers bind 0.0.0.0 here, but every connection goes to 127.0.0.1: no test sends anything outside
the loopback range.
"""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest
import viser
import websockets.exceptions
import websockets.sync.client as ws_client
from hopper.app.dashboard.access import Access, is_loopback, page_url
from hopper.app.dashboard.config import DashboardConfig
from hopper.app.dashboard.probe import ProbeClient
from net import free_port, wait_until
from rerun.chunk import RrdReader
from rrd import verify

from hopper.config import InvalidConfig

pytestmark = pytest.mark.integration  # servers, processes or pools (conftest: the suite in parts)

REPO = Path(__file__).resolve().parents[1]
TOKEN = "correct-horse-battery-staple-42"
URL_TOKEN = re.compile(r"token=([A-Za-z0-9._~-]+)")


def cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hopper.app.dashboard.cli", *args], capture_output=True, text=True, timeout=60, cwd=REPO
    )


def refused(url: str) -> int:
    """Open a websocket as a browser would and return the close code; fails if any data arrives."""
    protocols = [f"viser-v{viser.__version__}"]
    with (
        ws_client.connect(url, subprotocols=protocols, open_timeout=10) as socket,  # type: ignore[arg-type]
        pytest.raises(websockets.exceptions.ConnectionClosed) as closed,
    ):
        data = socket.recv(timeout=10)
        pytest.fail(f"a client without the token received {len(data)} bytes")
    assert closed.value.rcvd is not None, "the server did not close the connection"
    return closed.value.rcvd.code


def test_what_counts_as_loopback_and_the_url_that_carries_the_token() -> None:
    assert all(is_loopback(h) for h in ("127.0.0.1", "127.3.2.1", "::1", "localhost"))
    assert not any(is_loopback(h) for h in ("0.0.0.0", "::", "192.168.1.20", "10.0.0.1"))
    assert page_url("127.0.0.1", 8080, None) == "http://127.0.0.1:8080"
    # viser's page opens its websocket at the `websocket` parameter, query string and all.
    assert page_url("10.0.0.1", 8080, TOKEN) == f"http://10.0.0.1:8080/?websocket=ws://10.0.0.1:8080/?token={TOKEN}"
    assert page_url("::1", 9, TOKEN).startswith("http://[::1]:9/?websocket=ws://[::1]:9/?token=")


def test_grants_compare_the_whole_token() -> None:
    assert Access().grant("/") == "operate"  # no token: everyone, as on loopback before
    access = Access(TOKEN)
    assert access.grant(f"/?token={TOKEN}") == "operate"
    assert access.grant(f"/?x=1&token={TOKEN}") == "operate"
    for path in ("/", "/?token=", f"/?token={TOKEN[:-1]}", f"/?token={TOKEN}x", f"/?token={TOKEN.upper()}"):
        assert access.grant(path) is None, path
    assert Access(TOKEN, public_view=True).grant("/") == "view"
    assert TOKEN not in repr(access)


def test_the_config_requires_a_usable_token_off_loopback_and_never_shows_it() -> None:
    with pytest.raises(InvalidConfig, match="not a loopback address, needs an access token"):
        DashboardConfig(host="0.0.0.0")
    with pytest.raises(InvalidConfig, match="at least 16 characters") as bad:
        DashboardConfig(token="secret pass")
    assert "secret pass" not in str(bad.value)
    with pytest.raises(InvalidConfig, match="--public-view needs --token"):
        DashboardConfig(public_view=True)
    generated = DashboardConfig(host="0.0.0.0", token="auto")
    assert generated.token is not None and len(generated.token) >= 32 and generated.token != "auto"
    assert DashboardConfig(host="0.0.0.0", token="auto").token != generated.token
    assert generated.token not in repr(generated)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--host", "0.0.0.0"], "serving on 0.0.0.0, which is not a loopback address, needs an access token"),
        (["--host", "::"], "not a loopback address, needs an access token"),
        (["--token", "tooshort"], "--token must be at least 16 characters"),
        (["--token", "spaces are not allowed in urls"], "--token must be at least 16 characters"),
        (["--public-view"], "--public-view needs --token"),
        (["--idle-timeout", "0"], "idle-timeout must be a positive number of seconds"),
    ],
)
def test_bad_access_arguments_give_one_line_and_exit_2(args: list[str], message: str) -> None:
    result = cli(*args, "--port", str(free_port()))
    assert result.returncode == 2, result
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hopper-dashboard: error: ") and message in lines[0], result.stderr
    assert "Traceback" not in result.stderr + result.stdout
    if "--token" in args:
        assert args[args.index("--token") + 1] not in result.stderr  # a mistyped token is not echoed either


def test_off_loopback_a_client_without_the_token_is_refused_and_one_with_it_connects(start) -> None:
    d = start(host="0.0.0.0", token=TOKEN)
    port = d.server.get_port()
    assert refused(f"ws://127.0.0.1:{port}/") == 1008
    assert refused(f"ws://127.0.0.1:{port}/?token=not-the-token-at-all") == 1008
    assert d.gatekeeper.refused == 2 and not d.server.get_clients() and d.roles.operator is None

    probe = ProbeClient(f"http://127.0.0.1:{port}/?token={TOKEN}")
    try:
        assert probe.wait_for(lambda p: len(p.gui) > 20 and p.pose_frames > 0), "the token holder saw nothing"
        assert wait_until(lambda: d.roles.operator is not None), "the token holder does not operate"
        # Operating is not yet being viser's client: viser drops GUI updates from a connection
        # until it has handled its first camera message (conftest's `client` waits the same way).
        assert wait_until(lambda: len(d.server.get_clients()) == 1), "the server never registered the probe"
        probe.set_gui_value("Kp", 640.0)
        assert wait_until(lambda: d.sim.gains.kp == 640.0), (
            d.sim.gains,
            (d.roles.operator, d.roles.seated, d.roles.refused),
            [n.get("title") for n in probe.notifications],
            [e.describe() for e in list(d.sim.events)[-5:]],
        )
    finally:
        probe.close()


def test_public_view_lets_clients_without_the_token_watch_but_never_operate(start) -> None:
    d = start(host="0.0.0.0", token=TOKEN, public_view=True)
    port = d.server.get_port()
    holder = ProbeClient(f"http://127.0.0.1:{port}/?token={TOKEN}")
    watcher = ProbeClient(f"http://127.0.0.1:{port}/")
    try:
        assert holder.wait_for(lambda p: len(p.gui) > 20)
        assert wait_until(lambda: d.roles.operator is not None)
        assert watcher.wait_for(lambda p: len(p.gui) > 20 and p.pose_frames > 0), "a public viewer saw nothing"
        assert wait_until(lambda: len(d.roles.seated) == 2)
        watcher_id = d.roles.seated[1]

        refused_before = d.roles.refused
        watcher.set_gui_value("Kp", 600.0)
        assert watcher.wait_for(lambda p: any(n.get("title") == "Read-only" for n in p.notifications))
        assert d.roles.refused == refused_before + 1 and d.sim.gains.kp == 450.0

        holder.close()  # the only one who may operate leaves: nobody operates, the watcher still watches
        assert wait_until(lambda: d.roles.operator is None and d.roles.seated == [watcher_id])
        d.roles.ask(watcher_id)
        assert d.roles.askers == [] and d.roles.operator is None
        frames = watcher.snapshot()[2]
        assert watcher.wait_for(lambda p: p.pose_frames > frames + 5)
    finally:
        holder.close()
        watcher.close()


def test_the_token_appears_in_no_log_and_no_recording(tmp_path: Path) -> None:
    """A real `hopper-dashboard --host 0.0.0.0 --token auto --rrd`: refused and admitted clients, a
    hand-over, then SIGTERM. The token is on stdout once (the URL to open) and nowhere else."""
    port, rrd = free_port(), tmp_path / "session.rrd"
    args = ["--host", "0.0.0.0", "--port", str(port), "--token", "auto", "--rrd", str(rrd)]
    child = subprocess.Popen(
        [sys.executable, "-m", "hopper.app.dashboard.cli", *args, "--sessions-dir", str(tmp_path / "s")],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=REPO,
    )
    out: list[str] = []
    err: list[str] = []
    readers = [
        threading.Thread(target=lambda: out.extend(child.stdout), daemon=True),  # type: ignore[arg-type]
        threading.Thread(target=lambda: err.extend(child.stderr), daemon=True),  # type: ignore[arg-type]
    ]
    for reader in readers:
        reader.start()
    probes: list[ProbeClient] = []
    try:
        assert wait_until(lambda: any("serving" in line for line in out), timeout=90), (out, err)
        token = URL_TOKEN.search(next(line for line in out if "serving" in line)).group(1)  # type: ignore[union-attr]
        assert "/?websocket=ws://" in "".join(out)

        assert refused(f"ws://127.0.0.1:{port}/") == 1008
        assert refused(f"ws://127.0.0.1:{port}/?token={token[:-2]}") == 1008
        for _ in range(2):
            probe = ProbeClient(f"http://127.0.0.1:{port}/?token={token}")
            probes.append(probe)
            assert probe.wait_for(lambda p: any(m["props"].get("label") == "Hand over" for m in p.gui.values()), 60)
        first, second = probes
        second.set_gui_value("Ask for control", True)
        assert first.wait_for(lambda p: any("asks for control" in n.get("title", "") for n in p.notifications))
        first.set_gui_value("Hand over", True)
        assert second.wait_for(lambda p: any(n.get("title") == "You have control" for n in p.notifications))
    finally:
        for probe in probes:
            probe.close()
        child.send_signal(signal.SIGTERM)
        child.wait(timeout=60)
        for reader in readers:
            reader.join(timeout=10)
    assert child.returncode == 0, (out, err)

    stdout, stderr = "".join(out), "".join(err)
    assert "refused a connection from 127.0.0.1" in stderr and "operator: client" in stderr  # the log was written
    assert token not in stderr
    assert [line for line in out if token in line] == [line for line in out if "serving" in line]

    verify(rrd)
    assert token.encode() not in rrd.read_bytes()
    decoded = " ".join(str(chunk.to_record_batch().to_pylist()) for chunk in RrdReader(rrd).stream())
    # What is searched holds the events (a positive control for the search below).
    assert re.search(r"operator client \d+ \(127\.0\.0\.1\): handed over by client \d+", decoded)
    assert token not in decoded
    assert stdout.count("serving") == 1
