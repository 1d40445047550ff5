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
    recorder: Recorder | None = None
    _state: tuple[str, Path | None, str, str | None] = ("idle", None, "", None)

    def show(self, state: str, path: Path | None, message: str = "", viewer_url: str | None = None) -> None:
        self._state = (state, path, message, viewer_url)
        recording = state in ("recording", "starting", "behind")
        self.record.visible, self.stop.visible = not recording, recording
        self.refresh()

    def refresh(self) -> None:
        """Re-draw the text (the current file's size grows); sends nothing if it did not change."""
        state, path, message, viewer_url = self._state
        where = html.escape(str(path)) if path is not None else "the rerun viewer"
        size = ""
        if state in ("recording", "behind") and path is not None and self.recorder is not None:
            current, written, parts = self.recorder.progress()
            if current is not None:
                where = html.escape(str(current))
                size = f" &middot; {written / 1e6:.1f} MB" + (f" (part {parts})" if parts > 1 else "")
        text = {
            "idle": "Not recording.",
            "starting": f"Starting: <code>{where}</code>",
            "recording": f"<b class='hd-rec'>●</b> Recording to <code>{where}</code>{size}",
            "saved": f"Saved <code>{where}</code>",
            "failed": f"Recording failed: {html.escape(message)}",
            "behind": f"<b class='hd-rec'>●</b> Recording to <code>{where}</code>{size}<br>"
            f"<b class='hd-behind'>Behind:</b> {html.escape(message)}",
        }[state]
        if viewer_url and state in ("recording", "starting", "behind"):
            text += f"<br>Viewer: <a href='{html.escape(viewer_url)}' target='_blank'>{html.escape(viewer_url)}</a>"
        content = f"<div class='hd-record'>{text}</div>"
        if content != self.info.content:
            self.info.content = content


def build_record_panel(gui: viser.GuiApi, recorder: Recorder) -> RecordPanel:
    """Each Record press writes a new timestamped .rrd under the sessions folder."""
    gui.add_html(
        f"<div class='hd-record hd-dim'>Sessions folder: <code>{html.escape(str(recorder.sessions_dir))}</code></div>"
    )
    panel = RecordPanel(
        record=gui.add_button("Record", icon=viser.Icon.PLAYER_RECORD, color="red"),
        stop=gui.add_button("Stop recording", icon=viser.Icon.PLAYER_STOP, visible=False),
        info=gui.add_html(""),
        recorder=recorder,
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
