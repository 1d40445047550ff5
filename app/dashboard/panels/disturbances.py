"""Disturbances panel: pitch kick, pushes and a mid-flight torque pulse, each with its own magnitude."""

from __future__ import annotations

import dataclasses

import viser
from hopper.app.dashboard.feedback import guarded
from hopper.app.dashboard.panels import PanelContext
from hopper.app.dashboard.panels.entry import NumberEntry

from hopper.commands import Disturb
from hopper.sim import DISTURBANCE_LIMITS

# Button label -> (core kind, magnitude label, default magnitude). Defaults are visible but recoverable.
KINDS = {
    "Pitch kick": ("pitch_kick", "Kick", 1.0),
    "Push ▶": ("push_forward", "Push ▶", 4.0),
    "Push ◀": ("push_backward", "Push ◀", 4.0),
    "Torque pulse": ("torque_pulse", "Pulse", 15.0),
}


@dataclasses.dataclass
class DisturbancesPanel:
    magnitudes: dict[str, NumberEntry]  # typed boxes, by core kind
    apply: viser.GuiButtonGroupHandle
    reset_button: viser.GuiButtonHandle

    def reset(self) -> None:
        for kind, _, default in KINDS.values():
            self.magnitudes[kind].show(default)


def build_disturbances_panel(gui: viser.GuiApi, ctx: PanelContext) -> DisturbancesPanel:
    """Magnitudes are typed, checked against hopper.sim.DISTURBANCE_LIMITS, and used when a button is pressed."""
    magnitudes = {}
    for kind, label, default in KINDS.values():
        limit, unit = DISTURBANCE_LIMITS[kind]
        box = gui.add_text(f"{label} ({unit})", "", hint=f"From -{limit:g} to {limit:g} {unit}")
        magnitudes[kind] = NumberEntry(box, f"{label} magnitude", -limit, limit, unit, value=default)
    panel = DisturbancesPanel(
        magnitudes=magnitudes,
        apply=gui.add_button_group("Apply", tuple(KINDS), hint="A torque pulse waits for the next flight"),
        reset_button=gui.add_button("Default magnitudes", icon=viser.Icon.RESTORE, color="dark"),
    )

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
