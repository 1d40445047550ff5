"""View panel: camera follow or free, home view, trail, phase label, lighting and the physics overlays."""

from __future__ import annotations

import dataclasses

import viser
from hopper.app.dashboard.config import LIGHTING
from hopper.app.dashboard.feedback import guarded
from hopper.app.dashboard.physics import PhysicsView
from hopper.app.dashboard.scene import CameraFollow, RobotView, Trail, configure_lighting


@dataclasses.dataclass
class ViewPanel:
    follow: viser.GuiCheckboxHandle
    home: viser.GuiButtonHandle
    trail: viser.GuiCheckboxHandle
    label: viser.GuiCheckboxHandle
    lighting: viser.GuiDropdownHandle[str]
    physics: viser.GuiCheckboxHandle
    reset_button: viser.GuiButtonHandle
    default_lighting: str = "full"  # the session's own (--lighting): what Default view goes back to

    def reset(self) -> None:
        self.follow.value = self.trail.value = self.label.value = self.physics.value = True
        self.lighting.value = self.default_lighting


def build_view_panel(
    gui: viser.GuiApi,
    scene: viser.SceneApi,
    camera: CameraFollow,
    trail: Trail,
    robot: RobotView,
    physics: PhysicsView | None = None,
    lighting: str = "full",
) -> ViewPanel:
    """Scene options only: nothing here reaches the simulation."""
    panel = ViewPanel(
        follow=gui.add_checkbox("Follow robot", True, hint="Off: the world holds still (free camera)"),
        home=gui.add_button(
            "Side view", icon=viser.Icon.CAMERA, color="gray", hint="Put your camera back beside the robot"
        ),
        trail=gui.add_checkbox("Torso trail", True),
        label=gui.add_checkbox("Phase label", True),
        lighting=gui.add_dropdown(
            "Lighting",
            LIGHTING,
            initial_value=lighting,
            hint="simple: no environment light and no shadows, for browsers without a GPU (about 4x the frame rate)",
        ),
        physics=gui.add_checkbox(
            "Forces and flight",
            True,
            hint="Ground reaction arrows (robot weight = 0.5 m), the predicted CoM arc and landing, "
            "the mouse's pull. Drag the torso to pull it.",
        ),
        reset_button=gui.add_button("Default view", icon=viser.Icon.RESTORE, color="dark"),
        default_lighting=lighting,
    )

    def on_lighting(_: viser.GuiEvent) -> None:
        configure_lighting(scene, str(panel.lighting.value))

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
    panel.lighting.on_update(guarded(on_lighting))
    panel.physics.on_update(guarded(on_physics))
    panel.home.on_click(guarded(on_home))
    panel.reset_button.on_click(guarded(lambda _: panel.reset()))
    return panel
