"""Disturbances panel: pitch kick, pushes and a mid-flight torque pulse, each with its own magnitude."""

from __future__ import annotations

import dataclasses

import viser
from hopper.app.dashboard.feedback import Refused, checked, guarded, keep_in_range, notify
from hopper.app.dashboard.panels import PanelContext

from hopper.commands import Disturb
from hopper.sim import DISTURBANCE_LIMITS

# Button label -> (core kind, magnitude label, default magnitude). Defaults are visible but recoverable.
KINDS = {
    "Pitch kick": ("pitch_kick", "Kick", 1.0),
    "Push ▶": ("push_forward", "Push ▶", 2.0),
    "Push ◀": ("push_backward", "Push ◀", 2.0),
    "Torque pulse": ("torque_pulse", "Pulse", 15.0),
}


@dataclasses.dataclass
class DisturbancesPanel:
    magnitudes: dict[str, viser.GuiNumberHandle[float]]  # by core kind
    apply: viser.GuiButtonGroupHandle
    reset_button: viser.GuiButtonHandle

    def reset(self) -> None:
        for kind, _, default in KINDS.values():
            self.magnitudes[kind].value = default


def build_disturbances_panel(gui: viser.GuiApi, ctx: PanelContext) -> DisturbancesPanel:
    """Magnitudes are checked against hopper.sim.DISTURBANCE_LIMITS before anything is queued."""
    magnitudes = {}
    for kind, label, default in KINDS.values():
        limit, unit = DISTURBANCE_LIMITS[kind]
        magnitudes[kind] = gui.add_number(f"{label} ({unit})", default, min=-limit, max=limit, step=0.1)
        keep_in_range(magnitudes[kind], f"{label} magnitude", -limit, limit, unit)
    panel = DisturbancesPanel(
        magnitudes=magnitudes,
        apply=gui.add_button_group("Apply", tuple(KINDS), hint="A torque pulse waits for the next flight"),
        reset_button=gui.add_button("Default magnitudes", icon=viser.Icon.RESTORE, color="dark"),
    )

    @guarded
    def on_apply(event: viser.GuiEvent) -> None:
        kind, label, default = KINDS[panel.apply.value]
        limit, unit = DISTURBANCE_LIMITS[kind]
        handle = panel.magnitudes[kind]
        try:
            magnitude, message = checked(f"{label} magnitude", handle.value, -limit, limit, unit)
        except Refused:
            handle.value = default
            raise
        if message:
            notify(event.client, "Magnitude clamped", message, "warning")
            handle.value = magnitude
        ctx.submit(Disturb(kind, magnitude))

    panel.apply.on_click(on_apply)
    panel.reset_button.on_click(guarded(lambda _: panel.reset()))
    return panel
