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
from typing import Any

import viser
from hopper.app.dashboard import viser_compat as compat

log = logging.getLogger(__name__)
# viser's handles for which a browser sends a press (True) or, in a group, one of its options.
BUTTONS = (viser.GuiButtonHandle, viser.GuiButtonGroupHandle, viser.GuiUploadButtonHandle)


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


def problem(handle: viser.GuiInputHandle, updates: object) -> str | None:
    """Why a browser's `updates` for this control must be dropped; None if fine."""
    if not isinstance(updates, dict) or set(updates) != {"value"}:
        return f"updates {sorted(updates) if isinstance(updates, dict) else type(updates).__name__} are not a value"
    if getattr(handle, "disabled", False):
        return "the control is disabled"
    value = updates["value"]
    options = getattr(handle, "options", None)
    if isinstance(handle, BUTTONS):  # a button sends True; a button group one of its options
        ok = isinstance(value, str) if options is not None else value is True
        return None if ok else f"a button sent {value!r}"
    if not _same_kind(handle.value, value):
        return f"a {type(value).__name__} for a {type(handle.value).__name__} control"
    if options is not None and value not in options:  # a dropdown
        return f"{value!r} is not one of its options"
    return None


def guard_gui_updates(server: viser.ViserServer) -> None:
    """Check every GUI update a browser sends before viser applies it to a shared control (once, at start)."""

    def allows(client_id: int, message: Any) -> bool:
        if not isinstance(message, compat.GuiUpdateMessage):
            return True
        handle = compat.shared_input(server, message.uuid)
        if handle is None:  # a client's own widget (its handlers are not gated) or no control at all
            return True
        why = problem(handle, message.updates)
        if why is not None:
            log.info("dropped a GUI update from client %s for %r: %s", client_id, getattr(handle, "label", "?"), why)
        return why is None

    compat.gate_incoming(server, allows)
