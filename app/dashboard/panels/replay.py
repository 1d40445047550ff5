"""Replay panel: re-fly the last flight with the current gains (A/B table), a history scrubber, keyframes.

Callbacks run on viser's threads: re-flying uses a scratch simulation of its own; saving a keyframe
is a command the loop applies between ticks; a restore (a scrubbed moment, a keyframe) is a command
too, which the loop applies between two step batches, so that no tick follows it while paused.
"""

from __future__ import annotations

import collections
import dataclasses
import html
import math
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

import viser
from hopper.app.dashboard.feedback import checked, format_number, guarded, notify
from hopper.app.dashboard.panels import PanelContext
from hopper.app.dashboard.panels.entry import NumberEntry, hide_slider_boxes
from hopper.app.dashboard.plots import ReflyPlots
from hopper.app.dashboard.scene import GhostRobot

from hopper import keyframes
from hopper.config import Gains, SimConfig
from hopper.history import GHOST_EVERY, RING_SPAN_S, Flight, History, fly
from hopper.snapshot import Snapshot

if TYPE_CHECKING:
    from hopper.sim import Simulation

AB_ROWS = 6  # gain sets kept in the A/B table
SCRUB_STEP_S = 0.1  # s, the slider's step (the ring's period)


class ReplayHost(Protocol):
    """What the panel needs of the dashboard."""

    sim: Simulation
    history: History

    def pause(self, paused: bool) -> None: ...

    def request_restore(self, snapshot: Snapshot, what: str) -> None:
        """Put the live simulation back into `snapshot` between two step batches (no tick after it);
        the event log says `what` was restored."""


@dataclasses.dataclass(frozen=True)
class SaveKeyframe:
    """Command: snapshot the live simulation as a named keyframe and hand it to `then`."""

    name: str
    then: Callable[[keyframes.Keyframe], None]

    def apply(self, sim: Simulation) -> None:
        self.then(keyframes.save(sim, self.name))


@dataclasses.dataclass(frozen=True)
class Comparison:
    """One re-fly: the recorded flight, the same state and gains flown again, and the current gains."""

    recorded: Flight
    before: Flight
    after: Flight

    @property
    def before_identical(self) -> bool:
        r, b = self.recorded, self.before
        return r.pitch.tobytes() == b.pitch.tobytes() and r.torque.tobytes() == b.torque.tobytes()


def refly(recorded: Flight, flown: Gains | SimConfig) -> Comparison:
    """Fly `recorded` again from its liftoff state as it was flown, and with `flown`'s gains (and
    controller, given a SimConfig: the same flight flown by two controllers), in scratch simulations."""
    return Comparison(recorded, fly(recorded.start), fly(recorded.start, flown))


_COLUMNS = (
    ("peak_pitch_deg", "peak", "°", "{:.2f}"),
    ("rms_rate_deg_s", "rms rate", "°/s", "{:.1f}"),
    ("landing_pitch_deg", "landing", "°", "{:.2f}"),
    ("peak_torque_nm", "peak τ", "N m", "{:.2f}"),
)


def _fmt(value: float, fmt: str) -> str:
    return fmt.format(value) if math.isfinite(value) else "–"


def ab_table_html(rows: list[tuple[str, float, str, dict[str, float]]], note: str = "") -> str:
    """Rows (label, liftoff time s, what flew it (Flight.label), Flight.summary()), oldest first."""
    head = "".join(f"<th>{h}<br><span>{u}</span></th>" for _, h, u, _ in _COLUMNS)
    body = []
    for label, t, g, summary in rows:
        cells = "".join(f"<td>{_fmt(summary[f], fmt)}</td>" for f, _, _, fmt in _COLUMNS)
        gains = html.escape(g)
        where = f"<td style='text-align:left'>{html.escape(label)}<br><span>{t:.1f} s</span></td>"
        body.append(f"<tr>{where}<td style='white-space:nowrap'>{gains}</td>{cells}</tr>")
    if not body:
        body.append(f"<tr><td colspan={len(_COLUMNS) + 2} class='hd-empty'>re-fly a flight to compare gains</td></tr>")
    caption = f"<caption>{html.escape(note)}</caption>" if note else ""
    return (
        f"<table class='hd-hops hd-ab'>{caption}<tr><th style='text-align:left'>flight<br><span>liftoff</span></th>"
        f"<th>law<br><span>Kp/Ki/Kd or controller</span></th>{head}</tr>{''.join(body)}</table>"
    )


@dataclasses.dataclass
class ReplayPanel:
    host: ReplayHost
    plots: ReflyPlots | None  # set once the left panel exists
    ghost: GhostRobot
    refly_button: viser.GuiButtonHandle
    ab: viser.GuiHtmlHandle
    scrub: viser.GuiSliderHandle[float]
    back: NumberEntry  # the typed Back, seconds ago, beside the slider (its own box is hidden)
    scrub_info: viser.GuiHtmlHandle
    resume_here: viser.GuiButtonHandle
    name: viser.GuiTextHandle
    save: viser.GuiButtonHandle
    choice: viser.GuiDropdownHandle[str]
    restore_button: viser.GuiButtonHandle
    export: viser.GuiButtonHandle
    upload: viser.GuiUploadButtonHandle
    keyframes: dict[str, keyframes.Keyframe] = dataclasses.field(default_factory=dict)
    rows: collections.deque = dataclasses.field(default_factory=lambda: collections.deque(maxlen=AB_ROWS))
    last: Comparison | None = None  # the last re-fly, for tests
    scrubbed: Snapshot | None = None  # the moment the live simulation was put back to, if any
    _scrub_paused: bool = False  # the loop has shown the scrub paused (a later resume ends the scrub)
    _lock: threading.Lock = dataclasses.field(default_factory=threading.Lock, repr=False)

    # -- re-fly ----------------------------------------------------------------------------
    def refly(self, client: viser.ClientHandle | None = None) -> Comparison | None:
        recorded = self.host.history.last_flight
        if recorded is None:
            notify(client, "Nothing to re-fly", "No complete flight yet: wait for a touchdown.", "warning")
            return None
        with self._lock:  # one re-fly at a time: two would interleave their rows
            comparison = refly(recorded, self.host.sim.config)  # the gains and controller flying now
            before, after = comparison.before, comparison.after
            dt = recorded.start.config.timestep
            if self.plots is not None:
                self.plots.show(dt, (before.pitch, before.torque), (after.pitch, after.torque))
            self.ghost.play(after.poses, GHOST_EVERY * dt, time.perf_counter())
            t = recorded.start.time
            for label, flight in (("recorded", recorded), ("re-fly", after)):
                row = (label, t, flight.label, flight.summary())
                if not any(r[1] == t and r[2] == flight.label for r in self.rows):
                    self.rows.append(row)
            same = "identical to" if comparison.before_identical else "DIFFERS from"
            note = f"before (recorded gains, same state) is {same} the recorded flight, {len(recorded.pitch)} ticks"
            self.ab.content = ab_table_html(list(self.rows), note)
            self.last = comparison
        return comparison

    # -- history scrubber ------------------------------------------------------------------
    def go_back(self, seconds: float, client: viser.ClientHandle | None, message: str | None = None) -> None:
        """Show the moment `seconds` back (in [0, RING_SPAN_S], `message` if it was clamped to that), or
        the history's oldest if it holds less; slider and box show the moment shown."""
        span = self.host.history.span
        if seconds > span:  # further back than the history reaches: its oldest moment
            asked, seconds = seconds, span
            message = f"Back {format_number(asked)} s: the history holds {span:.1f} s; showing its oldest moment"
        if message:
            notify(client, "Back clamped", message, "warning")
        self._show_back(seconds)
        if self.scrub_to(seconds) is None:
            notify(client, "No history yet", "The simulation has not run long enough.", "warning")

    def _show_back(self, seconds: float) -> None:
        # The slider is a timeline, the past to the left: it holds minus the seconds back (0.0 - x: never -0.0).
        self.scrub.value = 0.0 - seconds  # a program assignment: the slider's handler ignores it
        shown = _seconds_back(seconds, RING_SPAN_S)  # to the ring's period, as the history line says it
        if self.back.value != shown:  # a typed value is shown by its box already
            self.back.show(shown)

    def scrub_to(self, seconds_back: float) -> Snapshot | None:
        """Pause and put the live simulation back `seconds_back` s before the newest ring entry."""
        history = self.host.history
        snap = history.at(seconds_back)
        if snap is None:
            return None
        self.host.pause(True)  # queued: the loop applies it with the restore, in order
        self._scrub_paused = False
        self.scrubbed = snap
        back = _seconds_back(seconds_back, history.span)
        self.host.request_restore(snap, f"the moment {back:.1f} s back")
        self.scrub_info.content = _scrub_html(snap, back, history.span)
        return snap

    def resume(self) -> None:
        """Continue the live simulation from the moment shown; later history is dropped."""
        self.scrubbed = None
        self._show_back(0.0)
        self.scrub_info.content = _scrub_html(None, 0.0, self.host.history.span)
        self.host.pause(False)

    def show_span(self, paused: bool) -> None:
        """Refresh the history line while live (the loop calls it with the status)."""
        if self.scrubbed is not None and paused:
            self._scrub_paused = True  # the loop has applied the scrub's pause
        elif self.scrubbed is not None and self._scrub_paused:  # resumed by the Simulation panel's button
            self.scrubbed = None
            self._show_back(0.0)
        if self.scrubbed is None:
            self.scrub_info.content = _scrub_html(None, 0.0, self.host.history.span)

    # -- keyframes -------------------------------------------------------------------------
    def add_keyframe(self, keyframe: keyframes.Keyframe) -> keyframes.Keyframe:
        """Keep `keyframe` and select it; under a taken name it becomes "name (2)" (the one kept)."""
        with self._lock:  # a save and an import may come at once: the name is chosen and taken together
            name = keyframes.unique_name(keyframe.name, self.keyframes)
            keyframe = dataclasses.replace(keyframe, name=name)
            self.keyframes[name] = keyframe
            self.choice.options = tuple(self.keyframes)
            self.choice.value = name
        return keyframe

    def selected(self, client: viser.ClientHandle | None) -> keyframes.Keyframe | None:
        keyframe = self.keyframes.get(self.choice.value)
        if keyframe is None:
            notify(client, "No keyframe", "Save or import a keyframe first.", "warning")
        return keyframe

    def restore_keyframe(self, keyframe: keyframes.Keyframe) -> None:
        self.host.request_restore(keyframe.snapshot, f"keyframe {keyframe.name!r}")

    def import_file(self, content: bytes, client: viser.ClientHandle | None) -> keyframes.Keyframe | None:
        try:
            keyframe = keyframes.from_json(content, self.host.sim)
        except keyframes.KeyframeError as exc:
            notify(client, "Keyframe refused", str(exc), "error")
            return None
        kept = self.add_keyframe(keyframe)
        notify(client, "Keyframe imported", _kept(kept, keyframe.name))
        return kept


def _kept(keyframe: keyframes.Keyframe, asked: str) -> str:
    """A save's or an import's notice: the name kept, and why it is not the one asked."""
    renamed = f" ({asked!r} is taken: both are kept)" if keyframe.name != asked else ""
    return f"{keyframe.name!r} at t = {keyframe.time:.2f} s{renamed}"


def _seconds_back(seconds: float, span: float) -> float:
    """`seconds` (s back) within [0, span], to the ring's 0.1 s: what the box and the line show (never -0.0)."""
    return round(min(max(seconds, 0.0), span), 1) + 0.0  # -0.0 + 0.0 is 0.0


def _scrub_html(snap: Snapshot | None, back: float, span: float) -> str:
    if snap is None:
        # Whole seconds: the line changes once a second while the history grows, not at every status.
        return f"<div class='hd-record'>live · {span:.0f} s of history held</div>"
    return (
        f"<div class='hd-record'>showing t = {snap.time:.2f} s ({back:.1f} s back of {span:.1f} s) · "
        f"paused: <b>Resume from here</b> continues from this moment</div>"
    )


def build_replay_panel(
    gui: viser.GuiApi, ctx: PanelContext, host: ReplayHost, plots: ReflyPlots | None, ghost: GhostRobot
) -> ReplayPanel:
    with gui.add_folder("Re-fly and compare"):
        refly_button = gui.add_button(
            "Re-fly last flight",  # a longer label is cut off in the side panel
            icon=viser.Icon.PLANE_DEPARTURE,
            hint="Restore the last liftoff state in a scratch simulation and fly it with the recorded and "
            "the current gains and controller; the charts overlay both, the ghost shows the new flight",
        )
        ab = gui.add_html(ab_table_html([]))
    with gui.add_folder("History"):
        # A timeline, the past to the left (its value is minus the seconds back); its marks read seconds back.
        marks = tuple((-s, f"{s:g}" if s else "now") for s in (RING_SPAN_S, RING_SPAN_S / 2, 0.0))
        scrub = gui.add_slider(
            "Back (s)", -RING_SPAN_S, 0.0, SCRUB_STEP_S, 0.0, marks=marks, hint="Pause and show the robot this long ago"
        )
        hint = f"Type how many seconds back, 0 to {RING_SPAN_S:g}; applied after a pause"
        # No top of its own: go_back clamps to what the history holds, in one notice (two said 40 and 39.9).
        back = NumberEntry(gui.add_text("s back", "", hint=hint), "Back", 0.0, math.inf, "s", value=0.0, magnitude=True)
        hide_slider_boxes(gui, [scrub])
        scrub_info = gui.add_html(_scrub_html(None, 0.0, 0.0))
        resume_here = gui.add_button("Resume from here", icon=viser.Icon.PLAYER_PLAY, color="green")
    with gui.add_folder("Keyframes"):
        name = gui.add_text("Name", "keyframe 1")
        save = gui.add_button("Save keyframe", icon=viser.Icon.BOOKMARK)
        choice = gui.add_dropdown("Keyframe", ("",), initial_value="")
        restore_button = gui.add_button("Restore keyframe", icon=viser.Icon.RESTORE)
        export = gui.add_button("Export keyframe", icon=viser.Icon.DOWNLOAD, color="gray")
        upload = gui.add_upload_button("Import keyframe", icon=viser.Icon.UPLOAD, color="gray", mime_type=".json")
    panel = ReplayPanel(
        host, plots, ghost, refly_button, ab, scrub, back, scrub_info, resume_here, name, save, choice,
        restore_button, export, upload,
    )  # fmt: skip

    panel.refly_button.on_click(guarded(lambda event: panel.refly(event.client)))

    @guarded
    def on_scrub(event: viser.GuiEvent) -> None:
        if event.client is None:  # a program assignment (resume, a clamp) moves the slider
            return
        # A drag stays in range; a value out of it comes from no page of ours: clamped in the slider's terms.
        value, message = checked("Back", scrub.value, -RING_SPAN_S, 0.0, "s")  # Refused: notified, kept
        panel.go_back(0.0 - value, event.client, message)

    scrub.on_update(on_scrub)
    back.on_apply = panel.go_back  # (seconds, client): beyond the history, go_back clamps and says so
    resume_here.on_click(guarded(lambda _: panel.resume()))

    @guarded
    def on_save(event: viser.GuiEvent) -> None:
        try:
            keyframe_name = keyframes.check_name(name.value)  # refused here, at once, with a message
        except keyframes.KeyframeError as exc:
            notify(event.client, "Keyframe refused", str(exc), "warning")
            return

        def saved(keyframe: keyframes.Keyframe) -> None:
            notify(event.client, "Keyframe saved", _kept(panel.add_keyframe(keyframe), keyframe.name))

        ctx.submit(SaveKeyframe(keyframe_name, saved))

    @guarded
    def on_restore(event: viser.GuiEvent) -> None:
        keyframe = panel.selected(event.client)
        if keyframe is not None:
            panel.restore_keyframe(keyframe)
            notify(event.client, "Keyframe restored", f"{keyframe.name!r} at t = {keyframe.time:.2f} s")

    @guarded
    def on_export(event: viser.GuiEvent) -> None:
        keyframe = panel.selected(event.client)
        if keyframe is not None and event.client is not None:
            filename = "".join(c if c.isalnum() or c in "-_" else "_" for c in keyframe.name) + ".json"
            event.client.send_file_download(filename, keyframes.to_json(keyframe).encode(), save_immediately=True)

    @guarded
    def on_upload(event: viser.GuiEvent) -> None:
        panel.import_file(upload.value.content, event.client)

    save.on_click(on_save)
    restore_button.on_click(on_restore)
    export.on_click(on_export)
    upload.on_upload(on_upload)
    return panel
