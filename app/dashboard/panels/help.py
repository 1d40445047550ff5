"""Help: a button that opens static/help.md in a modal for the client who asked; Close or Esc closes it."""

from __future__ import annotations

import threading

import viser
from hopper.app.dashboard.feedback import guarded


def build_help_button(gui: viser.GuiApi, markdown: str) -> viser.GuiButtonHandle:
    button = gui.add_button("Help", icon=viser.Icon.HELP_CIRCLE, hint="What everything does")

    @guarded
    def on_click(event: viser.GuiEvent) -> None:
        client = event.client
        if client is None:
            return
        with client.gui.add_modal("Help") as modal:
            client.gui.add_markdown(markdown)
            close_button = client.gui.add_button("Close", hint="Or press Esc")
        # viser's modal ignores Esc (only the server may close it), so Esc is a hotkey for this
        # client, there only while the modal is open.
        escape = client.gui.add_command("Close help", description="Esc", hotkey="escape")
        once = threading.Lock()

        def close(_: object) -> None:
            if once.acquire(blocking=False):  # Close and Esc together close it once
                modal.close()
                escape.remove()

        close_button.on_click(guarded(close))
        escape.on_trigger(guarded(close))

    button.on_click(on_click)
    return button
