"""Stand panel (World tab): put the live robot on the gimbal test stand (hopper.stand) and back.

On the stand the Disturb tab's kicks act as in flight; the reference box steps the pitch the
attitude loop holds (deg, within hopper.stand.REFERENCE_LIMIT); its Chirp injection folder plays a chirp into
the loop (panels.inject). A reference off the stand, or out of range, is refused with a
notification and the loop runs on.
"""

from __future__ import annotations

import dataclasses
import math

import viser
from hopper.app.dashboard.feedback import guarded
from hopper.app.dashboard.panels import PanelContext
from hopper.app.dashboard.panels.entry import NumberEntry
from hopper.app.dashboard.panels.inject import InjectPanel, build_inject_panel

from hopper.commands import SetReference
from hopper.stand import REFERENCE_LIMIT

# What the Mode dropdown shows -> what Dashboard.set_mode takes.
MODES = {"Hopping": "hop", "Stand, legs locked": "stand locked", "Stand, legs free": "stand free"}


@dataclasses.dataclass
class StandPanel:
    ctx: PanelContext
    mode: viser.GuiDropdownHandle[str]
    reference: NumberEntry
    inject: InjectPanel

    def apply_mode(self) -> None:
        mode = MODES[str(self.mode.value)]  # KeyError if a browser sent another: refused
        self.ctx.loop.set_mode(mode)
        self.reference.show(0.0)  # a new simulation holds 0
        self.inject.on_stand = mode != "hop"

    def reset(self) -> None:
        self.mode.value = "Hopping"
        self.inject.on_stand = False


def build_stand_panel(gui: viser.GuiApi, ctx: PanelContext) -> StandPanel:
    limit = round(math.degrees(REFERENCE_LIMIT), 9)  # deg: degrees(radians(30)) is 29.999999999999996
    mode = gui.add_dropdown(
        "Mode", tuple(MODES), initial_value="Hopping", hint="Hop over the terrain, or hold the robot on the test stand"
    )
    box = gui.add_text("Reference °", "", hint=f"The stand's pitch reference, -{limit:g} to {limit:g} deg: a step")
    entry = NumberEntry(
        box,
        "Reference",
        -limit,
        limit,
        "deg",
        value=0.0,
        on_apply=lambda value, _client: ctx.submit(SetReference(math.radians(value))),
    )
    with gui.add_folder("Chirp injection", expand_by_default=False):
        inject = build_inject_panel(gui, ctx)
    panel = StandPanel(ctx, mode, entry, inject)
    mode.on_update(guarded(lambda _: panel.apply_mode()))
    return panel
