"""Inject panel (World tab, Test stand): a chirp played into the live stand's loop as it runs, and
its Bode plot over the model's once it has played.

The chirp (hopper.analysis.frequency.ChirpSpec: kind, band, amplitude, length) is added at the
wheel torque (N m) or at the pitch reference (deg) by the loop, one sample a tick
(hopper.stand.Injection); kicks, reference steps and the charts go on meanwhile, and a recording
carries the injected signal. The estimate and its plot are made on a worker thread, never on the
loop. Each box takes what ChirpSpec takes of its number (hopper.analysis.frequency.chirp_limits):
past a limit it is clamped to it, past an excluded one (0, the loop's Nyquist frequency) refused, with
a notice that names the limit. What ties the numbers together (the band's order, two cycles of its
lowest frequency) is judged by ChirpSpec at Inject; so are an injection off the stand or over another.
"""

from __future__ import annotations

import contextlib
import dataclasses
import html
import logging
import math
from concurrent.futures import ThreadPoolExecutor

import viser
from hopper.app.dashboard.feedback import format_number, guarded, notify
from hopper.app.dashboard.panels import PanelContext, measured
from hopper.app.dashboard.panels.entry import NumberEntry

from hopper.analysis.bench import REFERENCE_AMPLITUDE, STAND_AMPLITUDE
from hopper.analysis.frequency import ChirpSpec, InvalidChirp, Limit, chirp_limits, excitation
from hopper.commands import Inject
from hopper.stand import Injection

log = logging.getLogger(__name__)

# What the dropdowns show -> ChirpSpec's words.
AT = {"wheel torque (N m)": "input", "pitch reference (deg)": "reference"}
KINDS = {"logarithmic": "log", "linear": "linear", "stepped sines": "stepped"}
# Defaults that stay linear, and units (the reference's shown in deg, rad in ChirpSpec and the CLI).
AMPLITUDE = {"input": (STAND_AMPLITUDE, "N m"), "reference": (math.degrees(REFERENCE_AMPLITUDE), "deg")}


def amplitude_limit(at: str) -> Limit:
    """ChirpSpec's amplitude range at `at`, in the unit the box shows (deg at the reference)."""
    limit = chirp_limits(at)["amplitude"]
    if at == "input":
        return limit
    # 15 deg, not degrees(radians(15)) = 14.999999999999998: what the box shows and clamps to.
    return limit._replace(high=round(math.degrees(limit.high), 9), unit="deg")


def describe(spec: ChirpSpec) -> str:
    """The chirp in the event log's words: "a 20 s logarithmic chirp, 0.5-40 Hz, 2 N m"."""
    size = f"{spec.amplitude:.3g} N m" if spec.at == "input" else f"{math.degrees(spec.amplitude):.3g} deg"
    band = f"{spec.f_min:g}-{spec.f_max:g} Hz, {size}"
    if spec.kind == "stepped":
        return f"{spec.length:g} s of stepped sines, {band}"
    words = {"log": "logarithmic", "linear": "linear"}[spec.kind]
    return f"a {spec.length:g} s {words} chirp, {band}"


def bound(entry: NumberEntry, limit: Limit) -> None:
    """Give a box the range it clamps (or refuses) typed numbers to."""
    entry.low, entry.high, entry.unit = limit.low, limit.high, limit.unit
    entry.above, entry.below, entry.why = True, limit.below, limit.why  # a Limit's low is excluded


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
        at = AT[str(self.at.value)]
        value, unit = AMPLITUDE[at]
        bound(self.amplitude, amplitude_limit(at))
        self.amplitude.handle.label = f"Amplitude ({unit})"
        self.amplitude.show(value)

    def spec(self, client: viser.ClientHandle | None) -> ChirpSpec | None:
        """The chirp typed now, or None (refused, with a notice)."""
        values = [entry.commit(client) for entry in (self.f_min, self.f_max, self.amplitude, self.length)]
        if None in values:
            return None  # the entry has said why
        f_min, f_max, amplitude, length = values
        if f_min >= f_max:  # ChirpSpec says it in its own terms (f_min, f_max): here, the boxes'
            notify(client, "Chirp refused", f"From ({format_number(f_min)} Hz) must be below To "
                   f"({format_number(f_max)} Hz)", "warning")  # fmt: skip
            return None
        at = AT[str(self.at.value)]
        if at == "reference":  # the box's limit in deg, back in rad: never past ChirpSpec's by a rounding
            amplitude = min(math.radians(amplitude), chirp_limits(at)["amplitude"].high)
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
        what = describe(spec)  # the event log's words too
        self.status.content = f"<div class='hd-measured hd-dim'>injecting {html.escape(what)} at {where}…</div>"

        def done(injection: Injection) -> None:
            self._played(injection, spec, client)

        self.ctx.submit(Inject(excitation(spec), spec.at, done, what=what))

    def _played(self, injection: Injection, spec: ChirpSpec, client: viser.ClientHandle | None) -> None:
        """On the loop's thread: hand the records to the worker (or say why there are none)."""
        if injection.stopped:
            played_s = injection.played * injection.length_s / len(injection.d)
            self.status.content = (
                f"<div class='hd-measured hd-bad'>stopped after {played_s:.1f} of {injection.length_s:g} s: "
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
    limits = chirp_limits("input")

    def entry(label: str, value: float, limit: Limit, hint: str) -> NumberEntry:
        box = NumberEntry(
            gui.add_text(f"{label} ({limit.unit})", "", hint=hint), label, limit.low, limit.high, value=value
        )
        bound(box, limit)  # its unit, and which ends are excluded
        return box

    band = limits["f_max"]
    nyquist = f"{band.why} ({band.high:g} Hz)"
    amplitude_hint = (
        f"Up to {limits['amplitude'].high:g} N m at the wheel torque ({limits['amplitude'].why}), "
        f"{amplitude_limit('reference').high:g} deg at the reference"
    )
    at = gui.add_dropdown("Inject at", tuple(AT), hint="The plant input (the loop's response) or the reference")
    kind = gui.add_dropdown("Chirp", tuple(KINDS), hint="A swept sine, or sines held one frequency at a time")
    f_min = entry("From", 1.0, limits["f_min"], "The chirp's lowest frequency: under its highest")
    f_max = entry("To", 300.0, band, f"Its highest: under {nyquist}")
    amplitude = entry("Amplitude", AMPLITUDE["input"][0], amplitude_limit("input"), amplitude_hint)
    length = entry(
        "Length",
        10.0,
        limits["length"],
        f"The chirp's length, up to {limits['length'].high:g} s: 2 cycles of its lowest frequency at least",
    )
    button = gui.add_button("Inject", icon=viser.Icon.WAVE_SINE, hint="Play the chirp into the stand's loop, live")
    status = gui.add_html("<div class='hd-measured hd-dim'>nothing injected yet</div>")
    bode = gui.add_image(
        measured.blank(), label="Bode of the injection: measured over predicted", format="png", visible=False
    )
    panel = InjectPanel(ctx, at, kind, f_min, f_max, amplitude, length, button, status, bode)
    button.on_click(guarded(lambda event: panel.inject(event.client)))
    at.on_update(guarded(lambda _: panel.show_point()))
    return panel
