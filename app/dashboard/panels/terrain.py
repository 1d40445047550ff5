"""Terrain panel: crater seed, regenerate, flat ground, and gravity presets."""

from __future__ import annotations

import dataclasses

import viser
from hopper.app.dashboard.feedback import Refused, guarded, notify_all
from hopper.app.dashboard.panels import PanelContext
from hopper.app.dashboard.panels.entry import NumberEntry

from hopper.commands import SetGravity, SetTerrain
from hopper.config import GRAVITY_PRESETS, MAX_SEED, MOON_GRAVITY, GaitParams
from hopper.control.gait import legs_cap
from hopper.robot import PACKAGED, Robot


def _preset_name(gravity: float) -> str:
    for name, value in GRAVITY_PRESETS.items():
        if abs(value - gravity) < 1e-9:
            return name.capitalize()
    return "Moon"


@dataclasses.dataclass
class TerrainPanel:
    ctx: PanelContext
    seed: NumberEntry
    flat: viser.GuiCheckboxHandle
    regenerate: viser.GuiButtonHandle
    next_seed: viser.GuiButtonHandle
    gravity: viser.GuiDropdownHandle[str]
    reset_button: viser.GuiButtonHandle
    default_seed: int
    default_flat: bool
    default_gravity: str  # the preset's name the dashboard started with
    robot: Robot = PACKAGED  # the flown robot and its gait: whether its legs cap the hop at a gravity
    gait: GaitParams = dataclasses.field(default_factory=GaitParams)

    def apply_terrain(self, client: viser.ClientHandle | None = None) -> None:
        """Queue a terrain rebuild from the panel's seed and flat choice (restarts the robot)."""
        value = self.seed.commit(client)  # a seed typed just before the click counts
        if value is None:  # refused, with a notice
            return
        seed, kind = int(value), "flat" if self.flat.value else "crater"
        self.ctx.submit(SetTerrain(kind, seed))

    def apply_gravity(self) -> None:
        name = str(self.gravity.value).lower()
        if name not in GRAVITY_PRESETS:  # only preset names may reach the core
            raise Refused(f"unknown gravity preset {self.gravity.value!r}")
        gravity = GRAVITY_PRESETS[name]
        try:
            cap = legs_cap(gravity, self.gait, self.robot)
        except ValueError:  # legs that cannot hold the robot there at all: the loop refuses it, and says so
            cap = None
        if cap is not None:  # the world changes for everyone: everyone is told why the robot stumbles
            notify_all(
                self.ctx.server,
                "Legs at their limit",
                f"At {gravity:g} m/s² this robot's {self.robot.leg_torque_limit:g} N m legs cap the hop at "
                f"{cap[0]:.2f} m of the {cap[1]:g} m asked: expect stumbles and falls on crater ground. "
                f"hopper-sim size --gravity {gravity:g} --out FILE writes the robot sized for this gravity; "
                "fly it with hopper-dashboard --model FILE (README: A robot sized for another gravity).",
                "warning",
            )
        self.ctx.submit(SetGravity(gravity))  # after the notice: once the loop has the gravity, it is out

    def show_gravity(self, gravity: float) -> None:
        """Show the gravity the simulation flies (m/s^2), after it refused another; the control's callback
        asks for it again, which changes nothing."""
        self.gravity.value = _preset_name(gravity)

    def reset(self) -> None:
        """Back to the starting terrain and gravity (one rebuild)."""
        self.gravity.value = self.default_gravity
        self.seed.show(self.default_seed)
        if self.flat.value != self.default_flat:
            self.flat.value = self.default_flat  # its callback rebuilds
        else:
            self.apply_terrain()


def build_terrain_panel(
    gui: viser.GuiApi,
    ctx: PanelContext,
    seed: int,
    kind: str,
    gravity: float = MOON_GRAVITY,
    robot: Robot = PACKAGED,
    gait: GaitParams | None = None,
) -> TerrainPanel:
    """Rebuilding hot-swaps the heightfield and restarts the robot; gravity applies at the next tick,
    with a warning to every client when the flown `robot`'s legs cap the hop of its `gait` there."""
    seed_box = gui.add_text("Seed", "", hint=f"A whole number from 0 to {MAX_SEED}; Regenerate applies it")
    panel = TerrainPanel(
        ctx=ctx,
        seed=NumberEntry(seed_box, "Seed", 0, MAX_SEED, value=seed, integer=True),
        flat=gui.add_checkbox("Flat ground", kind == "flat"),
        regenerate=gui.add_button("Regenerate", icon=viser.Icon.REFRESH, hint="Rebuild the terrain, restart the robot"),
        next_seed=gui.add_button(
            "Next seed", icon=viser.Icon.PLAYER_TRACK_NEXT, color="gray", hint="Seed + 1, then regenerate"
        ),
        gravity=gui.add_dropdown(
            "Gravity",
            tuple(name.capitalize() for name in GRAVITY_PRESETS),
            initial_value=_preset_name(gravity),
            hint=", ".join(f"{n.capitalize()} {g:g} m/s²" for n, g in GRAVITY_PRESETS.items()),
        ),
        reset_button=gui.add_button("Default terrain and gravity", icon=viser.Icon.RESTORE, color="dark"),
        default_seed=seed,
        default_flat=kind == "flat",
        default_gravity=_preset_name(gravity),
        robot=robot,
        gait=gait or GaitParams(),
    )

    def next_seed(event: viser.GuiEvent) -> None:
        seed = panel.seed.commit(event.client)
        if seed is None:
            return
        panel.seed.show(min(int(seed) + 1, MAX_SEED))
        panel.apply_terrain(event.client)

    panel.regenerate.on_click(guarded(lambda event: panel.apply_terrain(event.client)))
    panel.next_seed.on_click(guarded(next_seed))
    panel.flat.on_update(guarded(lambda event: panel.apply_terrain(event.client)))
    panel.gravity.on_update(guarded(lambda _: panel.apply_gravity()))
    panel.reset_button.on_click(guarded(lambda _: panel.reset()))
    return panel
