"""Disturbances panel: pitch kick, pushes and a mid-flight torque pulse, each with its own magnitude,
and the repeatable test: one of them scheduled after every (Nth) liftoff (hopper.schedule)."""

from __future__ import annotations

import dataclasses

import viser
from hopper.app.dashboard.feedback import guarded, notify
from hopper.app.dashboard.panels import PanelContext
from hopper.app.dashboard.panels.entry import NumberEntry

from hopper.commands import Disturb, SetSchedule
from hopper.disturbances import DISTURBANCE_LIMITS
from hopper.schedule import DEFAULT_DELAY_S, MAX_DELAY_S, MAX_EVERY, KickSchedule

# Button label -> (core kind, magnitude label, default magnitude). Defaults are visible but recoverable.
KINDS = {
    "Pitch kick": ("pitch_kick", "Kick", 1.0),
    "Push ▶": ("push_forward", "Push ▶", 4.0),
    "Push ◀": ("push_backward", "Push ◀", 4.0),
    "Torque pulse": ("torque_pulse", "Pulse", 10.0),  # 1 N m s over 0.1 s: inside the flight envelope
}
SCHEDULE_DEFAULTS = ("Pitch kick", 0.3, DEFAULT_DELAY_S * 1000, 1)  # kind label, magnitude, delay ms, every
SCHEDULE_OFF = "Schedule off: each hop runs undisturbed."


@dataclasses.dataclass
class ScheduleControls:
    """The repeatable test: which kick, how big, how long after liftoff, every how many hops."""

    kind: viser.GuiDropdownHandle
    magnitude: NumberEntry  # in the kind's unit; the kind's own limit is checked at Start
    delay_ms: NumberEntry
    every: NumberEntry
    buttons: viser.GuiButtonGroupHandle
    status: viser.GuiMarkdownHandle

    def reset(self) -> None:
        label, magnitude, delay, every = SCHEDULE_DEFAULTS
        self.kind.value = label
        self.magnitude.show(magnitude)
        self.delay_ms.show(delay)
        self.every.show(every)

    def show(self, schedule: KickSchedule | None) -> None:
        """What the simulation runs now (called on its ScheduleChanged event)."""
        self.status.content = f"**Schedule on:** {schedule.describe()}" if schedule else SCHEDULE_OFF


@dataclasses.dataclass
class DisturbancesPanel:
    magnitudes: dict[str, NumberEntry]  # typed boxes, by core kind
    apply: viser.GuiButtonGroupHandle
    reset_button: viser.GuiButtonHandle
    schedule: ScheduleControls

    def reset(self) -> None:
        for kind, _, default in KINDS.values():
            self.magnitudes[kind].show(default)
        self.schedule.reset()


def build_disturbances_panel(gui: viser.GuiApi, ctx: PanelContext) -> DisturbancesPanel:
    """Magnitudes are typed, checked against hopper.disturbances.DISTURBANCE_LIMITS, used when a button is pressed."""
    magnitudes = {}
    for kind, label, default in KINDS.values():
        limit, unit = DISTURBANCE_LIMITS[kind]
        box = gui.add_text(f"{label} ({unit})", "", hint=f"From -{limit:g} to {limit:g} {unit}")
        magnitudes[kind] = NumberEntry(box, f"{label} magnitude", -limit, limit, unit, value=default)
    apply = gui.add_button_group("Apply", tuple(KINDS), hint="A torque pulse waits for the next flight")
    reset_button = gui.add_button("Default magnitudes", icon=viser.Icon.RESTORE, color="dark")
    with gui.add_folder("Repeatable test"):
        schedule = build_schedule_controls(gui, ctx)
    panel = DisturbancesPanel(magnitudes=magnitudes, apply=apply, reset_button=reset_button, schedule=schedule)

    @guarded
    def on_apply(event: viser.GuiEvent) -> None:
        kind, _, _ = KINDS[panel.apply.value]
        magnitude = panel.magnitudes[kind].commit(event.client)  # what was just typed counts
        if magnitude is None:  # refused, with a notice: nothing is applied
            return
        ctx.submit(Disturb(kind, magnitude))

    panel.apply.on_click(on_apply)
    panel.reset_button.on_click(guarded(lambda _: panel.reset()))
    return panel


def build_schedule_controls(gui: viser.GuiApi, ctx: PanelContext) -> ScheduleControls:
    """Start submits SetSchedule (a bad combination is refused with a notice); Clear submits None."""
    label, magnitude, delay, every = SCHEDULE_DEFAULTS
    widest = max(limit for limit, _ in DISTURBANCE_LIMITS.values())
    hint = "N m s (kick), N s (push) or N m (pulse); each kind's own limit applies"
    controls = ScheduleControls(
        kind=gui.add_dropdown("Kick", tuple(KINDS), initial_value=label),
        magnitude=NumberEntry(gui.add_text("Size", "", hint=hint), "Schedule size", -widest, widest, value=magnitude),
        delay_ms=NumberEntry(
            gui.add_text("After liftoff (ms)", "", hint=f"0 to {MAX_DELAY_S * 1000:g} ms"),
            "Schedule delay",
            0.0,
            MAX_DELAY_S * 1000,
            "ms",
            value=delay,
            integer=True,
        ),
        every=NumberEntry(
            gui.add_text("Every Nth hop", "", hint="1: every hop; 3: hops 3, 6, 9, ..."),
            "Schedule every",
            1,
            MAX_EVERY,
            value=every,
            integer=True,
        ),
        buttons=gui.add_button_group("Schedule", ("Start", "Clear")),
        status=gui.add_markdown(SCHEDULE_OFF),
    )

    @guarded
    def on_click(event: viser.GuiEvent) -> None:
        if controls.buttons.value == "Clear":
            ctx.submit(SetSchedule(None))
            return
        values = [entry.commit(event.client) for entry in (controls.magnitude, controls.delay_ms, controls.every)]
        if any(value is None for value in values):  # refused, with a notice
            return
        magnitude, delay, every = values
        kind = KINDS[controls.kind.value][0]
        try:
            schedule = KickSchedule(kind, magnitude, delay / 1000.0, int(every))
        except ValueError as exc:
            notify(event.client, "Schedule refused", str(exc), "warning")
            return
        ctx.submit(SetSchedule(schedule))

    controls.buttons.on_click(on_click)
    return controls
