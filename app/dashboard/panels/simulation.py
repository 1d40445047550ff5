"""Simulation panel: pause/resume, single steps, reset, speed, and what to do after a fall."""

from __future__ import annotations

import dataclasses

import viser
from hopper.app.dashboard.feedback import Refused, checked, guarded, notify
from hopper.app.dashboard.pacing import MAX, MAX_SPEED, MIN_SPEED
from hopper.app.dashboard.panels import LoopControls, PanelContext

from hopper.commands import Reset

STEPS = {"+1 ms": 1, "+10 ms": 10, "+100 ms": 100}  # control ticks of 1 ms
# One click each; the slider takes any speed in its range. Max runs as fast as the machine allows (the
# scene at a lower frame rate, the charts' window stretched); the status shows what it delivers.
SPEEDS = {"¼×": 0.25, "1×": 1.0, "4×": 4.0, "16×": 16.0, "64×": 64.0, "Max": MAX}


@dataclasses.dataclass
class SimulationPanel:
    loop: LoopControls
    pause: viser.GuiButtonHandle
    resume: viser.GuiButtonHandle
    step: viser.GuiButtonGroupHandle
    reset_robot: viser.GuiButtonHandle
    speed: viser.GuiSliderHandle[float]
    presets: viser.GuiButtonGroupHandle
    stay_fallen: viser.GuiCheckboxHandle
    reset_button: viser.GuiButtonHandle
    applied_speed: float = 1.0

    def set_paused(self, paused: bool) -> None:
        self.loop.set_paused(paused)
        self.pause.visible, self.resume.visible = not paused, paused
        self.step.visible = paused  # viser button groups cannot be disabled after creation

    def choose(self, preset: str) -> None:
        """A preset: a speed on the slider (its update sets it), or Max, which the slider cannot show."""
        speed = SPEEDS.get(preset, 1.0)
        if speed == MAX:
            self.applied_speed = MAX
            self.loop.set_speed(MAX)
        else:
            self.set_speed(speed)

    def set_speed(self, speed: float) -> None:
        """Put the slider at `speed`; from Max, the loop is told even if the slider was there already."""
        if self.applied_speed == MAX and self.speed.value == speed:
            self.applied_speed = speed
            self.loop.set_speed(speed)
        self.speed.value = speed

    def reset(self) -> None:
        """Defaults: running at 1x, auto reset after a fall."""
        self.set_speed(1.0)
        self.stay_fallen.value = False
        self.set_paused(False)


def build_simulation_panel(gui: viser.GuiApi, ctx: PanelContext, speed: float = 1.0) -> SimulationPanel:
    """Buttons act on the loop (pause, steps, speed) or queue a reset command for the simulation."""
    panel = SimulationPanel(
        loop=ctx.loop,
        pause=gui.add_button("Pause", icon=viser.Icon.PLAYER_PAUSE),
        resume=gui.add_button("Resume", icon=viser.Icon.PLAYER_PLAY, color="green", visible=False),
        step=gui.add_button_group("Step", tuple(STEPS), hint="Single 1 ms control ticks", visible=False),
        reset_robot=gui.add_button(
            "Reset robot", icon=viser.Icon.REFRESH, color="gray", hint="Stand the robot at the start"
        ),
        speed=gui.add_slider(
            "Speed ×",
            MIN_SPEED,
            MAX_SPEED,
            0.05,  # the box shows 0.25 for the 1/4x button, not 0.3
            min(speed, MAX_SPEED),
            marks=((1.0, "1"), (16.0, "16"), (32.0, "32"), (64.0, "64")),
        ),
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

    @guarded
    def on_speed(event: viser.GuiEvent) -> None:
        try:
            value, message = checked("Speed", panel.speed.value, MIN_SPEED, MAX_SPEED, "x")
        except Refused:
            panel.speed.value = panel.applied_speed
            raise
        if message:
            notify(event.client, "Speed clamped", message, "warning")
            panel.speed.value = value
        panel.applied_speed = value
        ctx.loop.set_speed(value)

    @guarded
    def on_stay(_: viser.GuiEvent) -> None:
        ctx.loop.set_stay_fallen(bool(panel.stay_fallen.value))

    panel.speed.on_update(on_speed)
    panel.stay_fallen.on_update(on_stay)
    return panel
