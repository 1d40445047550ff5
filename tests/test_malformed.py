"""Malformed websocket traffic over 127.0.0.1: the loop steps on and the running settings stay valid."""

from __future__ import annotations

import math
import random
import time

import msgspec
import pytest
import viser
import websockets.sync.client as ws_client
from hopper.app.dashboard.probe import ProbeClient
from hopper.app.dashboard.server import Dashboard
from net import wait_until

from hopper.config import GAIN_RANGES

pytestmark = pytest.mark.integration  # servers, processes or pools (conftest: the suite in parts)

GARBAGE_FRAMES = 12  # connections that each send one random binary frame (bounded: loopback only)


def settings(d: Dashboard) -> tuple:
    """Everything a browser may change: gains, wheel, sensing, gravity, terrain, speed, pause, stay fallen."""
    c = d.sim.config
    return (c.gains, c.wheel, c.sensing, c.gravity, c.seed, c.terrain, d.pacer.speed, d.pacer.paused, d.stay_fallen)


def rtf_over(d: Dashboard, seconds: float) -> float:
    """Simulated seconds per wall second over `seconds`, divided by the asked speed."""
    t0, w0 = d.sim.time, time.perf_counter()
    time.sleep(seconds)  # a measuring window, not an ordering wait
    return (d.sim.time - t0) / (time.perf_counter() - w0) / d.pacer.speed


def raw_frame(url: str, frame: bytes | str) -> None:
    """One connection with viser's subprotocol that sends `frame` and waits (bounded) for the server's verdict."""
    with ws_client.connect(
        url.replace("http://", "ws://", 1),
        subprotocols=[f"viser-v{viser.__version__}"],  # type: ignore[list-item]
        open_timeout=10,
        max_size=None,
        compression=None,
    ) as socket:
        socket.send(frame)
        deadline = time.monotonic() + 2.0
        try:  # the server drops a connection that sends garbage; read until it does (or 2 s pass)
            while time.monotonic() < deadline:
                socket.recv(timeout=max(0.01, deadline - time.monotonic()))
        except Exception:
            pass


def send_updates(client: ProbeClient, label: str, values: list) -> None:
    uuid = client.input_uuid(label)
    for value in values:
        client.send({"type": "GuiUpdateMessage", "uuid": uuid, "updates": {"value": value}})


# viser warns as it decodes the camera message with a word for a quaternion (part 3): expected here.
@pytest.mark.filterwarnings("ignore:.*does not match annotation:UserWarning")
def test_malformed_traffic_never_stops_the_loop_or_corrupts_settings(dashboard: Dashboard, client: ProbeClient) -> None:
    before = settings(dashboard)
    print(f"\nRTF before: {rtf_over(dashboard, 1.0):.3f}")
    rng = random.Random(10)

    # 1. Frames that are not viser messages at all, each on its own connection (viser drops it).
    for _ in range(GARBAGE_FRAMES):
        raw_frame(dashboard.url, rng.randbytes(rng.randint(1, 3000)))
    raw_frame(dashboard.url, "a text frame")
    for message in ([1, 2, 3], 42, {"no": "type"}, {"type": "NoSuchMessage", "x": 1}, {"type": "GuiUpdateMessage"}):
        raw_frame(dashboard.url, msgspec.msgpack.encode(message))

    # 2. Well-formed messages with wrong content, on a registered client (these keep the connection).
    kp_box = next(m["props"]["label"] for m in client.gui.values() if m["props"].get("label", "").startswith("N m/rad"))
    send_updates(client, "Kp", ["abc", [1, 2], {"a": 1}, None, True, "1e3", "nan"])
    send_updates(client, kp_box, [None, ["800"], True, {"v": 1}])
    send_updates(client, "Wheel on", ["no", 0, None, [], "false"])
    send_updates(client, "Realistic sensing", ["yes", 1, "true", [1]])
    send_updates(client, "Speed ×", ["fast", None, True, [2.0]])
    send_updates(client, "Stay fallen", ["yes", 1])
    send_updates(client, "Flat ground", ["yes", 1])
    send_updates(client, "Gravity", ["Jupiter", 3, None])
    send_updates(client, "Pause", [False, "x", 2])
    uuid = client.input_uuid("Kp")
    for updates in (
        {"no_such_prop": 1.0},
        {"removed": True},  # viser would mark the slider removed for everyone
        {"update_cb": 0},  # ... or replace its callbacks
        {"value": 800.0, "sync_cb": None},
        {},
    ):
        client.send({"type": "GuiUpdateMessage", "uuid": uuid, "updates": updates})
    client.send({"type": "GuiUpdateMessage", "uuid": "no-such-uuid", "updates": {"value": 1.0}})
    # 3. Messages that do not decode, each on its own connection (viser drops the connection).
    raw_frame(dashboard.url, msgspec.msgpack.encode({"type": "ViewerCameraMessage", "wxyz": "x"}))
    raw_frame(dashboard.url, msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": uuid, "updates": []}))

    # Ordering marker on the same connection: once this valid update is applied, everything sent
    # before it on this connection has been handled (or dropped).
    client.set_gui_value("Torso trail", False)
    assert wait_until(lambda: dashboard.layout.view.trail.value is False), "the client's valid update was lost"
    assert not client.closed, "well-formed messages must not cost the client its connection"
    marker = ProbeClient(dashboard.url)
    try:
        assert marker.wait_for(lambda p: len(p.gui) > 20), "a new client never saw the page after the garbage"
        print(f"RTF after the garbage: {rtf_over(dashboard, 1.0):.3f}")
        assert settings(dashboard) == before, "malformed traffic changed a setting"
        gains = dashboard.layout.gains
        assert gains.kp.value == before[0].kp and gains.entries["kp"].handle.value == "450"
        assert dashboard.layout.terrain.gravity.value == "Moon" and dashboard.layout.gains.wheel.value is True

        # 4. Out of range: clamped to valid values, never past the limits; the slider still works.
        send_updates(client, "Kp", [1e308, -1e308])
        send_updates(client, "Kd", [1e9])
        assert wait_until(lambda: dashboard.sim.gains.kd == GAIN_RANGES["kd"].high)
        for name in ("kp", "ki", "kd"):
            value, (low, high, _) = getattr(dashboard.sim.gains, name), GAIN_RANGES[name]
            assert math.isfinite(value) and low <= value <= high
        t = dashboard.sim.time
        assert wait_until(lambda: dashboard.sim.time > t + 0.5), "the loop stopped stepping"
        print(f"RTF at the end: {rtf_over(dashboard, 1.0):.3f}")
    finally:
        marker.close()
