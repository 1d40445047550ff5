"""View panel: camera follow or free, home view, trail, phase label and the physics overlays."""

from __future__ import annotations

import dataclasses

import viser
from hopper.app.dashboard.feedback import guarded
from hopper.app.dashboard.physics import PhysicsView
from hopper.app.dashboard.scene import CameraFollow, RobotView, Trail, configure_lighting


@dataclasses.dataclass
class ViewPanel:
    follow: viser.GuiCheckboxHandle
    home: viser.GuiButtonHandle
    trail: viser.GuiCheckboxHandle
    label: viser.GuiCheckboxHandle
    shadows: viser.GuiCheckboxHandle
    physics: viser.GuiCheckboxHandle
    reset_button: viser.GuiButtonHandle

    def reset(self) -> None:
        self.follow.value = self.trail.value = self.label.value = self.shadows.value = self.physics.value = True


def build_view_panel(
    gui: viser.GuiApi,
    scene: viser.SceneApi,
    camera: CameraFollow,
    trail: Trail,
    robot: RobotView,
    physics: PhysicsView | None = None,
) -> ViewPanel:
    """Scene options only: nothing here reaches the simulation."""
    panel = ViewPanel(
        follow=gui.add_checkbox("Follow robot", True, hint="Off: the world holds still (free camera)"),
        home=gui.add_button(
            "Side view", icon=viser.Icon.CAMERA, color="gray", hint="Put your camera back beside the robot"
        ),
        trail=gui.add_checkbox("Torso trail", True),
        label=gui.add_checkbox("Phase label", True),
        shadows=gui.add_checkbox("Shadows", True, hint="Untick on software-rendered (no GPU) browsers"),
        physics=gui.add_checkbox(
            "Forces and flight",
            True,
            hint="Ground reaction arrows (robot weight = 0.5 m), the predicted CoM arc and landing, "
            "the mouse's pull. Drag the torso to pull it.",
        ),
        reset_button=gui.add_button("Default view", icon=viser.Icon.RESTORE, color="dark"),
    )

    def on_shadows(_: viser.GuiEvent) -> None:
        configure_lighting(scene, shadows=bool(panel.shadows.value))

    def on_follow(_: viser.GuiEvent) -> None:
        camera.enabled = bool(panel.follow.value)

    def on_trail(_: viser.GuiEvent) -> None:
        trail.visible = bool(panel.trail.value)

    def on_label(_: viser.GuiEvent) -> None:
        robot.show_label = bool(panel.label.value)

    def on_physics(_: viser.GuiEvent) -> None:
        if physics is not None:
            physics.visible = bool(panel.physics.value)

    def on_home(event: viser.GuiEvent) -> None:
        if event.client is not None:
            camera.home(event.client)

    panel.follow.on_update(guarded(on_follow))
    panel.trail.on_update(guarded(on_trail))
    panel.label.on_update(guarded(on_label))
    panel.shadows.on_update(guarded(on_shadows))
    panel.physics.on_update(guarded(on_physics))
    panel.home.on_click(guarded(on_home))
    panel.reset_button.on_click(guarded(lambda _: panel.reset()))
    return panel
