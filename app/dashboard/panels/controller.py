"""Controller panel: which law flies the wheel in flight (hopper.controllers), and its params.

The selector offers the built-ins that load and the specs the server was started with
(--controller, --controller-choice): a browser never names a file or module to import, since
that would run code of its choosing on the server. Picking one queues SetController; the
simulation emits ControllerChanged when it flies, and the panel then shows that controller's
declared params (the PID's are the gain sliders below). A controller that cannot fly is refused
with a notice; one that fails in flight hands over to the PID (ControllerFailed), and the panel
follows.

Each param is a slider to drag and a box to type, as the Gains panel's: the slider's own number box
is hidden (it applied every keystroke), the box applies after a quiet time, clamps to the param's
declared range with a notice, refuses text that is no number. Slider and box show the value in use:
set from either, or by the simulation (ControllerChanged), or again after the law refused a value.
"""

from __future__ import annotations

import dataclasses
import html
import threading
from collections.abc import Callable

import viser
from hopper.app.dashboard.feedback import Refused, checked, guarded, notify
from hopper.app.dashboard.panels import PanelContext
from hopper.app.dashboard.panels.entry import NumberEntry, hide_slider_boxes

from hopper.commands import SetController, SetControllerParam
from hopper.controllers import BUILTIN, ControllerError, FlightLaw, Param, load_class

SLIDER_STEPS = 200  # a param's slider moves in 1/200 of its range; typed values may fall between


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
    entries: dict[str, NumberEntry] = dataclasses.field(default_factory=dict)  # the typed boxes, by param
    flying: str = "pid"
    _built: tuple[str, tuple[Param, ...]] | None = None  # (spec, params) the handles were built for
    # Each controller's params as last flown this session: switching back flies them again, as the
    # PID keeps its gains (the Gains panel's), rather than the law's defaults.
    remembered: dict[str, dict[str, float]] = dataclasses.field(default_factory=dict)
    _style: viser.GuiHtmlHandle | None = None  # hides the sliders' own boxes
    # Values sent and not yet back (each applied one is a ControllerChanged): while more are on their
    # way (a drag sends many), the older ones coming back must not move the slider under the pointer.
    _pending: int = 0
    _lock: threading.RLock = dataclasses.field(default_factory=threading.RLock, repr=False)

    def show(self, law: FlightLaw, fault: str | None = None) -> None:
        """Show the controller flying now: the choice, a line about it, its params' sliders and boxes.

        The same controller with other values (a param changed) keeps its handles and shows the values.
        """
        with self._lock:
            if law.spec not in self.choice.options:
                self.choice.options = (*self.choice.options, law.spec)
            # Only a change of law moves the selector: the same law shown again (a param applied)
            # must not undo an operator's pick whose callback has not run yet, which then read the
            # old law back from the selector and was dropped as no change.
            if law.spec != self.flying:
                self.choice.value = law.spec
            self.flying = law.spec
            if law.params:
                self.remembered[law.spec] = dict(law.values)
            compiled = " · compiled into the kernel" if law.compiled else ""
            failed = f"<div class='hd-bad'>{html.escape(fault)}</div>" if fault else ""
            short = html.escape(law.spec.rpartition("/")[2])  # a file spec by its file's name; the path on hover
            info = (
                f"<div class='hd-law' title='{html.escape(law.spec)}'><span class='hd-dim'>flying</span> "
                f"<b>{html.escape(law.name)}</b> <span class='hd-dim'>({short}){compiled}</span>{failed}</div>"
            )
            if self.info.content != info:
                self.info.content = info
            for handle in self.pid_handles:
                handle.visible = law.spec == "pid"  # type: ignore[attr-defined]
            built = (law.spec, law.params)
            if built == self._built:
                self._follow(law.values)
                return
            self._clear()
            self._built = built
            if law.spec == "pid":
                self.params.visible = False
                return
            values = law.values
            with self.params:
                for p in law.params:
                    self._add(p, values[p.name])
                self._style = hide_slider_boxes(self.gui, list(self.sliders.values()))
            self.params.visible = bool(law.params)

    def refused(self, law: FlightLaw) -> None:
        """Show the law that still flies in the selector, after a pick the simulation refused."""
        with self._lock:
            self.choice.value = law.spec
            self.show(law)

    def resync(self, law: FlightLaw) -> None:
        """Show the values in use again, after the simulation refused one (CommandFailed)."""
        with self._lock:
            self._pending = 0
            self.show(law)

    def apply(self, name: str, value: float, slider: viser.GuiSliderHandle[float]) -> None:
        """Queue `value` for the param whose slider is `slider` and show it in slider and box.

        From viser's and the boxes' timer threads; a slider or box of a controller no longer shown
        (its handles were rebuilt meanwhile) changes nothing.
        """
        with self._lock:
            if self.sliders.get(name) is not slider:
                return
            self._pending += 1
            self.ctx.submit(SetControllerParam(name, value))
            self._show_value(name, value)

    def _add(self, p: Param, value: float) -> None:
        low, high = p.range
        unit = f", {p.unit}" if p.unit else ""
        slider = self.gui.add_slider(p.name, low, high, (high - low) / SLIDER_STEPS, value, hint=f"{p.name}{unit}")
        box = self.gui.add_text(
            p.unit or p.name, "", hint=f"Type {p.name}{unit}: {low:g} to {high:g}; applied after a pause"
        )
        self.sliders[p.name] = slider
        self.entries[p.name] = NumberEntry(
            box, p.name, low, high, p.unit, value=value, on_apply=lambda v, _client: self.apply(p.name, v, slider)
        )
        slider.on_update(self._on_slider(p, slider))

    def _on_slider(self, p: Param, slider: viser.GuiSliderHandle[float]) -> Callable[[viser.GuiEvent], None]:
        @guarded
        def handler(event: viser.GuiEvent) -> None:
            if event.client is None:  # set by the panel: already in use
                return
            low, high = p.range
            try:
                value, message = checked(p.name, slider.value, low, high, p.unit)
            except Refused:
                with self._lock:
                    if self.sliders.get(p.name) is slider:  # show the value in use again
                        slider.value = self.entries[p.name].value
                raise
            if message:
                notify(event.client, "Value clamped", message, "warning")
            self.apply(p.name, value, slider)

        return handler

    def _follow(self, values: dict[str, float]) -> None:
        """Show the simulation's values once every value sent is among them (under the lock)."""
        if self._pending:
            self._pending -= 1
            if self._pending:
                return
        for name, value in values.items():
            self._show_value(name, value)

    def _show_value(self, name: str, value: float) -> None:
        slider, entry = self.sliders.get(name), self.entries.get(name)
        if slider is None or entry is None:
            return
        if slider.value != value:
            slider.value = value  # a program assignment: the slider's handler ignores it
        if entry.value != value:
            entry.show(value)

    def _clear(self) -> None:
        """Remove the params' handles (under the lock)."""
        for entry in self.entries.values():
            entry.close()
            entry.handle.remove()
        for slider in self.sliders.values():
            slider.remove()
        if self._style is not None:
            self._style.remove()
        self.sliders, self.entries, self._style, self._built = {}, {}, None, None
        self._pending = 0


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
        spec = panel.choice.value
        ctx.submit(SetController(spec, tuple(panel.remembered.get(spec, {}).items())))

    panel.choice.on_update(on_choice)
    return panel
