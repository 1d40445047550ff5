"""View panel: camera follow or free, home view, trail and phase label."""

from __future__ import annotations

import dataclasses

import viser

from app.dashboard.feedback import guarded
from app.dashboard.scene import CameraFollow, RobotView, Trail


@dataclasses.dataclass
class ViewPanel:
    follow: viser.GuiCheckboxHandle
    home: viser.GuiButtonHandle
    trail: viser.GuiCheckboxHandle
    label: viser.GuiCheckboxHandle

    def reset(self) -> None:
        self.follow.value = self.trail.value = self.label.value = True


def build_view_panel(gui: viser.GuiApi, camera: CameraFollow, trail: Trail, robot: RobotView) -> ViewPanel:
    """Scene options only: nothing here reaches the simulation."""
    panel = ViewPanel(
        follow=gui.add_checkbox("Follow robot", True, hint="Off: free camera"),
        home=gui.add_button("Side view", icon=viser.Icon.CAMERA, hint="Put your camera back beside the robot"),
        trail=gui.add_checkbox("Torso trail", True),
        label=gui.add_checkbox("Phase label", True),
    )

    def on_follow(_: viser.GuiEvent) -> None:
        camera.enabled = bool(panel.follow.value)

    def on_trail(_: viser.GuiEvent) -> None:
        trail.visible = bool(panel.trail.value)

    def on_label(_: viser.GuiEvent) -> None:
        robot.show_label = bool(panel.label.value)

    def on_home(event: viser.GuiEvent) -> None:
        if event.client is not None:
            camera.home(event.client)

    panel.follow.on_update(guarded(on_follow))
    panel.trail.on_update(guarded(on_trail))
    panel.label.on_update(guarded(on_label))
    panel.home.on_click(guarded(on_home))
    return panel
