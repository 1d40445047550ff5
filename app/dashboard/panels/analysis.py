"""Loop analysis beside the gains, the design helpers that write them, and the loop measured.

The analysis is of the flight plant (hopper.analysis.linearize): the whole model linearized early in a
flight of the present configuration, computed on a worker thread whenever gravity, terrain or
sensing change; a gain change only re-closes the loop (about 60 ms), so it follows every change,
on a worker thread of its own: never on the simulation's 1 kHz loop, which reports gain changes.
*Measure* injects a chirp into a simulation of its own (on the test stand, or over flights) at the
present gains or controller, on a worker thread, and draws the measured Bode plot over the model's
(hopper.analysis.bench, hopper.report.frequency).
"""

from __future__ import annotations

import dataclasses
import html
import logging
import math
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import viser
from hopper.app.dashboard.feedback import guarded, notify
from hopper.app.dashboard.panels import measured
from hopper.app.dashboard.panels.entry import NumberEntry

from hopper.analysis.design import lqr_bryson, place_poles
from hopper.analysis.linearize import Cancelled, flight_plant, settled_flight
from hopper.analysis.loop import LoopAnalysis, Plant, analyse
from hopper.config import Gains, SimConfig
from hopper.controllers import FlightLaw
from hopper.robot import PACKAGED, Robot

log = logging.getLogger(__name__)

ApplyGains = Callable[[Gains, str], None]  # (gains, what chose them)
MEASURE_ON = {"stand, legs locked": "locked", "stand, legs free": "free", "flight": "flight"}
MEASURE_FLIGHTS = 20  # flights a measurement in flight averages (~2 s of work)


@dataclasses.dataclass
class AnalysisPanel:
    html: viser.GuiHtmlHandle
    rate: NumberEntry  # deg/s, the rate disturbance whose cost is shown
    wn: NumberEntry
    zeta: NumberEntry
    max_pitch: NumberEntry
    max_torque: NumberEntry
    place_button: viser.GuiButtonHandle
    lqr_button: viser.GuiButtonHandle
    measure_on: viser.GuiDropdownHandle
    measure_button: viser.GuiButtonHandle
    measured_html: viser.GuiHtmlHandle
    bode: viser.GuiImageHandle
    apply_gains: ApplyGains
    gains: Gains
    config: SimConfig | None = None  # the simulation's, as last shown (show_law, update_plant)
    measuring: threading.Thread | None = None
    delay: int = 0
    note: str = ""  # what the analysis is of when not the PID's gains
    plant: Plant | None = None
    result: LoopAnalysis | None = None
    _generation: int = 0
    _lock: threading.RLock = dataclasses.field(default_factory=threading.RLock, repr=False)
    _workers: list[threading.Thread] = dataclasses.field(default_factory=list, repr=False)
    _closed: bool = False
    _shown: int = 0  # requests to show the loop; only the newest is computed
    _closer: ThreadPoolExecutor = dataclasses.field(
        default_factory=lambda: ThreadPoolExecutor(1, thread_name_prefix="loop-analysis"), repr=False
    )

    def show_gains(self, gains: Gains, delay: int | None = None) -> None:
        """Re-close the loop at these gains (and command delay, ticks) and show it."""
        with self._lock:
            self.gains = gains
            if delay is not None:
                self.delay = delay
            self._refresh()

    def show_law(self, law: FlightLaw, config: SimConfig) -> None:
        """Analyse the controller flying now: the PID at its gains; a law with `state_feedback()`
        (N m per rad, rad/s and rad/s of the wheel, e.g. LQR) as the PD part of it; others not."""
        with self._lock:
            self.config = config
            if law.compiled == "pid":
                self.note = ""
                self.show_gains(config.gains)
                return
            feedback = getattr(law.controller, "state_feedback", None)
            gains = None
            if feedback is not None:
                try:
                    k = feedback()
                    gains = Gains(kp=float(k[0]), ki=0.0, kd=float(k[1]))
                    self.note = (
                        f"{law.name} as state feedback: Kp {k[0]:.4g} N m/rad, Kd {k[1]:.4g} N m s/rad; its "
                        f"wheel-speed term {k[2]:.3g} N m s/rad is left out of this analysis"
                    )
                except Exception as exc:  # a gain outside the analysis' ranges, a failed design
                    self.note = f"no loop analysis for {law.name}: {exc}"
            else:
                self.note = f"no loop analysis: {law.name} is not a linear law (the analysis is for PID and LQR)"
            if gains is None:
                self._shown += 1  # a pending re-close of the PID's loop is not shown
                self.html.content = f"<div class='hd-analysis hd-dim'>{html.escape(self.note)}</div>"
                return
            self.show_gains(gains)

    def update_plant(self, config: SimConfig) -> None:
        """Linearize a flight of `config` on a worker thread; the newest request wins."""
        with self._lock:
            self._generation += 1
            generation = self._generation
            self.config = config
            self.delay = config.command_delay_ticks
            self.html.content = _render(None, self.gains, self.plant, pending=True)

        def work() -> None:
            try:
                plant = flight_plant(settled_flight(config, cancelled=lambda: generation != self._generation))
            except Cancelled:
                return
            except Exception as exc:  # e.g. no flight at all: the panel says so, the dashboard goes on
                log.warning("no flight plant for the analysis: %s", exc)
                plant = None
            with self._lock:
                if generation == self._generation:
                    self.plant = plant
                    self._refresh()

        with self._lock:
            if self._closed:
                return
            self._workers = [w for w in self._workers if w.is_alive()]
            worker = threading.Thread(target=work, name="flight-plant", daemon=True)
            self._workers.append(worker)
            worker.start()

    def close(self, timeout: float = 30.0) -> None:
        """Stop a linearization under way and wait for it (s): a thread still stepping MuJoCo or
        compiling the kernel while the interpreter exits can crash it."""
        with self._lock:
            self._generation += 1
            self._closed = True
            workers = list(self._workers)
        if self.measuring is not None:
            workers.append(self.measuring)
        for worker in workers:
            worker.join(timeout)
        self._closer.shutdown(wait=True, cancel_futures=True)

    def _refresh(self) -> None:
        """Re-close the loop soon, on the analysis thread (the caller may be the simulation's loop)."""
        self._shown += 1
        if not self._closed:
            self._closer.submit(self._close_loop, self._shown)

    def _close_loop(self, shown: int) -> None:
        with self._lock:
            if shown != self._shown:
                return  # a newer request follows
            plant, gains, delay, rate, note = self.plant, self.gains, self.delay, self.rate.value, self.note
        try:
            result = analyse(plant, gains, delay, rate) if plant else None
        except Exception:
            log.exception("loop analysis failed")
            result = None
        with self._lock:
            if shown == self._shown:  # nothing changed meanwhile: show it
                self.result = result
                self.html.content = _render(result, gains, plant, note=note)

    def design(self, kind: str, client: viser.ClientHandle | None) -> None:
        """Run a design helper on the present plant and apply its gains (or say why not)."""
        with self._lock:
            plant, gains = self.plant, self.gains
        if plant is None:
            notify(client, "Analysis not ready", "The flight plant is still being computed; try again in a second.")
            return
        try:
            if kind == "poles":
                wn, zeta = self.wn.commit(client), self.zeta.commit(client)
                if wn is None or zeta is None:
                    return
                designed = place_poles(plant, wn, zeta, delay=self.delay)
                source = f"pole placement (wn {wn:g} rad/s, zeta {zeta:g})"
            else:
                max_pitch, max_torque = self.max_pitch.commit(client), self.max_torque.commit(client)
                if max_pitch is None or max_torque is None:
                    return
                designed = lqr_bryson(plant.inertia.effective, max_pitch, max_torque, ki=gains.ki)
                source = f"LQR (Bryson: {max_pitch:g} deg, {max_torque:g} N m)"
        except ValueError as exc:
            notify(client, "Design refused", str(exc), "warning")
            return
        self.apply_gains(designed, source)

    def measure(self, client: viser.ClientHandle | None) -> None:
        """Measure the loop at the present gains or controller, on a worker thread, and draw it."""
        with self._lock:
            if self.measuring is not None and self.measuring.is_alive():
                notify(client, "Measuring", "A measurement is under way; its plot comes when it ends.")
                return
            if self.config is None or self._closed:
                notify(client, "Not ready", "The simulation is starting; try again in a second.")
                return
            config = self.config
            if config.controller == "pid":
                config = dataclasses.replace(config, gains=self.gains)
            where = MEASURE_ON[self.measure_on.value]
            self.measured_html.content = (
                f"<div class='hd-measured hd-dim'>measuring ({html.escape(self.measure_on.value)})…</div>"
            )
            self.measuring = threading.Thread(
                target=self._measure, args=(config, where, client), name="measure", daemon=True
            )
            self.measuring.start()

    def _measure(self, config: SimConfig, where: str, client: viser.ClientHandle | None) -> None:
        from hopper.analysis import bench
        from hopper.analysis.frequency import ChirpSpec

        try:
            if where == "flight":
                spec = ChirpSpec(f_min=5.0, f_max=200.0, amplitude=bench.FLIGHT_AMPLITUDE, length=0.4, kind="linear")
                result = bench.measure_flight(config, spec, MEASURE_FLIGHTS)
            else:
                spec = ChirpSpec(f_min=1.0, f_max=300.0, amplitude=bench.STAND_AMPLITUDE, length=10.0)
                sim = bench.stand(dataclasses.replace(config, terrain="flat"), where)
                result = bench.measure_stand(sim, spec)
            image = measured.bode_image(result)
        except Exception as exc:  # a controller that cannot fly the stand, no flight: say so, go on
            log.warning("measurement failed: %s", exc)
            with self._lock:
                self.measured_html.content = measured.failed_html(str(exc))
            notify(client, "Not measured", str(exc), "warning")
            return
        with self._lock:
            if self._closed:
                return
            measured.show(result, image, self.bode, self.measured_html)
        notify(client, "Loop measured", measured.summary(result))


def _render(
    result: LoopAnalysis | None, gains: Gains, plant: Plant | None, pending: bool = False, note: str = ""
) -> str:
    if result is None:
        text = "linearizing a flight…" if pending or plant is None else "no analysis"
        return f"<div class='hd-analysis hd-dim'>{text}</div>"
    inertia = plant.inertia if plant else None
    rows = []
    if not result.stable:
        rows.append(("loop", "<b class='hd-bad'>unstable</b>: a mode grows within a flight"))
    else:
        rows.append(("pair", f"ω<sub>n</sub> {result.wn:.1f} rad/s · ζ {result.zeta:.2f}"))
    pm = "∞" if math.isinf(result.phase_margin_deg) else f"{result.phase_margin_deg:.0f}°"
    gm = "∞" if math.isinf(result.gain_margin_db) else f"{result.gain_margin_db:.1f} dB"
    pm_class = "hd-bad" if result.phase_margin_deg < 30.0 else ""
    at = "" if math.isnan(result.crossover_rad_s) else f" at {result.crossover_rad_s:.0f} rad/s"
    rows.append(("margins", f"<span class='{pm_class}'>phase {pm}</span>{at} · gain {gm}"))
    rows.append(("poles", ", ".join(_pole(p) for p in _pairs(result.poles)) + " 1/s"))
    if inertia is not None:
        rows.append(("inertia", f"J {inertia.effective:.3f} kg m² legs held · {inertia.torso:.3f} torso alone"))
    torque_class = "hd-bad" if result.torque_fraction > 1.0 else ""
    momentum_class = "hd-bad" if result.momentum_fraction > 1.0 else ""
    rows.append(
        (
            f"{result.rate_disturbance_deg_s:g}°/s turn",
            f"<span class='{torque_class}'>{result.peak_torque:.1f} N m ({result.torque_fraction:.0%} of"
            f" {result.torque_limit:g})</span> · <span class='{momentum_class}'>{result.peak_momentum:.2f} N m s"
            f" ({result.momentum_fraction:.0%} of {result.momentum_capacity:.2f})</span>",
        )
    )
    delay = f", {result.delay_ticks} ms command delay" if result.delay_ticks else ""
    body = "".join(f"<tr><td>{html.escape(k)}</td><td>{v}</td></tr>" for k, v in rows)
    caption = note + delay if note else f"flight loop at Kp {gains.kp:.4g}, Ki {gains.ki:.4g}, Kd {gains.kd:.4g}{delay}"
    caption = html.escape(caption)
    return f"<div class='hd-analysis'><table>{body}</table><div class='hd-dim'>{caption}</div></div>"


def _pairs(poles: tuple[complex, ...]) -> list[complex]:
    """One of each conjugate pair (the upper), slowest first, at most six."""
    return [p for p in poles if p.imag >= 0.0][:6]


def _pole(p: complex) -> str:
    if abs(p.imag) < 1e-6:
        return f"{p.real:.3g}"
    return f"{p.real:.3g}±{abs(p.imag):.3g}j"


def build_analysis_panel(
    gui: viser.GuiApi, initial: Gains, apply_gains: ApplyGains, robot: Robot = PACKAGED
) -> AnalysisPanel:
    """The analysis (HTML) and the two design helpers, in folders of the Gains tab; Bryson's torque
    is `robot`'s wheel limit by default."""
    with gui.add_folder("Loop analysis"):
        handle = gui.add_html(_render(None, initial, None, pending=True))
        rate = _entry(gui, "Turn to stop", 60.0, 1.0, 1000.0, "deg/s", "The rate disturbance whose cost is shown")
        measure_on = gui.add_dropdown("Measure on", tuple(MEASURE_ON), initial_value="stand, legs locked",
                                      hint="Inject a chirp on the test stand, or over flights")  # fmt: skip
        measure = gui.add_button(
            "Measure", icon=viser.Icon.WAVE_SINE, hint="The loop measured by injection, over the model's"
        )
        measured_html = gui.add_html("<div class='hd-measured hd-dim'>not measured yet</div>")
        bode = gui.add_image(measured.blank(), label="Bode: measured over predicted", format="png", visible=False)
    with gui.add_folder("Design gains", expand_by_default=False):
        wn = _entry(gui, "ωn", 25.0, 1.0, 200.0, "rad/s", "Natural frequency of the dominant pair")
        zeta = _entry(gui, "ζ", 0.7, 0.05, 2.0, "", "Damping ratio of the dominant pair")
        place = gui.add_button("Place poles", icon=viser.Icon.TARGET, hint="Kp, Ki, Kd giving this pair in flight")
        max_pitch = _entry(gui, "max pitch", 3.0, 0.1, 90.0, "deg", "Bryson: the pitch error worth the full torque")
        max_torque = _entry(
            gui, "max torque", robot.wheel_torque_limit, 0.1, 100.0, "N m", "Bryson: the torque allowed"
        )
        lqr = gui.add_button("LQR (Bryson)", icon=viser.Icon.MATH_FUNCTION, hint="Kp, Kd of the 2-state LQR; Ki kept")
    panel = AnalysisPanel(
        html=handle,
        rate=rate,
        wn=wn,
        zeta=zeta,
        max_pitch=max_pitch,
        max_torque=max_torque,
        place_button=place,
        lqr_button=lqr,
        measure_on=measure_on,
        measure_button=measure,
        measured_html=measured_html,
        bode=bode,
        apply_gains=apply_gains,
        gains=initial,
    )
    rate.on_apply = lambda _value, _client: panel.show_gains(panel.gains)
    place.on_click(guarded(lambda event: panel.design("poles", event.client)))
    lqr.on_click(guarded(lambda event: panel.design("lqr", event.client)))
    measure.on_click(guarded(lambda event: panel.measure(event.client)))
    return panel


def _entry(gui: viser.GuiApi, label: str, value: float, low: float, high: float, unit: str, hint: str) -> NumberEntry:
    handle = gui.add_text(f"{label} ({unit})" if unit else label, "", hint=hint)
    return NumberEntry(handle, label, low, high, unit, value=value)
