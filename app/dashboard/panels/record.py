"""Record panel: start/stop a rerun recording into the sessions folder and show where it went."""

from __future__ import annotations

import dataclasses
import html
from pathlib import Path

import viser
from hopper.app.dashboard.feedback import guarded, notify
from hopper.app.dashboard.recording import Recorder


@dataclasses.dataclass
class RecordPanel:
    record: viser.GuiButtonHandle
    stop: viser.GuiButtonHandle
    info: viser.GuiHtmlHandle

    def show(self, state: str, path: Path | None, message: str = "", viewer_url: str | None = None) -> None:
        recording = state in ("recording", "starting")
        self.record.visible, self.stop.visible = not recording, recording
        where = html.escape(str(path)) if path is not None else "the rerun viewer"
        text = {
            "idle": "Not recording.",
            "starting": f"Starting: <code>{where}</code>",
            "recording": f"<b class='hd-rec'>●</b> Recording to <code>{where}</code>",
            "saved": f"Saved <code>{where}</code>",
            "failed": f"Recording failed: {html.escape(message)}",
        }[state]
        if viewer_url and recording:
            text += f"<br>Viewer: <a href='{html.escape(viewer_url)}' target='_blank'>{html.escape(viewer_url)}</a>"
        self.info.content = f"<div class='hd-record'>{text}</div>"


def build_record_panel(gui: viser.GuiApi, recorder: Recorder) -> RecordPanel:
    """Each Record press writes a new timestamped .rrd under the sessions folder."""
    gui.add_html(
        f"<div class='hd-record hd-dim'>Sessions folder: <code>{html.escape(str(recorder.sessions_dir))}</code></div>"
    )
    panel = RecordPanel(
        record=gui.add_button("Record", icon=viser.Icon.PLAYER_RECORD, color="red"),
        stop=gui.add_button("Stop recording", icon=viser.Icon.PLAYER_STOP, visible=False),
        info=gui.add_html(""),
    )
    panel.show("recording" if recorder.active else "idle", recorder.path, viewer_url=recorder.viewer_url)
    recorder.listeners.append(lambda state, path, message: panel.show(state, path, message, recorder.viewer_url))

    @guarded
    def on_record(event: viser.GuiEvent) -> None:
        try:
            path = recorder.start()
        except ValueError as exc:
            notify(event.client, "Cannot record", str(exc), "error")
            return
        panel.show("starting", path)

    @guarded
    def on_stop(_: viser.GuiEvent) -> None:
        recorder.stop()

    panel.record.on_click(on_record)
    panel.stop.on_click(on_stop)
    return panel
