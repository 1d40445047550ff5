"""Help: a button that opens static/help.md in a modal for the client who asked."""

from __future__ import annotations

import viser
from hopper.app.dashboard.feedback import guarded


def build_help_button(gui: viser.GuiApi, markdown: str) -> viser.GuiButtonHandle:
    button = gui.add_button("Help", icon=viser.Icon.HELP_CIRCLE, hint="What everything does")

    @guarded
    def on_click(event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        with event.client.gui.add_modal("Help") as modal:
            event.client.gui.add_markdown(markdown)
            event.client.gui.add_button("Close").on_click(lambda _: modal.close())

    button.on_click(on_click)
    return button
