"""Gains panel: the wheel PID's Kp, Ki, Kd (slider plus numeric entry) and wheel on/off."""

from __future__ import annotations

import dataclasses

import viser
from hopper.app.dashboard.feedback import Refused, checked, guarded, notify
from hopper.app.dashboard.panels import PanelContext

from hopper.commands import SetGains, SetWheel
from hopper.config import GAIN_RANGES, Gains


@dataclasses.dataclass
class GainsPanel:
    kp: viser.GuiSliderHandle[float]
    ki: viser.GuiSliderHandle[float]
    kd: viser.GuiSliderHandle[float]
    wheel: viser.GuiCheckboxHandle
    reset_button: viser.GuiButtonHandle
    defaults: Gains
    applied: Gains

    def reset(self) -> None:
        """Back to the gains the dashboard started with, wheel on."""
        self.kp.value, self.ki.value, self.kd.value = self.defaults.kp, self.defaults.ki, self.defaults.kd
        self.wheel.value = True


def build_gains_panel(gui: viser.GuiApi, ctx: PanelContext, initial: Gains, wheel: bool = True) -> GainsPanel:
    """Sliders apply at the next control tick; a bad value is clamped or refused with a notification."""

    def slider(label: str, bounds: tuple[float, float], step: float, value: float, hint: str) -> viser.GuiSliderHandle:
        low, high = bounds
        marks = ((low, f"{low:g}"), (value, f"{value:g}"), (high, f"{high:g}"))
        return gui.add_slider(label, low, high, step, min(max(value, low), high), marks=marks, hint=hint)

    panel = GainsPanel(
        kp=slider("Kp", GAIN_RANGES["kp"][:2], 5.0, initial.kp, "Proportional gain, N m/rad"),
        ki=slider("Ki", GAIN_RANGES["ki"][:2], 1.0, initial.ki, "Integral gain, N m/(rad s); reset at each liftoff"),
        kd=slider("Kd", GAIN_RANGES["kd"][:2], 0.5, initial.kd, "Derivative gain on the measured rate, N m s/rad"),
        wheel=gui.add_checkbox("Wheel on", wheel, hint="Off: zero wheel torque, the wheel spins freely"),
        reset_button=gui.add_button("Default gains", icon=viser.Icon.RESTORE, color="dark"),
        defaults=initial,
        applied=initial,
    )
    ranges = {
        label: (handle, GAIN_RANGES[label.lower()][:2], GAIN_RANGES[label.lower()].unit)
        for label, handle in (("Kp", panel.kp), ("Ki", panel.ki), ("Kd", panel.kd))
    }

    @guarded
    def on_gain(event: viser.GuiEvent) -> None:
        values = {}
        for name, (handle, (low, high), unit) in ranges.items():
            try:
                value, message = checked(name, handle.value, low, high, unit)
            except Refused:
                handle.value = getattr(panel.applied, name.lower())  # restore the last applied gain
                raise
            if message:
                notify(event.client, "Gain clamped", message, "warning")
                handle.value = value
            values[name.lower()] = value
        gains = Gains(**values)  # the core's own validation, before anything is queued
        if gains == panel.applied:
            return
        panel.applied = gains
        ctx.submit(SetGains(gains))

    @guarded
    def on_wheel(_: viser.GuiEvent) -> None:
        enabled = bool(panel.wheel.value)
        ctx.submit(SetWheel(enabled))

    for handle in (panel.kp, panel.ki, panel.kd):
        handle.on_update(on_gain)
    panel.wheel.on_update(on_wheel)
    panel.reset_button.on_click(guarded(lambda _: panel.reset()))
    return panel
