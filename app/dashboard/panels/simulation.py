"""Simulation panel: pause/resume, single steps, reset, speed, and what to do after a fall."""

from __future__ import annotations

import dataclasses
import threading

import viser
from hopper.app.dashboard.feedback import Refused, checked, guarded, notify
from hopper.app.dashboard.pacing import MAX, MAX_SPEED, MIN_SPEED
from hopper.app.dashboard.panels import LoopControls, PanelContext
from hopper.app.dashboard.panels.entry import NumberEntry, hide_slider_boxes

from hopper.commands import Reset

STEPS = {"+1 ms": 1, "+10 ms": 10, "+100 ms": 100}  # control ticks of 1 ms
# One click each; the slider takes any speed in its range. Max runs as fast as the machine allows (the
# scene at a lower frame rate, the charts' window stretched); the status shows what it delivers.
SPEEDS = {"¼×": 0.25, "1×": 1.0, "4×": 4.0, "16×": 16.0, "64×": 64.0, "Max": MAX}
UNIT = "x"  # x real time, as the notices say it
# The slider is linear: its ends and even steps between (a mark "1" at 1 sat at the left end and read as its lowest).
SPEED_MARKS = (MIN_SPEED, 16.0, 32.0, 48.0, MAX_SPEED)


@dataclasses.dataclass
class SimulationPanel:
    loop: LoopControls
    pause: viser.GuiButtonHandle
    resume: viser.GuiButtonHandle
    step: viser.GuiButtonGroupHandle
    reset_robot: viser.GuiButtonHandle
    speed: viser.GuiSliderHandle[float]  # at its top for Max, which only the box can say
    entry: NumberEntry  # the typed speed: a number, or Max
    presets: viser.GuiButtonGroupHandle
    stay_fallen: viser.GuiCheckboxHandle
    reset_button: viser.GuiButtonHandle
    applied_speed: float = 1.0
    _lock: threading.RLock = dataclasses.field(default_factory=threading.RLock, repr=False)

    def set_paused(self, paused: bool) -> None:
        self.loop.set_paused(paused)
        self.pause.visible, self.resume.visible = not paused, paused
        self.step.visible = paused  # viser button groups cannot be disabled after creation

    def choose(self, preset: str) -> None:
        """A preset button: its speed, Max included."""
        self.set_speed(SPEEDS.get(preset, 1.0))

    def set_speed(self, speed: float) -> None:
        """Run at `speed` (x real time, or MAX) and show it: the slider there (at its top for Max), the box
        its number or Max. Called from viser's and the box's timer threads, hence the lock."""
        with self._lock:
            if speed != self.applied_speed:
                self.applied_speed = speed
                self.loop.set_speed(speed)
            self.speed.value = min(speed, MAX_SPEED)  # a program assignment: the slider's handler ignores it
            if self.entry.value != speed:  # a typed value is shown by its box already
                self.entry.show(speed)

    def reset(self) -> None:
        """Defaults: running at 1x, auto reset after a fall."""
        self.set_speed(1.0)
        self.stay_fallen.value = False
        self.set_paused(False)


def build_simulation_panel(gui: viser.GuiApi, ctx: PanelContext, speed: float = 1.0) -> SimulationPanel:
    """Buttons act on the loop (pause, steps, speed) or queue a reset command for the simulation."""
    pause = gui.add_button("Pause", icon=viser.Icon.PLAYER_PAUSE)
    resume = gui.add_button("Resume", icon=viser.Icon.PLAYER_PLAY, color="green", visible=False)
    step = gui.add_button_group("Step", tuple(STEPS), hint="Single 1 ms control ticks", visible=False)
    reset_robot = gui.add_button(
        "Reset robot", icon=viser.Icon.REFRESH, color="gray", hint="Stand the robot at the start"
    )
    slider = gui.add_slider(
        "Speed ×",
        MIN_SPEED,
        MAX_SPEED,
        0.05,  # the box shows 0.25 for the 1/4x button, not 0.3
        min(speed, MAX_SPEED),
        marks=tuple((mark, f"{mark:g}") for mark in SPEED_MARKS),
    )
    box = gui.add_text("× real time", "", hint="Type a speed, 0.1 to 64, or max; applied after a pause")
    hide_slider_boxes(gui, [slider])
    panel = SimulationPanel(
        loop=ctx.loop,
        pause=pause,
        resume=resume,
        step=step,
        reset_robot=reset_robot,
        speed=slider,
        entry=NumberEntry(box, "Speed", MIN_SPEED, MAX_SPEED, UNIT, value=speed, words={"Max": MAX}),
        presets=gui.add_button_group("Speeds", tuple(SPEEDS), hint="Fast-forward; Max: as fast as the machine allows"),
        stay_fallen=gui.add_checkbox("Stay fallen", False, hint="After a fall, keep the robot down for inspection"),
        reset_button=gui.add_button("Defaults", icon=viser.Icon.RESTORE, color="dark", hint="1x speed, auto reset"),
        applied_speed=speed,
    )
    panel.pause.on_click(guarded(lambda _: panel.set_paused(True)))
    panel.resume.on_click(guarded(lambda _: panel.set_paused(False)))
    panel.step.on_click(guarded(lambda _: ctx.loop.request_steps(STEPS.get(panel.step.value, 0))))
    panel.reset_robot.on_click(guarded(lambda _: ctx.submit(Reset("user"))))
    panel.reset_button.on_click(guarded(lambda _: panel.reset()))
    panel.presets.on_click(guarded(lambda _: panel.choose(panel.presets.value)))
    panel.entry.on_apply = lambda value, _client: panel.set_speed(value)

    @guarded
    def on_speed(event: viser.GuiEvent) -> None:
        if event.client is None:  # set by panel.set_speed(): already in use
            return
        try:
            value, message = checked("Speed", panel.speed.value, MIN_SPEED, MAX_SPEED, UNIT)
        except Refused:
            panel.set_speed(panel.applied_speed)  # show the speed in use again
            raise
        if message:
            notify(event.client, "Speed clamped", message, "warning")
        panel.set_speed(value)

    @guarded
    def on_stay(_: viser.GuiEvent) -> None:
        ctx.loop.set_stay_fallen(bool(panel.stay_fallen.value))

    panel.speed.on_update(on_speed)
    panel.stay_fallen.on_update(on_stay)
    return panel
