"""Check browser GUI updates on the wire, before viser applies them: only a value, of the control's own type.

viser applies a GuiUpdateMessage's `updates` as they come: any property (label, min, max,
disabled, ...) and a value cast with the control's type, so that "false" or 1 ticks a checkbox
(bool("false") is True) and True moves a slider to 1.0. Worse, any key names
a field of viser's handle state: {"removed": true} or {"update_cb": 0} would silently kill a
control for everyone. A browser only ever sends {"value": v} with v of the control's type (viser's client, ControlPanel/
Generated.tsx and components/), so anything else is malformed and dropped here, logged, before
it can change a setting. Values of the right type still go through the callbacks' own range
checks (hopper.app.dashboard.feedback), which clamp or refuse with a notification.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Coroutine
from typing import Any

import viser
from viser._messages import GuiUpdateMessage

log = logging.getLogger(__name__)

Handler = Callable[[Any, GuiUpdateMessage], Coroutine[Any, Any, None]]


def _same_kind(current: object, value: object) -> bool:
    """Whether a browser `value` has the type of the control's `current` value (ints pass as floats)."""
    if isinstance(current, bool):
        return isinstance(value, bool)
    if isinstance(current, (int, float)):
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if isinstance(current, str):  # a number typed into a text box reads as its text, as viser makes it
        return isinstance(value, (str, int, float)) and not isinstance(value, bool)
    if isinstance(current, tuple):
        return (
            isinstance(value, (list, tuple))
            and len(value) == len(current)
            and all(_same_kind(c, v) for c, v in zip(current, value, strict=True))
        )
    return type(value) is type(current)


def problem(state: Any, updates: object) -> str | None:
    """Why a browser's `updates` for a control in `state` (viser's handle state) must be dropped; None if fine."""
    if not isinstance(updates, dict) or set(updates) != {"value"}:
        return f"updates {sorted(updates) if isinstance(updates, dict) else type(updates).__name__} are not a value"
    props = state.props
    if getattr(props, "disabled", False):
        return "the control is disabled"
    value = updates["value"]
    options = getattr(props, "options", None)
    if state.is_button:  # a button sends True; a button group one of its options
        ok = isinstance(value, str) if options is not None else value is True
        return None if ok else f"a button sent {value!r}"
    if not _same_kind(state.value, value):
        return f"a {type(value).__name__} for a {type(state.value).__name__} control"
    if options is not None and value not in options:  # a dropdown
        return f"{value!r} is not one of its options"
    return None


def guard_gui_updates(server: viser.ViserServer) -> None:
    """Put the check in front of the server GUI's update handler (once, after the server starts)."""
    gui = server.gui
    websock = server._websock_server  # viser offers no public hook before an update is applied
    original: Handler = gui._handle_gui_updates  # type: ignore[assignment]

    async def checked(client_id: Any, message: GuiUpdateMessage) -> None:
        handle = gui._gui_input_handle_from_uuid.get(message.uuid)
        if handle is None:
            return
        why = problem(handle._impl, message.updates)
        if why is not None:
            label = getattr(handle._impl.props, "label", "?")
            log.info("dropped a GUI update from client %s for %r: %s", client_id, label, why)
            return
        await original(client_id, message)

    websock.unregister_handler(GuiUpdateMessage, original)
    websock.register_handler(GuiUpdateMessage, checked)
