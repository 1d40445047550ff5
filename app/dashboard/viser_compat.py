"""Every touch of viser's private internals, one small function each, version-checked when imported.

viser 1.1 has no public hook for what these do; each says why at the line. The rest of the
dashboard calls these functions only (`bash /work/shared/tools/private_uses.sh` finds no other
touch). tests/test_viser_compat.py proves what each does against a real `ViserServer` and a
real websocket client, so a viser release that reroutes one of them fails there rather than,
say, silently letting a viewer's input through the read-only gate.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import inspect
import logging
from collections.abc import AsyncIterator, Awaitable, Callable, Iterator, Sequence
from typing import Any

import viser
import viser._messages as _messages
from viser.infra import Message

from hopper.versions import installed_version, require_series

log = logging.getLogger(__name__)

SERIES = "1.1"  # pyproject.toml pins viser>=1.1.1,<1.2; every touch below was read in viser 1.1.1


def check_version(found: str | None = None) -> None:
    """UnsupportedVersion unless the installed viser (or `found`) is a 1.1 release."""
    require_series("viser", SERIES, installed_version("viser") if found is None else found, module=__name__)


check_version()

# -- the messages a browser sends -------------------------------------------------------------
# viser decodes each incoming frame into one of these classes, which live in its private
# `_messages` module (only their base, viser.infra.Message, is public). The read-only gate sorts
# messages by them.
GuiUpdateMessage = _messages.GuiUpdateMessage  # a GUI input's new value (or, crafted, any property)
GuiButtonHoldMessage = _messages.GuiButtonHoldMessage  # a button held down, repeated
CommandTriggerMessage = _messages.CommandTriggerMessage  # a command palette entry or its hotkey
ViewerCameraMessage = _messages.ViewerCameraMessage  # the client's own camera
GetRenderResponseMessage = _messages.GetRenderResponseMessage  # an answer to the server's render request
ShareUrlRequest = _messages.ShareUrlRequest  # asks viser to open a public share tunnel
ShareUrlDisconnect = _messages.ShareUrlDisconnect  # closes it


# -- GUI elements -------------------------------------------------------------------------------
def element_id(handle: Any) -> str:
    """The id viser gives a GUI element: in its wire messages and as its root element's `id` in the page.

    Private: handles keep it in their `_impl` state; no public attribute names it.
    """
    return handle._impl.uuid


def shared_input(server: viser.ViserServer, uuid: str) -> viser.GuiInputHandle | None:
    """The server-scope GUI input with this id, None if it is no such input (or was removed).

    Private: viser keeps the registry it dispatches updates by in `GuiApi._gui_input_handle_from_uuid`
    and has no public lookup or listing of a GuiApi's elements.
    """
    return server.gui._gui_input_handle_from_uuid.get(uuid)


def shared_inputs(server: viser.ViserServer) -> dict[str, viser.GuiInputHandle]:
    """Every server-scope GUI input by id, a copy (see `shared_input`)."""
    return dict(server.gui._gui_input_handle_from_uuid)


def is_shared_command(server: viser.ViserServer, uuid: str) -> bool:
    """Whether this id names a server-scope command (command palette). Private: as `shared_input`."""
    return uuid in server.gui._command_handle_from_uuid


def connection_closed(client: viser.ClientHandle) -> bool:
    """Whether the client's connection has closed: anything queued for it now is lost (and viser warns).

    Private: `server.get_clients()` keeps listing a client until viser's disconnect callback has
    run, after its connection closed (and every client while the server stops); only the
    connection's message buffer (`_websock_connection`, its `done` flag) says so at once.
    """
    return client._websock_connection.get_message_buffer().done


def update_for_client(client: viser.ClientHandle, uuid: str, updates: dict[str, Any]) -> None:
    """Set properties of a shared GUI element in one client's page only (the server's state is untouched).

    Private: viser's handles only broadcast; a per-client change of a shared element (greying it
    for a viewer) needs the client's own message queue, `ClientHandle._websock_connection`.
    """
    _send(client, GuiUpdateMessage(uuid, updates))


def sets_disabled(message: Message) -> tuple[str, bool] | None:
    """(element id, disabled) if `message` creates a GUI input or updates a GUI element's `disabled`; else None.

    Private: the GUI's creation messages share a base, `_CreateGuiComponentMessage`, in viser's
    `_messages`; of their `props`, the inputs' (`GuiBaseProps`) are the ones with `disabled`.
    """
    if isinstance(message, _messages._CreateGuiComponentMessage):
        disabled = getattr(getattr(message, "props", None), "disabled", None)
        return None if disabled is None else (message.uuid, bool(disabled))
    if isinstance(message, GuiUpdateMessage) and "disabled" in message.updates:
        return message.uuid, bool(message.updates["disabled"])
    return None


def with_disabled(message: Message, disabled: bool) -> Message:
    """A copy of a message that `sets_disabled` names, setting `disabled` instead (the original is untouched:
    the shared one is replayed to later clients, and a creation's props are its handle's own state).
    """
    new = copy.copy(message)
    if hasattr(new, "updates"):
        new.updates = {**new.updates, "disabled": disabled}  # type: ignore[attr-defined]
    else:
        new.props = copy.copy(new.props)  # type: ignore[attr-defined]
        new.props.disabled = disabled  # type: ignore[attr-defined]
    return new


# -- code for one page ---------------------------------------------------------------------------
# The page's uPlot instance of a chart, by the chart's element id (a JavaScript function expression).
# Private: viser 1.1's client registers every inline chart it creates under
# `window.__viserTestpoints.uplots[uuid].chart` (components/UplotComponent.tsx, for its own end-to-end
# tests) and offers no other way to reach one; a chart in the expand dialog is not registered.
CHART_INSTANCE_JS = "((uuid) => window.__viserTestpoints?.uplots?.[uuid]?.chart)"


def run_javascript(client: viser.ClientHandle, source: str) -> None:
    """Run `source` in this one client's page, in order with the client's other messages.

    Private: viser's client runs a RunJavascriptMessage's source as it arrives (MessageHandler.tsx,
    `new Function(source)()`), but only viser itself sends one (to load plotly.js, into the shared
    scene that every new client replays); here it goes on the client's own queue, which keeps nothing
    for later clients.
    """
    _send(client, _messages.RunJavascriptMessage(source=source))


def _send(client: viser.ClientHandle, message: Message) -> None:
    """Queue `message` on one client's connection, best effort (see page_may_close)."""
    with page_may_close(client):
        client._websock_connection.queue_message(message)


@contextlib.contextmanager
def page_may_close(client: viser.ClientHandle) -> Iterator[None]:
    """Sends to `client` inside the block are lost without a warning if its page has just closed.

    The page may close between a caller's `connection_closed` check (or viser's own) and the send:
    the message is then lost with the page, which is fine, so the sends are viser's sanctioned dead
    writes (`sanctioned_dead_writes`, as its own scene removals use) rather than a warning, which is
    for handles leaking onto dead connections. Private: the buffer is `_websock_connection`'s.
    """
    with client._websock_connection.get_message_buffer().sanctioned_dead_writes():
        yield


# -- incoming messages ----------------------------------------------------------------------------
Gate = Callable[[int, Message], bool]


def gate_incoming(server: viser.ViserServer, allows: Gate) -> None:
    """Run `allows(client_id, message)` on every message a client sends, before the server-scope handlers.

    False drops the message for them (the server GUI's callbacks, the camera's, ...). The sending
    client's own handlers (its `client.gui` widgets) still get it: viser hands every message to
    the server's dispatcher and to the client connection's, and only the first passes here. Gates
    stack: each new one runs before the ones installed earlier. An exception in `allows` drops
    the message (and viser logs it).

    Private: no public hook sees a message before viser acts on it, so this replaces the
    websocket server's dispatcher, `WebsockServer._handle_incoming_message`, which viser's
    connection handler looks up on the instance for every message it receives.
    """
    ws = server._websock_server
    dispatch = ws._handle_incoming_message
    if not inspect.iscoroutinefunction(dispatch):
        raise TypeError(f"viser's incoming-message dispatcher is no coroutine function: {dispatch!r}")

    async def gated(client_id: int, message: Message) -> None:
        if allows(client_id, message):
            await dispatch(client_id, message)

    ws._handle_incoming_message = gated


# -- the shared scene as each client gets it ------------------------------------------------------------
Rewrite = Callable[[int, Message], Message]


def rewrite_shared(server: viser.ViserServer, rewrite: Rewrite) -> None:
    """Send each client `rewrite(client_id, message)` instead of each shared message, as it leaves for it.

    For what one page must see differently of a shared element from the moment it exists (a viewer's
    controls greyed), in order with everything else shared: a per-client update could overtake the
    element's creation and be lost (see `broadcast_sent`). `rewrite` runs on viser's event loop, once
    per message and client, so it must be quick and not wait for locks; it returns the message itself
    or a new one (never change the shared one: later clients replay it). Should it raise, the client
    gets the message unchanged. Only connections opened after this call are rewritten.

    Private: viser sends every client the same shared messages and has no per-client hook; each
    connection reads the broadcast buffer (`_websock_server._broadcast_buffer`) through its own
    `window_generator(client_id, ...)`, which viser's message producer looks up on the buffer
    instance as the connection opens; this wraps it.
    """
    buffer = server._websock_server._broadcast_buffer
    make = buffer.window_generator
    if not callable(make):
        raise TypeError(f"viser's broadcast buffer has no window generator: {make!r}")

    def window_generator(client_id: int, *args: Any, **kwargs: Any) -> AsyncIterator[Sequence[Message]]:
        # Made now, not at the first window: viser captures the replay's end here.
        return _rewritten(make(client_id, *args, **kwargs), client_id, rewrite)

    buffer.window_generator = window_generator


async def _rewritten(windows: Any, client_id: int, rewrite: Rewrite) -> AsyncIterator[Sequence[Message]]:
    try:
        async for window in windows:
            yield [_rewrite_one(rewrite, client_id, message) for message in window]
    finally:  # closed with the connection: viser's own generator releases its cursor then
        await windows.aclose()


def _rewrite_one(rewrite: Rewrite, client_id: int, message: Message) -> Message:
    try:
        return rewrite(client_id, message)
    except Exception:
        log.exception("rewriting a %s for client %s failed; sent unchanged", type(message).__name__, client_id)
        return message


# -- replay of the shared scene to a new client ----------------------------------------------------
def broadcast_mark(server: viser.ViserServer) -> int:
    """The number of the latest message queued for every client (the shared scene and GUI), -1 if none.

    Private, as `broadcast_sent`.
    """
    return server._websock_server._broadcast_buffer.message_counter - 1


def broadcast_sent(server: viser.ViserServer, client_id: int) -> int:
    """The number of the latest shared message handed to this client's connection, -1 if none (or gone).

    A new client first gets the replay of everything shared, on a queue of its own apart from
    its per-client messages; a per-client update for an element the page has not created yet is
    lost. Private: viser tracks how far each connection has read the shared queue only in its
    broadcast buffer's `generator_cursors`; its end-of-replay marker goes to the browser alone.
    """
    return server._websock_server._broadcast_buffer.generator_cursors.get(client_id, -1)


# -- websockets as they open -------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Opening:
    """A websocket that has just opened: nothing has been sent to it yet."""

    client_id: int
    path: str  # the request's path with its query string
    address: str  # the peer's IP address ("?" if unknown)
    close: Callable[[int, str], Awaitable[None]]  # close(code, reason): the client gets nothing at all


def on_connection_open(server: viser.ViserServer, callback: Callable[[Opening], Awaitable[None]]) -> None:
    """Call `callback` (awaited on viser's event loop) as each websocket opens, before viser sends it anything.

    Private: `ViserServer.on_client_connect` runs only after the browser's first camera message,
    once the scene's replay has been sent; only the websocket layer (`_websock_server`) calls back
    before that, and only its `_live_connections` hold the request (path, peer) to check.
    """
    ws = server._websock_server

    async def opened(conn: Any) -> None:
        connection = ws._live_connections.get(conn.client_id)
        if connection is None:  # gone already
            return
        path = connection.request.path if connection.request is not None else "/"
        address = str(connection.remote_address[0]) if connection.remote_address else "?"
        await callback(Opening(conn.client_id, path, address, connection.close))

    ws.on_client_connect(opened)


def on_connection_close(server: viser.ViserServer, callback: Callable[[int], Awaitable[None]]) -> None:
    """Call `callback(client_id)` (awaited on viser's event loop) as each websocket closes, opened or refused.

    Private: the websocket layer, as `on_connection_open`; `on_client_disconnect` misses
    connections that never became clients.
    """

    async def closed(conn: Any) -> None:
        await callback(conn.client_id)

    server._websock_server.on_client_disconnect(closed)


def close_connections(server: viser.ViserServer) -> None:
    """Close every open websocket (the pages reconnect at once). Private: the websocket layer, as above."""
    server._websock_server.disconnect_all_clients()
