"""Contract tests of hopper.app.dashboard.viser_compat: one per private touch of viser, by what it does.

Each runs a real `viser.ViserServer` on 127.0.0.1 and real websocket clients (`ProbeClient`, which
speaks the browser's protocol), so a viser release that reroutes a touch fails here: a gate that
no longer sees messages, an update that no longer arrives, a cursor that no longer moves. Waits
are on conditions that viser's own callbacks or the client's received frames make true.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import re
import threading
import warnings
from collections.abc import Callable, Iterator
from typing import Any

import pytest
import viser
import websockets.exceptions
import websockets.sync.client as ws_client
from hopper.app.dashboard import viser_compat as compat
from hopper.app.dashboard.probe import ProbeClient
from net import wait_until

from hopper.errors import HopperError
from hopper.versions import UnsupportedVersion

pytestmark = pytest.mark.integration  # a real ViserServer and websocket clients

HOST = "127.0.0.1"
TIMEOUT_S = 20.0  # s at most for any one awaited condition (a bound for a stuck run, not a delay)


class Seen:
    """Items reported from viser's threads, waited on with a condition variable."""

    def __init__(self) -> None:
        self.items: list[Any] = []
        self._changed = threading.Condition()

    def add(self, item: Any) -> None:
        with self._changed:
            self.items.append(item)
            self._changed.notify_all()

    def wait_for(self, predicate: Callable[[list[Any]], object], timeout: float = TIMEOUT_S) -> bool:
        with self._changed:
            return bool(self._changed.wait_for(lambda: predicate(self.items), timeout))


class Clients:
    """A server's registered clients, from its own connect and disconnect callbacks."""

    def __init__(self, server: viser.ViserServer) -> None:
        self.joined, self.left = Seen(), Seen()

        async def joined(client: viser.ClientHandle) -> None:
            self.joined.add(client)

        async def left(client: viser.ClientHandle) -> None:
            self.left.add(client.client_id)

        server.on_client_connect(joined)
        server.on_client_disconnect(left)

    def wait_left(self, client_id: int) -> bool:
        return self.left.wait_for(lambda ids: client_id in ids)


@pytest.fixture
def server() -> Iterator[viser.ViserServer]:
    s = viser.ViserServer(host=HOST, port=0, verbose=False)
    yield s
    s.stop()  # idempotent: a test may have stopped it


@pytest.fixture
def clients(server: viser.ViserServer) -> Clients:
    return Clients(server)


def connect(
    server: viser.ViserServer, clients: Clients, probes: list[ProbeClient], path: str = ""
) -> tuple[ProbeClient, viser.ClientHandle]:
    """A probe that viser has registered as a client (it has handled the probe's camera message), and its handle."""
    before = len(clients.joined.items)
    probe = ProbeClient(f"http://{HOST}:{server.get_port()}{path}")
    probes.append(probe)
    assert clients.joined.wait_for(lambda c: len(c) == before + 1), "viser never registered the probe"
    return probe, clients.joined.items[-1]


def updates_of(gated: Seen) -> list[tuple[int, Any]]:
    return [(cid, m.updates) for cid, m in gated.items if isinstance(m, compat.GuiUpdateMessage)]


# -- the version check ---------------------------------------------------------------------------
def test_the_version_check_refuses_another_release_series(monkeypatch: pytest.MonkeyPatch) -> None:
    compat.check_version()  # the installed one
    for supported in ("1.1.0", "1.1.1", "1.1.12", "1.1.2rc1"):
        compat.check_version(supported)
    for other in ("1.2.0", "1.10.1", "1.0.9", "2.1.1"):
        with pytest.raises(UnsupportedVersion, match=rf"viser {re.escape(other)} is installed; .* viser 1\.1\.\* only"):
            compat.check_version(other)
    assert issubclass(UnsupportedVersion, HopperError) and issubclass(UnsupportedVersion, RuntimeError)

    # At import: under another installed release the module refuses to load at all.
    real = importlib.metadata.version
    monkeypatch.setattr(importlib.metadata, "version", lambda name: "1.2.0" if name == "viser" else real(name))
    spec = importlib.util.spec_from_file_location("viser_compat_under_1_2", compat.__file__)
    assert spec is not None and spec.loader is not None
    with pytest.raises(UnsupportedVersion, match=r"viser 1\.2\.0 is installed"):
        spec.loader.exec_module(importlib.util.module_from_spec(spec))


# -- gate_incoming ----------------------------------------------------------------------------------
def test_the_gate_sees_a_clients_messages_first_and_what_it_drops_reaches_no_server_handler(
    server: viser.ViserServer, clients: Clients, probes: list[ProbeClient]
) -> None:
    slider = server.gui.add_slider("Gain", 0.0, 10.0, 1.0, 0.0)
    applied = Seen()

    async def on_update(_: viser.GuiEvent) -> None:  # async: on viser's event loop, in message order
        applied.add(slider.value)

    slider.on_update(on_update)
    # Installed while the client is connected, as the dashboard may be: it applies to open connections too.
    probe, client = connect(server, clients, probes)
    first, second = Seen(), Seen()

    def drop_one(value: float, seen: Seen) -> compat.Gate:
        def allows(client_id: int, message: Any) -> bool:
            seen.add((client_id, message))
            return not (isinstance(message, compat.GuiUpdateMessage) and message.updates == {"value": value})

        return allows

    compat.gate_incoming(server, drop_one(1.0, first))
    compat.gate_incoming(server, drop_one(3.0, second))  # stacked: runs before the first
    for value in (1.0, 3.0, 2.0):
        probe.set_gui_value("Gain", value)
    assert applied.wait_for(lambda values: values == [2.0]), applied.items
    # viser handles a connection's messages in order, each to its end: had 1.0 or 3.0 got
    # through, its callback would have run before 2.0's.
    assert applied.items == [2.0] and slider.value == 2.0
    me = client.client_id
    assert updates_of(second) == [(me, {"value": 1.0}), (me, {"value": 3.0}), (me, {"value": 2.0})]
    assert updates_of(first) == [(me, {"value": 1.0}), (me, {"value": 2.0})]


def test_a_message_the_gate_drops_still_reaches_the_senders_own_widgets(
    server: viser.ViserServer, clients: Clients, probes: list[ProbeClient]
) -> None:
    """The read-only gate lets viewers press their own buttons (Ask for control) only because of this."""
    probe, client = connect(server, clients, probes)
    own = client.gui.add_button("Mine")
    pressed = Seen()
    own.on_click(lambda event: pressed.add(event.client_id))
    gated = Seen()

    def drop_all(client_id: int, message: Any) -> bool:
        gated.add(message)
        return False

    compat.gate_incoming(server, drop_all)
    probe.set_gui_value("Mine", True)
    assert pressed.wait_for(lambda ids: ids == [client.client_id]), "the client's own handler never ran"
    uuid = compat.element_id(own)
    assert any(isinstance(m, compat.GuiUpdateMessage) and m.uuid == uuid for m in gated.items)


# What a browser (or a script) sends, for each class the read-only gate sorts messages by.
WIRE: dict[str, dict[str, Any]] = {
    "GuiUpdateMessage": {"uuid": "u1", "updates": {"value": 1.0}},
    "GuiButtonHoldMessage": {"uuid": "u2", "frequency": 10.0},
    "CommandTriggerMessage": {"uuid": "u3"},
    "GetRenderResponseMessage": {"payload": b"", "render_uuid": "r1"},
    "ShareUrlRequest": {},
    "ShareUrlDisconnect": {},
}


def test_the_message_classes_are_what_a_client_sends_decode_into(
    server: viser.ViserServer, clients: Clients, probes: list[ProbeClient], monkeypatch: pytest.MonkeyPatch
) -> None:
    # Should a message get past the gate after all, no share tunnel is tried (loopback only).
    monkeypatch.setattr(server, "request_share_url", lambda *_, **__: None)
    monkeypatch.setattr(server, "disconnect_share_url", lambda *_, **__: None)
    probe, client = connect(server, clients, probes)
    gated = Seen()

    def drop_all(client_id: int, message: Any) -> bool:
        gated.add((client_id, message))
        return False

    compat.gate_incoming(server, drop_all)
    for kind, fields in WIRE.items():
        probe.send({"type": kind, **fields})
    probe.send_camera()
    assert gated.wait_for(lambda items: len(items) == len(WIRE) + 1), [type(m).__name__ for _, m in gated.items]
    assert all(cid == client.client_id for cid, _ in gated.items)
    kinds = [*WIRE, "ViewerCameraMessage"]
    assert [type(m) for _, m in gated.items] == [getattr(compat, kind) for kind in kinds]
    assert [getattr(m, "uuid", None) for _, m in gated.items][:3] == ["u1", "u2", "u3"]


# -- element_id, shared_input(s), is_shared_command --------------------------------------------
def test_an_element_id_is_the_id_a_client_uses_for_it(
    server: viser.ViserServer, clients: Clients, probes: list[ProbeClient]
) -> None:
    slider = server.gui.add_slider("Shared", 0.0, 1.0, 0.1, 0.5)
    command = server.gui.add_command("Shared command")
    triggered = Seen()
    command.on_trigger(lambda _: triggered.add("shared"))
    probe, client = connect(server, clients, probes)
    own = client.gui.add_button("Own")
    # The id on the wire (and the one the page gives the element's root as its DOM id).
    assert probe.input_uuid("Shared", TIMEOUT_S) == compat.element_id(slider)
    assert probe.input_uuid("Own", TIMEOUT_S) == compat.element_id(own)
    # A command's id is the one a client triggers it by.
    probe.send({"type": "CommandTriggerMessage", "uuid": compat.element_id(command)})
    assert triggered.wait_for(lambda t: t == ["shared"])


def test_shared_input_finds_the_servers_inputs_only(
    server: viser.ViserServer, clients: Clients, probes: list[ProbeClient]
) -> None:
    slider = server.gui.add_slider("Shared", 0.0, 1.0, 0.1, 0.5)
    _, client = connect(server, clients, probes)
    own = client.gui.add_button("Own")
    shared_id, own_id = compat.element_id(slider), compat.element_id(own)
    assert compat.shared_input(server, shared_id) is slider
    assert compat.shared_input(server, own_id) is None  # a client's own widget is no shared input
    assert compat.shared_input(server, "no-such-id") is None
    inputs = compat.shared_inputs(server)
    assert inputs[shared_id] is slider and own_id not in inputs
    inputs.clear()  # a copy
    assert compat.shared_input(server, shared_id) is slider
    slider.remove()
    assert compat.shared_input(server, shared_id) is None and shared_id not in compat.shared_inputs(server)


def test_is_shared_command_knows_the_servers_commands_only(
    server: viser.ViserServer, clients: Clients, probes: list[ProbeClient]
) -> None:
    command = server.gui.add_command("Shared command")
    slider = server.gui.add_slider("Shared", 0.0, 1.0, 0.1, 0.5)
    _, client = connect(server, clients, probes)
    own_command = client.gui.add_command("Own command")
    assert compat.is_shared_command(server, compat.element_id(command))
    assert not compat.is_shared_command(server, compat.element_id(own_command))
    assert not compat.is_shared_command(server, compat.element_id(slider))  # an input, not a command
    command.remove()
    assert not compat.is_shared_command(server, compat.element_id(command))


# -- update_for_client ------------------------------------------------------------------------------
def test_an_update_for_one_client_reaches_that_client_only(
    server: viser.ViserServer, clients: Clients, probes: list[ProbeClient]
) -> None:
    slider = server.gui.add_slider("Shared", 0.0, 1.0, 0.1, 0.5)
    uuid = compat.element_id(slider)
    a, client_a = connect(server, clients, probes)
    b, _ = connect(server, clients, probes)
    compat.update_for_client(client_a, uuid, {"disabled": True})
    # Broadcast after it: had the update gone to everyone, b would get it before this.
    slider.label = "Marker"
    assert a.wait_for(lambda p: p.gui_updates.get(uuid, {}).get("disabled") is True), a.gui_updates.get(uuid)
    assert b.wait_for(lambda p: p.gui_updates.get(uuid, {}).get("label") == "Marker")
    assert "disabled" not in b.gui_updates[uuid]
    assert slider.disabled is False  # the server's state is untouched


# -- sets_disabled, with_disabled, rewrite_shared ---------------------------------------------------
def shown(probe: ProbeClient, uuid: str) -> dict[str, Any]:
    """An element's properties as the page shows them: as created, then as last updated."""
    with probe._lock:
        return {**probe.gui[uuid]["props"], **probe.gui_updates.get(uuid, {})}


def every_input(gui: viser.GuiApi) -> list[Any]:
    """One GUI input of each kind viser offers."""
    return [
        gui.add_slider("slider", 0.0, 1.0, 0.1, 0.5),
        gui.add_multi_slider("multi", 0.0, 1.0, 0.1, (0.2, 0.8)),
        gui.add_number("number", 1.0),
        gui.add_text("text", "t"),
        gui.add_checkbox("checkbox", False),
        gui.add_button("button"),
        gui.add_upload_button("upload"),
        gui.add_button_group("group", ("A", "B")),
        gui.add_dropdown("dropdown", ("a", "b")),
        gui.add_vector2("vector2", (0.0, 0.0)),
        gui.add_vector3("vector3", (0.0, 0.0, 0.0)),
        gui.add_rgb("rgb", (1, 2, 3)),
        gui.add_rgba("rgba", (1, 2, 3, 4)),
    ]


def test_a_rewrite_changes_what_one_client_is_sent_of_the_shared_gui_in_order_and_nothing_shared(
    server: viser.ViserServer, clients: Clients, probes: list[ProbeClient]
) -> None:
    """The roles grey a viewer's controls as they are built: the creation itself arrives greyed
    (a per-client update sent beside it could arrive first and be lost, update_for_client)."""
    before = server.gui.add_slider("Before", 0.0, 1.0, 0.1, 0.5)  # replayed through the rewrite too
    greyed_for: set[int] = set()
    seen: list[tuple[str, bool]] = []

    def grey(client_id: int, message: Any) -> Any:
        found = compat.sets_disabled(message)
        if found is None or client_id not in greyed_for:
            return message
        seen.append(found)
        return compat.with_disabled(message, True)

    compat.rewrite_shared(server, grey)
    a, client_a = connect(server, clients, probes)
    b, _ = connect(server, clients, probes)
    greyed_for.add(client_a.client_id)
    inputs = every_input(server.gui)
    note = server.gui.add_markdown("no input")  # nothing to grey: sent as it is
    ids = [compat.element_id(h) for h in inputs]
    for probe in (a, b):
        assert probe.wait_for(lambda p: all(uuid in p.gui for uuid in [*ids, compat.element_id(note)]))
    assert [shown(a, uuid)["disabled"] for uuid in ids] == [True] * len(ids), "a creation reached a ungreyed"
    assert [shown(b, uuid)["disabled"] for uuid in ids] == [False] * len(ids)
    assert sorted(seen) == sorted((uuid, False) for uuid in ids)
    assert not any(h.disabled for h in inputs), "the server's state changed"
    assert shown(a, compat.element_id(before))["disabled"] is False  # a replayed it before it was greyed

    # A broadcast `disabled` goes through it too (viser keeps the last of two updates of one property).
    slider, box = inputs[0], inputs[3]
    slider.disabled = True
    slider.disabled = False
    box.label = "box"  # broadcast after it
    uid = compat.element_id(slider)
    for probe in (a, b):
        assert probe.wait_for(lambda p: shown(p, compat.element_id(box))["label"] == "box")
    assert shown(a, uid)["disabled"] is True and shown(b, uid)["disabled"] is False
    assert seen[-1] == (uid, False)

    # A later client replays the shared messages as they were built: the rewrite changed none.
    c, _ = connect(server, clients, probes)
    assert c.wait_for(lambda p: all(uuid in p.gui for uuid in ids))
    assert [shown(c, uuid)["disabled"] for uuid in ids] == [False] * len(ids)
    # Leaving releases viser's own generator (its cursor), as without the rewrite.
    a.close()
    assert clients.wait_left(client_a.client_id)
    assert wait_until(lambda: compat.broadcast_sent(server, client_a.client_id) == -1, TIMEOUT_S)


def test_a_rewrite_that_raises_sends_the_message_unchanged(
    server: viser.ViserServer, clients: Clients, probes: list[ProbeClient]
) -> None:
    def broken(client_id: int, message: Any) -> Any:
        if compat.sets_disabled(message) is not None:
            raise RuntimeError("broken rewrite")
        return message

    compat.rewrite_shared(server, broken)
    a, _ = connect(server, clients, probes)
    slider = server.gui.add_slider("Late", 0.0, 1.0, 0.1, 0.5)
    slider.value = 0.7
    uuid = compat.element_id(slider)
    assert a.wait_for(lambda p: p.gui_updates.get(uuid, {}).get("value") == 0.7), "the connection stopped"
    assert shown(a, uuid)["disabled"] is False and not a.closed


# -- run_javascript --------------------------------------------------------------------------------
# That a page runs the source, and that CHART_INSTANCE_JS finds a chart there, takes a browser:
# tests/test_charts_e2e.py.
def test_a_script_for_one_client_reaches_that_client_only_and_no_later_one(
    server: viser.ViserServer, clients: Clients, probes: list[ProbeClient]
) -> None:
    a, client_a = connect(server, clients, probes)
    b, _ = connect(server, clients, probes)
    compat.run_javascript(client_a, "window.__marker = 1;")
    slider = server.gui.add_slider("After", 0.0, 1.0, 0.1, 0.5)  # broadcast after it
    uuid = compat.element_id(slider)
    assert a.wait_for(lambda p: p.scripts == ["window.__marker = 1;"]), a.scripts
    assert b.wait_for(lambda p: uuid in p.gui) and b.scripts == []
    c, _ = connect(server, clients, probes)  # a later client replays the shared scene only
    assert c.wait_for(lambda p: uuid in p.gui) and c.scripts == []


def test_a_send_to_a_client_that_just_closed_is_lost_without_a_warning(
    server: viser.ViserServer, clients: Clients, probes: list[ProbeClient]
) -> None:
    """The chart feed and the roles check `connection_closed` and then send: a page that closes in
    between must not make viser warn (its warning is for handles leaking onto dead connections)."""
    slider = server.gui.add_slider("Shared", 0.0, 1.0, 0.1, 0.5)
    a, client_a = connect(server, clients, probes)
    own = client_a.gui.add_markdown("this page's own")  # as roles' view of a seat
    a.close()
    assert wait_until(lambda: compat.connection_closed(client_a), TIMEOUT_S)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        compat.run_javascript(client_a, "window.__marker = 1;")
        compat.update_for_client(client_a, compat.element_id(slider), {"disabled": True})
        with compat.page_may_close(client_a):  # as feedback.notify tells one page
            client_a.add_notification("Refused", "told to a page that closed")
            own.content = "updated on a page that closed"
    # An ordinary send to that page is what viser warns about: the check above can fail.
    with pytest.warns(UserWarning, match="never be delivered"):
        client_a.gui.add_markdown("late")


# -- broadcast_mark, broadcast_sent ---------------------------------------------------------------
def test_the_broadcast_cursor_reaches_the_mark_as_the_replay_is_sent(
    server: viser.ViserServer, clients: Clients, probes: list[ProbeClient]
) -> None:
    for i in range(300):  # a replay of several windows (viser sends at most 128 messages in one)
        server.gui.add_checkbox(f"box {i}", False)
    last = server.gui.add_markdown("the last shared element")
    mark = compat.broadcast_mark(server)
    assert mark >= 300
    assert compat.broadcast_sent(server, 10_000) == -1  # no such client
    probe, client = connect(server, clients, probes)
    assert probe.wait_for(lambda p: compat.element_id(last) in p.gui), "the replay never ended"
    assert wait_until(lambda: compat.broadcast_sent(server, client.client_id) >= mark, TIMEOUT_S)
    assert compat.broadcast_sent(server, client.client_id) <= compat.broadcast_mark(server)
    server.gui.add_markdown("one more")
    assert compat.broadcast_mark(server) > mark
    probe.close()
    assert clients.wait_left(client.client_id)
    assert compat.broadcast_sent(server, client.client_id) == -1


# -- connection_closed ------------------------------------------------------------------------------
def test_a_closed_connection_says_so_at_once_even_while_viser_still_lists_the_client(
    server: viser.ViserServer, clients: Clients, probes: list[ProbeClient]
) -> None:
    a, client_a = connect(server, clients, probes)
    _, client_b = connect(server, clients, probes)
    _, client_c = connect(server, clients, probes)
    everyone = (client_a, client_b, client_c)
    assert not any(compat.connection_closed(c) for c in everyone)
    # What the dashboard's own disconnect callback sees of the others (it updates their widgets).
    seen = Seen()

    async def left(gone: viser.ClientHandle) -> None:
        listed = server.get_clients()
        seen.add(
            (gone.client_id, {c.client_id: (compat.connection_closed(c), c.client_id in listed) for c in everyone})
        )

    server.on_client_disconnect(left)
    a.close()
    assert seen.wait_for(lambda s: len(s) == 1)
    assert seen.items[0] == (
        client_a.client_id,
        {client_a.client_id: (True, False), client_b.client_id: (False, True), client_c.client_id: (False, True)},
    )
    # b and c still connected. stop() marks their buffers done from this thread while the server's
    # loop already tears the connections down, so one's callback may still see the other open (1
    # run in 15 under load): only the page that leaves is sure to read closed in its own callback.
    server.stop()
    assert seen.wait_for(lambda s: len(s) == 3)
    for gone, view in seen.items[1:]:
        assert view[gone][0], (gone, view)
    assert all(compat.connection_closed(c) for c in everyone)
    print(f"\nlisted by get_clients() in the callbacks while stopping: {[v for _, v in seen.items[1:]]}")


# -- on_connection_open, on_connection_close, close_connections ----------------------------------
def refused_code(url: str) -> int:
    """Open a websocket as a browser would; the close code the server sent. Fails if any data arrives."""
    with (
        ws_client.connect(url, subprotocols=[f"viser-v{viser.__version__}"], open_timeout=10) as socket,  # type: ignore[list-item]
        pytest.raises(websockets.exceptions.ConnectionClosed) as closed,
    ):
        data = socket.recv(timeout=TIMEOUT_S)
        pytest.fail(f"a refused client received {len(data)} bytes")
    assert closed.value.rcvd is not None, "the server did not close the connection"
    return closed.value.rcvd.code


def test_the_open_hook_sees_path_and_peer_first_and_closing_there_sends_nothing(
    server: viser.ViserServer, clients: Clients, probes: list[ProbeClient]
) -> None:
    openings, closings = Seen(), Seen()

    async def opened(opening: compat.Opening) -> None:
        openings.add(opening)
        if "token=ok" not in opening.path:
            await opening.close(1008, "token required")

    async def closed(client_id: int) -> None:
        closings.add(client_id)

    compat.on_connection_open(server, opened)
    compat.on_connection_close(server, closed)
    assert refused_code(f"ws://{HOST}:{server.get_port()}/?token=bad") == 1008
    refused = openings.items[0]
    assert (refused.path, refused.address) == ("/?token=bad", HOST)
    assert closings.wait_for(lambda ids: refused.client_id in ids)

    probe, client = connect(server, clients, probes, path="/?token=ok")
    assert probe.wait_for(lambda p: p.frames > 0)
    assert [(o.client_id, o.path) for o in openings.items[1:]] == [(client.client_id, "/?token=ok")]
    assert [c.client_id for c in clients.joined.items] == [client.client_id]  # the refused one never joined


def test_close_connections_closes_every_open_websocket(
    server: viser.ViserServer, clients: Clients, probes: list[ProbeClient]
) -> None:
    a, client_a = connect(server, clients, probes)
    b, client_b = connect(server, clients, probes)
    compat.close_connections(server)
    assert a.wait_for(lambda p: p.closed, TIMEOUT_S) and b.wait_for(lambda p: p.closed, TIMEOUT_S)
    assert clients.wait_left(client_a.client_id) and clients.wait_left(client_b.client_id)
