"""Controller panel: which law flies the wheel in flight (hopper.controllers), and its params as sliders.

The selector offers the built-ins that load and the specs the server was started with
(--controller, --controller-choice): a browser never names a file or module to import, since
that would run code of its choosing on the server. Picking one queues SetController; the
simulation emits ControllerChanged when it flies, and the panel then shows that controller's
declared params (the PID's are the gain sliders below). A controller that cannot fly is refused
with a notice; one that fails in flight hands over to the PID (ControllerFailed), and the panel
follows.
"""

from __future__ import annotations

import dataclasses
import html
import threading

import viser
from hopper.app.dashboard.feedback import guarded
from hopper.app.dashboard.panels import PanelContext

from hopper.commands import SetController, SetControllerParam
from hopper.controllers import BUILTIN, ControllerError, FlightLaw, load_class

SLIDER_STEPS = 200  # a param's slider moves in 1/200 of its range


def available(extra: tuple[str, ...] = ()) -> tuple[str, ...]:
    """The built-ins that load here (an optional extra may be missing), then the `extra` specs."""
    names = []
    for name in BUILTIN:
        try:
            load_class(name)
        except ControllerError:
            continue
        names.append(name)
    return tuple(dict.fromkeys((*names, *extra)))


@dataclasses.dataclass
class ControllerPanel:
    gui: viser.GuiApi
    ctx: PanelContext
    choice: viser.GuiDropdownHandle[str]
    info: viser.GuiHtmlHandle
    params: viser.GuiFolderHandle
    pid_handles: tuple[object, ...] = ()  # the gain sliders and boxes: shown while the PID flies
    sliders: dict[str, viser.GuiSliderHandle[float]] = dataclasses.field(default_factory=dict)
    flying: str = "pid"
    _lock: threading.RLock = dataclasses.field(default_factory=threading.RLock, repr=False)

    def show(self, law: FlightLaw, fault: str | None = None) -> None:
        """Show the controller flying now: the choice, a line about it, its params' sliders."""
        with self._lock:
            self.flying = law.spec
            if law.spec not in self.choice.options:
                self.choice.options = (*self.choice.options, law.spec)
            self.choice.value = law.spec
            compiled = " · compiled into the kernel" if law.compiled else ""
            failed = f"<div class='hd-bad'>{html.escape(fault)}</div>" if fault else ""
            short = html.escape(law.spec.rpartition("/")[2])  # a file spec by its file's name; the path on hover
            self.info.content = (
                f"<div class='hd-law' title='{html.escape(law.spec)}'><span class='hd-dim'>flying</span> "
                f"<b>{html.escape(law.name)}</b> <span class='hd-dim'>({short}){compiled}</span>{failed}</div>"
            )
            for slider in self.sliders.values():
                slider.remove()
            self.sliders = {}
            for handle in self.pid_handles:
                handle.visible = law.spec == "pid"  # type: ignore[attr-defined]
            if law.spec == "pid":
                self.params.visible = False
                return
            values = law.values
            with self.params:
                for p in law.params:
                    low, high = p.range
                    slider = self.gui.add_slider(
                        p.name, low, high, (high - low) / SLIDER_STEPS, values[p.name], hint=f"{p.name}, {p.unit}"
                    )
                    slider.on_update(self._on_param(p.name))
                    self.sliders[p.name] = slider
            self.params.visible = bool(law.params)

    def _on_param(self, name: str):  # noqa: ANN202 (a viser callback)
        @guarded
        def handler(event: viser.GuiEvent) -> None:
            if event.client is None:
                return
            self.ctx.submit(SetControllerParam(name, float(self.sliders[name].value)))

        return handler


def build_controller_panel(
    gui: viser.GuiApi, ctx: PanelContext, initial: str, choices: tuple[str, ...] = ()
) -> ControllerPanel:
    """The selector and the params folder, at the top of the Gains tab."""
    panel = ControllerPanel(
        gui=gui,
        ctx=ctx,
        choice=gui.add_dropdown(
            "Controller",
            available((initial, *choices)),
            initial_value=initial,
            hint="The flight's wheel law; more with --controller-choice (README: Bring your own controller)",
        ),
        info=gui.add_html(""),
        params=gui.add_folder("Controller params"),
    )
    panel.params.visible = False

    @guarded
    def on_choice(event: viser.GuiEvent) -> None:
        if event.client is None or panel.choice.value == panel.flying:
            return
        ctx.submit(SetController(panel.choice.value))

    panel.choice.on_update(on_choice)
    return panel
