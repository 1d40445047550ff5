"""Inject panel (World tab, Test stand): a chirp played into the live stand's loop as it runs, and
its Bode plot over the model's once it has played.

The chirp (hopper.analysis.frequency.ChirpSpec: kind, band, amplitude, length) is added at the
wheel torque (N m) or at the pitch reference (deg) by the loop, one sample a tick
(hopper.stand.Injection); kicks, reference steps and the charts go on meanwhile, and a recording
carries the injected signal. The estimate and its plot are made on a worker thread, never on the
loop. A bad spec, an injection off the stand or over another one is refused with a notice.
"""

from __future__ import annotations

import contextlib
import dataclasses
import html
import logging
import math
from concurrent.futures import ThreadPoolExecutor

import viser
from hopper.app.dashboard.feedback import guarded, notify
from hopper.app.dashboard.panels import PanelContext, measured
from hopper.app.dashboard.panels.entry import NumberEntry

from hopper.analysis.bench import REFERENCE_AMPLITUDE, STAND_AMPLITUDE
from hopper.analysis.frequency import ChirpSpec, InvalidChirp, excitation
from hopper.commands import Inject
from hopper.stand import Injection

log = logging.getLogger(__name__)

# What the dropdowns show -> ChirpSpec's words.
AT = {"wheel torque (N m)": "input", "pitch reference (deg)": "reference"}
KINDS = {"logarithmic": "log", "linear": "linear", "stepped sines": "stepped"}
# Defaults that stay linear, and units (the reference's shown in deg, rad in ChirpSpec and the CLI).
AMPLITUDE = {"input": (STAND_AMPLITUDE, "N m"), "reference": (math.degrees(REFERENCE_AMPLITUDE), "deg")}


@dataclasses.dataclass
class InjectPanel:
    ctx: PanelContext
    at: viser.GuiDropdownHandle[str]
    kind: viser.GuiDropdownHandle[str]
    f_min: NumberEntry  # Hz
    f_max: NumberEntry  # Hz
    amplitude: NumberEntry  # N m at the wheel torque, deg at the reference
    length: NumberEntry  # s
    button: viser.GuiButtonHandle
    status: viser.GuiHtmlHandle
    bode: viser.GuiImageHandle
    on_stand: bool = False  # the mode the panel last chose (the loop refuses off the stand anyway)
    _worker: ThreadPoolExecutor = dataclasses.field(
        default_factory=lambda: ThreadPoolExecutor(1, thread_name_prefix="injection"), repr=False
    )
    _closed: bool = False

    def show_point(self) -> None:
        """The amplitude box in the unit of the injection point chosen, at its default."""
        value, unit = AMPLITUDE[AT[str(self.at.value)]]
        self.amplitude.unit = unit
        self.amplitude.handle.label = f"Amplitude ({unit})"
        self.amplitude.show(value)

    def spec(self, client: viser.ClientHandle | None) -> ChirpSpec | None:
        """The chirp typed now, or None (refused, with a notice)."""
        values = [entry.commit(client) for entry in (self.f_min, self.f_max, self.amplitude, self.length)]
        if None in values:
            return None  # the entry has said why
        f_min, f_max, amplitude, length = values
        at = AT[str(self.at.value)]
        if at == "reference":
            amplitude = math.radians(amplitude)
        try:
            return ChirpSpec(f_min=f_min, f_max=f_max, amplitude=amplitude, length=length,
                             kind=KINDS[str(self.kind.value)], at=at)  # fmt: skip
        except InvalidChirp as exc:
            notify(client, "Chirp refused", str(exc), "warning")
            return None

    def inject(self, client: viser.ClientHandle | None) -> None:
        if not self.on_stand:
            notify(client, "Not on the stand", "an injection needs the stand: choose a stand mode first", "warning")
            return
        spec = self.spec(client)
        if spec is None:
            return
        where = "the wheel torque" if spec.at == "input" else "the pitch reference"
        self.status.content = (
            f"<div class='hd-measured hd-dim'>injecting a {spec.length:g} s {html.escape(spec.kind)} chirp, "
            f"{spec.f_min:g}-{spec.f_max:g} Hz, at {where}…</div>"
        )
        self.ctx.submit(Inject(excitation(spec), spec.at, lambda injection: self._played(injection, spec, client)))

    def _played(self, injection: Injection, spec: ChirpSpec, client: viser.ClientHandle | None) -> None:
        """On the loop's thread: hand the records to the worker (or say why there are none)."""
        if injection.stopped:
            self.status.content = (
                f"<div class='hd-measured hd-bad'>stopped after {injection.played} of {len(injection.d)} ticks: "
                f"{html.escape(injection.stopped)}</div>"
            )
            notify(client, "Injection stopped", injection.stopped, "warning")
            return
        with contextlib.suppress(RuntimeError):  # the worker is closed: the dashboard is stopping
            self._worker.submit(self._estimate, injection, spec, client)

    def _estimate(self, injection: Injection, spec: ChirpSpec, client: viser.ClientHandle | None) -> None:
        from hopper.analysis.bench import compare_stand

        try:
            result = compare_stand(injection.sim.legs, injection.start, spec, [injection.records()])
            image = measured.bode_image(result)
        except Exception as exc:  # an estimate that cannot be made (no crossover, ...): say so
            log.warning("injection estimate failed: %s", exc)
            self.status.content = measured.failed_html(str(exc))
            notify(client, "Not measured", str(exc), "warning")
            return
        if self._closed:
            return
        measured.show(result, image, self.bode, self.status)
        notify(client, "Injection measured", measured.summary(result))

    def close(self) -> None:
        """Drop estimates not begun and wait for the one under way."""
        self._closed = True
        self._worker.shutdown(wait=True, cancel_futures=True)


def build_inject_panel(gui: viser.GuiApi, ctx: PanelContext) -> InjectPanel:
    def entry(label: str, value: float, unit: str, hint: str) -> NumberEntry:
        # Words are refused here; the numbers are judged together by ChirpSpec (band, Nyquist, the motor).
        return NumberEntry(gui.add_text(f"{label} ({unit})", "", hint=hint), label, 0.0, 1e4, unit, value=value)

    at = gui.add_dropdown("Inject at", tuple(AT), hint="The plant input (the loop's response) or the reference")
    kind = gui.add_dropdown("Chirp", tuple(KINDS), hint="A swept sine, or sines held one frequency at a time")
    f_min = entry("From", 1.0, "Hz", "The chirp's lowest frequency")
    f_max = entry("To", 300.0, "Hz", "Its highest: under the loop's Nyquist frequency (500 Hz at 1 kHz)")
    value, unit = AMPLITUDE["input"]
    amplitude = entry("Amplitude", value, unit, "N m at the wheel torque, deg at the reference")
    length = entry("Length", 10.0, "s", "The chirp's length: 2 cycles of its lowest frequency at least")
    button = gui.add_button("Inject", icon=viser.Icon.WAVE_SINE, hint="Play the chirp into the stand's loop, live")
    status = gui.add_html("<div class='hd-measured hd-dim'>nothing injected yet</div>")
    bode = gui.add_image(
        measured.blank(), label="Bode of the injection: measured over predicted", format="png", visible=False
    )
    panel = InjectPanel(ctx, at, kind, f_min, f_max, amplitude, length, button, status, bode)
    button.on_click(guarded(lambda event: panel.inject(event.client)))
    at.on_update(guarded(lambda _: panel.show_point()))
    return panel
