"""Gains panel: the wheel PID's Kp, Ki, Kd (slider to drag, box to type) and wheel on/off."""

from __future__ import annotations

import dataclasses
import threading
from collections.abc import Callable

import viser
from hopper.app.dashboard.feedback import Refused, checked, guarded, notify
from hopper.app.dashboard.panels import PanelContext
from hopper.app.dashboard.panels.entry import NumberEntry, hide_slider_boxes

from hopper.commands import SetGains, SetSensing, SetWheel
from hopper.config import GAIN_RANGES, Gains

LABELS = {"kp": "Kp", "ki": "Ki", "kd": "Kd"}
STEPS = {"kp": 5.0, "ki": 1.0, "kd": 0.5}  # slider steps; typed values may fall between them
HINTS = {
    "kp": "Proportional gain",
    "ki": "Integral gain; the integral is reset at each liftoff",
    "kd": "Derivative gain on the measured pitch rate",
}


@dataclasses.dataclass
class GainsPanel:
    ctx: PanelContext
    kp: viser.GuiSliderHandle[float]
    ki: viser.GuiSliderHandle[float]
    kd: viser.GuiSliderHandle[float]
    entries: dict[str, NumberEntry]  # the typed boxes, by gain name (kp, ki, kd)
    wheel: viser.GuiCheckboxHandle
    sensing: viser.GuiCheckboxHandle  # ticked: the controller reads a simulated IMU's estimate
    reset_button: viser.GuiButtonHandle
    defaults: Gains
    applied: Gains
    default_sensing: bool
    _lock: threading.RLock = dataclasses.field(default_factory=threading.RLock, repr=False)

    @property
    def sliders(self) -> dict[str, viser.GuiSliderHandle[float]]:
        return {"kp": self.kp, "ki": self.ki, "kd": self.kd}

    def apply(self, source: str = "", **changes: float) -> None:
        """Queue the gains in use with `changes` if they differ, and show the changed ones in slider and box.

        `source` says what chose them when a design helper did (the event log shows it).

        Called from viser's and the boxes' timer threads, hence the lock. Only the changed gains'
        handles are set: another slider may hold a value whose callback has yet to run.
        """
        ctx = self.ctx
        with self._lock:
            gains = dataclasses.replace(self.applied, **changes)  # the core's own validation first
            if gains != self.applied:
                self.applied = gains
                ctx.submit(SetGains(gains, source))
            for name, value in changes.items():
                self.sliders[name].value = value  # a program assignment: the slider's handler ignores it
                if self.entries[name].value != value:  # a typed value is shown by its box already
                    self.entries[name].show(value)

    def reset(self) -> None:
        """Back to the gains the dashboard started with, wheel on."""
        self.apply(**dataclasses.asdict(self.defaults))
        self.wheel.value = True
        self.sensing.value = self.default_sensing


def build_gains_panel(
    gui: viser.GuiApi, ctx: PanelContext, initial: Gains, wheel: bool = True, sensing: bool = False
) -> GainsPanel:
    """Dragging applies at once, typing after a short quiet time; every slider and box shows the gains in use."""
    sliders: dict[str, viser.GuiSliderHandle[float]] = {}
    entries: dict[str, NumberEntry] = {}
    for name, label in LABELS.items():
        low, high, unit = GAIN_RANGES[name]
        value = getattr(initial, name)  # Gains keeps it inside GAIN_RANGES
        marks = ((low, f"{low:g}"), (value, f"{value:g}"), (high, f"{high:g}"))
        sliders[name] = gui.add_slider(label, low, high, STEPS[name], value, marks=marks, hint=f"{HINTS[name]}, {unit}")
        box = gui.add_text(unit, "", hint=f"Type {label} in {unit}: 800, 12.5 or 1e3; applied after a pause")
        entries[name] = NumberEntry(box, label, low, high, unit, value=value)
    hide_slider_boxes(gui, list(sliders.values()))
    panel = GainsPanel(
        ctx=ctx,
        kp=sliders["kp"],
        ki=sliders["ki"],
        kd=sliders["kd"],
        entries=entries,
        wheel=gui.add_checkbox("Wheel on", wheel, hint="Off: zero wheel torque, the wheel spins freely"),
        sensing=gui.add_checkbox(
            "Realistic sensing",
            sensing,
            hint="The controller reads a simulated IMU (noise, bias, attitude estimate) with a 3 ms motor delay",
        ),
        reset_button=gui.add_button("Default gains", icon=viser.Icon.RESTORE, color="dark"),
        defaults=initial,
        applied=initial,
        default_sensing=sensing,
    )

    def on_slider(name: str) -> Callable[[viser.GuiEvent], None]:
        @guarded
        def handler(event: viser.GuiEvent) -> None:
            if event.client is None:  # set by panel.apply(): already in use
                return
            low, high, unit = GAIN_RANGES[name]
            try:
                value, message = checked(LABELS[name], sliders[name].value, low, high, unit)
            except Refused:
                panel.apply(**{name: getattr(panel.applied, name)})  # show the gain in use again
                raise
            if message:
                notify(event.client, "Gain clamped", message, "warning")
            panel.apply(**{name: value})

        return handler

    def on_typed(name: str) -> Callable[[float, viser.ClientHandle | None], None]:
        return lambda value, _client: panel.apply(**{name: value})

    @guarded
    def on_wheel(_: viser.GuiEvent) -> None:
        enabled = bool(panel.wheel.value)
        ctx.submit(SetWheel(enabled))

    for name, slider in sliders.items():
        slider.on_update(on_slider(name))
        entries[name].on_apply = on_typed(name)
    panel.wheel.on_update(on_wheel)
    panel.sensing.on_update(guarded(lambda _: ctx.submit(SetSensing("realistic" if panel.sensing.value else "ideal"))))
    panel.reset_button.on_click(guarded(lambda _: panel.reset()))
    return panel
