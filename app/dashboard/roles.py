"""Roles in a shared session: one operator changes the settings, every other client watches read-only.

The authority is on the server: every message a browser sends passes `Roles.allows` before viser
dispatches it, so a viewer's crafted GUI update is dropped however it was made; the greyed
controls (viser's `disabled`, for that client alone) only say so, on every control it gets: those
on its page when its role changes are updated, and one built later for everyone (a controller's
params) reaches a viewer greyed (`_as_seen_by`). The first client to connect operates; a viewer
may ask for control and the operator hands it over; an operator who leaves or sends no input for
`idle_timeout_s` passes it to the first who asked, else to the longest connected viewer. Every
change is an OperatorChanged event (log and recordings).
"""

from __future__ import annotations

import asyncio
import dataclasses
import html
import logging
import math
import threading
import time
from collections.abc import Callable, Iterable
from typing import Any

import viser
from hopper.app.dashboard import viser_compat as compat
from hopper.app.dashboard.access import Gatekeeper
from hopper.app.dashboard.feedback import guarded, notify

from hopper.events import OperatorChanged, OperatorReason
from hopper.sim import Command, Simulation

log = logging.getLogger(__name__)

IDLE_TIMEOUT_S = 300.0  # s without input before an operator's control passes to a viewer
READ_ONLY_NOTICE_S = 5.0  # s between a viewer's 'Read-only' notices (its refused inputs are each undone)
REPLAY_WAIT_S = 20.0  # s at most to wait for a new client's replay of the scene before greying its controls
REPLAY_MARGIN_S = 0.2  # s after viser has queued the replay's last window, for it to be sent
# Per-client, harmless from anyone: the camera, and answers to the server's own requests.
VIEWER_MESSAGES = (compat.ViewerCameraMessage, compat.GetRenderResponseMessage)
# Allowed from a viewer when they name one of the viewer-safe inputs (Help, Side view).
INPUT_MESSAGES = (compat.GuiUpdateMessage, compat.GuiButtonHoldMessage)
# Refused from everyone: a share tunnel would publish the session past --host and the token.
NEVER = (compat.ShareUrlRequest, compat.ShareUrlDisconnect)


@dataclasses.dataclass(frozen=True)
class Announce:
    """Command: put an OperatorChanged event in the simulation's log (on the loop thread)."""

    payload: OperatorChanged

    def apply(self, sim: Simulation) -> None:
        sim.emit(self.payload)


@dataclasses.dataclass
class ControlView:
    """One client's own widgets in the Control folder: who operates, Ask for control, Hand over."""

    line: viser.GuiHtmlHandle
    ask: viser.GuiButtonHandle
    hand: viser.GuiButtonHandle


@dataclasses.dataclass
class Seat:
    client: viser.ClientHandle
    name: str  # "client 3 (127.0.0.1)"
    may_operate: bool  # False: a --public-view client without the token
    view: ControlView | None = None  # built once the client has the scene
    read_only: bool | None = None  # the greying last sent to this client (None: none yet)
    # Inputs built live that this client was sent greyed (its greying undoes them by id: viser may
    # send one before it lists the input among the shared ones)
    greyed: set[str] = dataclasses.field(default_factory=set)
    last_notice: float = -math.inf  # when it was last told it is read-only (clock s)


class Roles:
    """Who operates a viser server's shared GUI; install once, after every shared input exists."""

    def __init__(
        self,
        server: viser.ViserServer,
        submit: Callable[[Command], None],
        *,
        folder: viser.GuiFolderHandle,
        viewer_safe: Iterable[Any] = (),
        gatekeeper: Gatekeeper | None = None,
        idle_timeout_s: float = IDLE_TIMEOUT_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.server, self.submit, self.folder, self.gatekeeper = server, submit, folder, gatekeeper
        self.viewer_safe = frozenset(compat.element_id(handle) for handle in viewer_safe)
        self.idle_timeout_s, self.clock = idle_timeout_s, clock
        self.operator: int | None = None
        self.refused = 0  # messages dropped from non-operators, for tests
        self._seats: dict[int, Seat] = {}  # in order of arrival: the first is the longest connected
        self._askers: list[int] = []
        self._last_input = clock()
        self._lock = threading.RLock()
        self._greying = threading.Lock()  # a seat's read_only and greyed, between _grey and _as_seen_by
        compat.gate_incoming(server, self.allows)  # every message, before viser's server-scope handlers
        compat.rewrite_shared(server, self._as_seen_by)  # every control built later, greyed as it is sent
        # Async: run on viser's event loop in the order they happen (thread-pool callbacks may not).
        server.on_client_connect(self._connected)
        server.on_client_disconnect(self._disconnected)

    # -- queries -----------------------------------------------------------------------------
    def name_of(self, client_id: int | None) -> str | None:
        with self._lock:
            seat = self._seats.get(client_id) if client_id is not None else None
            return seat.name if seat is not None else None

    @property
    def seated(self) -> list[int]:
        """Client ids in order of arrival (the first is the longest connected)."""
        with self._lock:
            return list(self._seats)

    @property
    def last_input(self) -> float:
        """The clock's time (s) of the operator's last input, or of the last change of operator."""
        with self._lock:
            return self._last_input

    @property
    def askers(self) -> list[int]:
        with self._lock:
            return list(self._askers)

    # -- the authority check (viser's event loop) ---------------------------------------------
    def allows(self, client_id: int, message: Any) -> bool:
        """Whether a message from this client may reach viser's handlers (and the simulation)."""
        if isinstance(message, NEVER):
            return False
        if isinstance(message, VIEWER_MESSAGES):
            return True
        with self._lock:
            if client_id == self.operator:
                self._last_input = self.clock()
                return True
            if not self._targets_shared(message):  # the client's own widgets (Ask for control, Help's Esc)
                return True
            if isinstance(message, INPUT_MESSAGES) and message.uuid in self.viewer_safe:
                return True
            self.refused += 1
            seat = self._seats.get(client_id)
        if seat is not None:
            self._refused(seat, message)
        return False

    # -- what each client is sent of the shared GUI (viser's event loop) ----------------------------
    def _as_seen_by(self, client_id: int, message: Any) -> Any:
        """A shared message as this client gets it: a viewer's copy of an input (or of its `disabled`) is
        greyed, from its creation on; the operator's is as built. Each panel builds its controls once,
        for everyone, whenever it likes (a controller's sliders as it flies): the role applies here."""
        found = compat.sets_disabled(message)
        if found is None or found[1] or found[0] in self.viewer_safe:
            return message
        seat = self._seats.get(client_id)  # no self._lock: the event loop must not wait on the roles
        if seat is None:  # still replaying the scene: greyed as a whole once seated (_after_replay)
            return message
        with self._greying:
            if not seat.read_only:
                return message
            seat.greyed.add(found[0])
        return compat.with_disabled(message, True)

    def _targets_shared(self, message: Any) -> bool:
        """Whether viser's server-scope handlers would act on it. viser hands every message to both
        the server's and the sending client's handlers; one for the client's own widgets finds
        nothing on the server's side, so it may pass (its own handler is not gated)."""
        if isinstance(message, INPUT_MESSAGES):
            return compat.shared_input(self.server, message.uuid) is not None
        if isinstance(message, compat.CommandTriggerMessage):
            return compat.is_shared_command(self.server, message.uuid)
        return True  # anything else from a viewer is refused

    def _refused(self, seat: Seat, message: Any) -> None:
        """Show the refused client what runs again (its widget may have moved) and why."""
        uuid = getattr(message, "uuid", None)
        handle = compat.shared_input(self.server, uuid) if isinstance(uuid, str) else None
        if handle is not None:
            _send(seat.client, uuid, {"value": handle.value})
        now = self.clock()
        if now - seat.last_notice < READ_ONLY_NOTICE_S:  # a drag or a held slider sends 20 a second
            return
        seat.last_notice = now
        operator = self.name_of(self.operator) or "nobody"
        notify(seat.client, "Read-only", f"{operator} operates; ask for control in the Control panel.", "warning")

    # -- changes -------------------------------------------------------------------------------
    def ask(self, client_id: int) -> None:
        """A viewer asks for control: the operator is told and may hand it over."""
        with self._lock:
            seat = self._seats.get(client_id)
            if seat is None or not seat.may_operate or client_id == self.operator or client_id in self._askers:
                return
            self._askers.append(client_id)
            operator = self._seats.get(self.operator) if self.operator is not None else None
            self._refresh()
        if operator is not None:
            notify(
                operator.client,
                f"{seat.name.capitalize()} asks for control",
                "Hand it over in the Control panel (it also passes after "
                f"{self.idle_timeout_s / 60:g} min without input).",
            )

    def hand_over(self, by: int, to: int | None = None) -> bool:
        """The operator `by` hands control to `to` (default: the next in line); False if not allowed."""
        with self._lock:
            if by != self.operator:
                return False
            target = to if to is not None else self._successor()
            if target is None or target == by or not self._eligible(target):
                return False
            self._transfer(target, "handed over")
            return True

    def poll(self, now: float | None = None) -> None:
        """Pass control on from an operator idle past the timeout (called often, from any thread)."""
        now = self.clock() if now is None else now
        with self._lock:
            if self.operator is None or now - self._last_input < self.idle_timeout_s:
                return
            successor = self._successor()
            if successor is not None:
                self._transfer(successor, "idle")

    # -- viser callbacks (event loop) -----------------------------------------------------------
    async def _connected(self, client: viser.ClientHandle) -> None:
        info = self.gatekeeper.info(client.client_id) if self.gatekeeper is not None else None
        if self.gatekeeper is not None and info is None:  # refused by the gate, or already gone
            return
        address = info.address if info is not None else "?"
        seat = Seat(client, f"client {client.client_id} ({address})", info is None or info.grant == "operate")
        with self._lock:
            self._seats[client.client_id] = seat
            if self.operator is None and seat.may_operate:
                self._transfer(client.client_id, "first")
            else:
                self._refresh()
        asyncio.get_running_loop().create_task(self._after_replay(seat))

    async def _disconnected(self, client: viser.ClientHandle) -> None:
        with self._lock:
            seat = self._seats.pop(client.client_id, None)
            if client.client_id in self._askers:
                self._askers.remove(client.client_id)
            if seat is None:
                return
            if client.client_id == self.operator:
                successor = self._successor()
                if successor is not None:
                    self._transfer(successor, "disconnected")
                else:
                    self.operator = None
                    self.submit(Announce(OperatorChanged(None, f"client {client.client_id}", "disconnected")))
            self._refresh()

    async def _after_replay(self, seat: Seat) -> None:
        """Build the client's widgets and grey its controls once it has the scene's GUI.

        A per-client update for a widget the browser has not created yet is dropped by it, and
        viser sends the replay of the shared scene and per-client messages on separate queues;
        so wait until the replay's last window has left (viser's own cursor of it).
        """
        target = compat.broadcast_mark(self.server)
        deadline = time.monotonic() + REPLAY_WAIT_S
        while compat.broadcast_sent(self.server, seat.client.client_id) < target and time.monotonic() < deadline:
            if seat.client.client_id not in self._seats:
                return
            await asyncio.sleep(0.05)
        await asyncio.sleep(REPLAY_MARGIN_S)
        with self._lock:
            if self._seats.get(seat.client.client_id) is not seat or _gone(seat.client):
                return
            try:
                seat.view = self._build_view(seat)
            except Exception:  # a client that left meanwhile
                log.debug("building the control view of %s failed", seat.name, exc_info=True)
                return
            self._show(seat)

    # -- internals (under the lock) ---------------------------------------------------------------
    def _eligible(self, client_id: int) -> bool:
        seat = self._seats.get(client_id)
        return seat is not None and seat.may_operate

    def _successor(self) -> int | None:
        """The first who asked, else the longest connected viewer who may operate."""
        for client_id in self._askers:
            if client_id != self.operator and self._eligible(client_id):
                return client_id
        for client_id, seat in self._seats.items():
            if client_id != self.operator and seat.may_operate:
                return client_id
        return None

    def _transfer(self, client_id: int, reason: OperatorReason) -> None:
        previous = self.operator
        self.operator = client_id
        self._last_input = self.clock()
        if client_id in self._askers:
            self._askers.remove(client_id)
        new = self._seats[client_id]
        old = self._seats.get(previous) if previous is not None else None
        # The one who operated before by number only: their address is in the event that named them.
        before = f"client {previous}" if previous is not None else None
        self.submit(Announce(OperatorChanged(new.name, before, reason)))
        log.info("operator: %s (%s)", new.name, reason)
        self._refresh()
        if reason != "first":
            notify(new.client, "You have control", "Your changes now drive the simulation.")
        if old is not None:
            why = " after a time without input" if reason == "idle" else ""
            notify(old.client, f"Control passed to {new.name}{why}", "Your controls are read-only; ask to get it back.")

    def _refresh(self) -> None:
        for seat in self._seats.values():
            self._show(seat)

    def _show(self, seat: Seat) -> None:
        """Bring one client's widgets and greying up to date (sends only what changed)."""
        if seat.view is None or _gone(seat.client):
            return
        try:
            self._grey(seat, seat.client.client_id != self.operator)
            line, ask, hand = self._texts(seat)
            view = seat.view
            with compat.page_may_close(seat.client):  # it may close after the check above
                if view.line.content != line:
                    view.line.content = line
                view.ask.visible = ask is not None
                if ask is not None:
                    view.ask.label, view.ask.disabled = ask
                view.hand.visible = hand is not None
                if hand is not None:
                    view.hand.label = hand
        except Exception:  # the client is leaving; its disconnect callback cleans up
            log.debug("updating the control view of %s failed", seat.name, exc_info=True)

    def _texts(self, seat: Seat) -> tuple[str, tuple[str, bool] | None, str | None]:
        """The role line, the Ask button's (label, disabled) or None, the Hand over label or None."""
        me, operator = seat.client.client_id, self.operator
        viewers = len(self._seats) - (operator is not None)
        if me == operator:
            line = f"<b class='hd-operator'>You operate</b> this session · {viewers} viewer{'s' * (viewers != 1)}"
            asking = [self._seats[c].name for c in self._askers if c in self._seats]
            if asking:
                line += f"<br>{html.escape(', '.join(asking))} {'asks' if len(asking) == 1 else 'ask'} for control"
            successor = self._successor()
            hand = None if successor is None else f"Hand over to {self._seats[successor].name}"
            return _div(line), None, hand
        who = html.escape(self._seats[operator].name) if operator in self._seats else "nobody"
        if not seat.may_operate:
            return _div(f"<b>Viewing</b> (no access token) · {who} operates"), None, None
        line = f"<b>Viewing</b> · {who} operates; your controls are read-only"
        if me in self._askers:
            return _div(line), ("Asked: waiting for the operator", True), None
        return _div(line), ("Ask for control", False), None

    def _grey(self, seat: Seat, read_only: bool) -> None:
        """Disable (or restore) every shared input but the viewer-safe ones, for this client alone."""
        if seat.read_only == read_only or (seat.read_only is None and not read_only):
            seat.read_only = read_only
            return
        with self._greying:  # what _as_seen_by greyed before is in `late`; what it sends after sees the change
            seat.read_only = read_only
            late, seat.greyed = seat.greyed, set()
        inputs = compat.shared_inputs(self.server)
        for uuid, handle in inputs.items():
            if uuid in self.viewer_safe:
                continue
            disabled = read_only or bool(getattr(handle, "disabled", False))
            _send(seat.client, uuid, {"disabled": disabled})
        if not read_only:  # greyed as sent, and not listed yet (or removed since: the page ignores those)
            for uuid in late - inputs.keys():
                _send(seat.client, uuid, {"disabled": False})

    def _build_view(self, seat: Seat) -> ControlView:
        gui, client_id = seat.client.gui, seat.client.client_id
        with self.folder:  # the client's own widgets, inside the shared folder
            view = ControlView(
                line=gui.add_html(""),
                ask=gui.add_button("Ask for control", icon=viser.Icon.HAND_STOP, visible=False),
                hand=gui.add_button("Hand over", icon=viser.Icon.ARROWS_EXCHANGE, color="gray", visible=False),
            )
        view.ask.on_click(guarded(lambda _: self.ask(client_id)))
        view.hand.on_click(guarded(lambda _: self.hand_over(client_id)))
        return view


def _div(content: str) -> str:
    return f"<div class='hd-role'>{content}</div>"


def _gone(client: viser.ClientHandle) -> bool:
    """Whether the client's connection has closed (viser warns about messages queued after that)."""
    return compat.connection_closed(client)


def _send(client: viser.ClientHandle, uuid: str, updates: dict[str, Any]) -> None:
    """Update a shared input in one client's page only (viser has no public per-client update of a shared widget)."""
    if _gone(client):
        return
    try:
        compat.update_for_client(client, uuid, updates)
    except Exception:
        log.debug("sending to client %s failed", client.client_id, exc_info=True)
