"""Measure the attitude loop as a lab would: inject, record, estimate, and lay it over the prediction.

On the stand one long chirp; in flight a short chirp in each of many flights (from SETTLE_S after
the apex, when the legs hold their landing pose, until the chirp ends: ~0.4 s of a lunar flight),
stitched into one estimate (hopper.analysis.frequency.estimate). Works for any controller: with a
linear law (PID, LQR) the model's curve and margins come along; for another (MPC, a policy) the
measured curve is all there is, and the result says so.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from hopper.analysis.frequency import (
    ChirpSpec,
    Margins,
    NotMeasured,
    Response,
    coherent_length,
    excitation,
    measure,
    measured_margins,
)
from hopper.analysis.predict import Predicted, linear_law, loop_of, response
from hopper.analysis.step import StepMetrics, metrics, predicted_step
from hopper.config import SimConfig
from hopper.control.kernel import EV_APEX, EV_FALL
from hopper.control.phases import Phase
from hopper.sim import Simulation
from hopper.snapshot import Snapshot
from hopper.stand import Legs, StandSimulation, record

SETTLE_S = 0.5  # s on the stand after a reset before a measurement: the legs and the loop at rest
# Default chirp amplitudes at the plant input (N m, of the motor's 29.5): above the gyro's noise
# through the law with realistic sensing (0.23 N m rms through kd = 30: at 0.5 N m the coherence at
# the crossover was ~0.9, at 2 N m 0.97-1.0), and in flight above what each flight does of itself
# (coherence 0.88 at 1 N m, 0.985 at 3). The loop is linear there: the same figures at 0.5 N m ideal.
STAND_AMPLITUDE = 2.0
FLIGHT_AMPLITUDE = 3.0
# Default chirp amplitude at the pitch reference, rad (2 deg), on the stand or in flight: a swing the
# loop follows linearly, far inside hopper.analysis.frequency.REFERENCE_LIMIT (15 deg); the dashboard's
# Inject panel offers the same (in deg).
REFERENCE_AMPLITUDE = math.radians(2.0)
FLIGHT_SETTLE_S = 0.1  # s after the apex: the legs hold their landing pose (hopper.analysis.linearize)
FLIGHT_LIMIT_S = 30.0  # s of simulation a flight may take to come (a fall or a stall ends the run)


@dataclasses.dataclass(frozen=True)
class Measurement:
    """A measured loop and what the model predicts for it; `note` says what could not be measured."""

    where: str  # "stand (legs locked)", "stand (legs free)", "flight"
    controller: str
    spec: ChirpSpec
    response: Response
    measured: Margins | None  # None: not measured (note says why)
    predicted: Predicted | None  # None: the law is not linear
    records: int  # records averaged (flights in flight)
    saturated_ticks: int  # ticks the motor's envelope clamped: then the response is not linear
    note: str = ""

    def to_json(self) -> dict:
        """A JSON-ready dict (hopper.report.frequency draws it): the curves on the measured grid."""
        r = self.response
        shown = r.loop if r.loop is not None else r.complementary
        predicted = None
        if self.predicted is not None:
            predicted = self.predicted.loop if r.loop is not None else self.predicted.reference
        return {
            "where": self.where,
            "controller": self.controller,
            "at": self.spec.at,
            "spec": dataclasses.asdict(self.spec),
            "records": self.records,
            "segments": r.segments,
            "saturated_ticks": self.saturated_ticks,
            "note": self.note,
            "f": r.f.tolist(),
            "coherence": r.coherence.tolist(),
            "measured_re": shown.real.tolist(),
            "measured_im": shown.imag.tolist(),
            "predicted_re": None if predicted is None else predicted.real.tolist(),
            "predicted_im": None if predicted is None else predicted.imag.tolist(),
            "measured_margins": None if self.measured is None else _finite(dataclasses.asdict(self.measured)),
            "predicted_margins": None
            if self.predicted is None
            else _finite(dataclasses.asdict(self.predicted.margins)),
        }

    def lines(self) -> list[str]:
        """The comparison as the CLI prints it."""
        m, p = self.measured, self.predicted
        head = f"{self.where}, {self.controller}: {self.spec.kind} chirp {self.spec.f_min:g}-{self.spec.f_max:g} Hz"
        head += f", {self.spec.amplitude:g} {'N m' if self.spec.at == 'input' else 'rad'} at the {self.spec.at}"
        head += f", {self.records} record{'s' * (self.records != 1)} of {self.spec.length:g} s"
        out = [head]
        rows = (("crossover", "Hz", "crossover_hz"), ("phase margin", "deg", "phase_margin_deg"))
        rows += (("gain margin", "dB", "gain_margin_db"),)
        out.append(f"  {'':14s} {'measured':>10s} {'predicted':>10s}")
        for label, unit, name in rows:
            mv = getattr(m, name) if m else math.nan
            pv = getattr(p.margins, name) if p else math.nan
            out.append(f"  {label + ' ' + unit:14s} {_fmt(mv):>10s} {_fmt(pv):>10s}")
        if m is not None and math.isnan(m.coherence):
            out.append(
                f"  coherence not estimated: the record is one Welch segment (its coherence is 1 whatever the "
                f"noise); a chirp of {coherent_length(self.spec):g} s or more gives two"
            )
        elif m is not None:
            out.append(f"  coherence at the crossover {m.coherence:.3f}")
        if self.saturated_ticks:
            out.append(f"  the motor saturated on {self.saturated_ticks} ticks: lower the amplitude")
        for note in (self.note, m.note if m else ""):
            if note:
                out.append(f"  {note}")
        if m is not None and not math.isfinite(m.gain_margin_db):
            out.append(f"  no -180 deg crossing measured up to {self.response.f[-1]:.0f} Hz: gain margin not measured")
        return out


def _finite(values: dict) -> dict:
    """JSON has no inf or NaN: those become None."""
    return {k: (v if not isinstance(v, float) or math.isfinite(v) else None) for k, v in values.items()}


def _fmt(value: float) -> str:
    return "-" if math.isnan(value) else "inf" if math.isinf(value) else f"{value:.2f}"


def _compare(
    where: str, sim: Simulation, spec: ChirpSpec, records: list, predicted_at: Simulation | None
) -> Measurement:
    response_ = measure(records, spec)
    law = linear_law(sim)
    note = ""
    predicted = None
    if law is None:
        note = f"{sim.law.name} is not a linear law of the API (no state_feedback): no prediction, no linear margins"
    elif predicted_at is not None:
        predicted = response(loop_of(predicted_at, law), response_.f)
    measured = None
    if spec.at == "input":
        try:
            measured = measured_margins(response_)
        except NotMeasured as exc:
            note = "; ".join(filter(None, (note, str(exc))))
    else:  # the reference gives the closed loop T alone: with the derivative on the rate, L is not T / (1 - T)
        why = "at the reference the closed loop T is measured (its Bode plot: --bode); margins need L: --at input"
        note = "; ".join(filter(None, (note, why)))
    saturated = int(sum(int(np.count_nonzero(r["saturated"])) for r in records))
    return Measurement(where, sim.law.name, spec, response_, measured, predicted, len(records), saturated, note)


def measure_stand(sim: StandSimulation, spec: ChirpSpec) -> Measurement:
    """Inject `spec` on the stand, from where the simulation is (settle it first)."""
    start = sim.snapshot(with_hops=False)
    records = [record(sim, excitation(spec), spec.at)]
    return compare_stand(sim.legs, start, spec, records)


def compare_stand(legs: Legs, start: Snapshot, spec: ChirpSpec, records: list[dict[str, np.ndarray]]) -> Measurement:
    """What `records` of `spec` played on a stand with legs `legs` from `start` measured, beside the
    model's prediction there (linearized on a copy of the stand at `start`, e.g. after a live
    injection: hopper.stand.Injection)."""
    twin = _twin(start.config, legs, start)
    return _compare(f"stand (legs {legs})", twin, spec, records, twin)


def _twin(config: SimConfig, legs: Legs, start: Snapshot) -> StandSimulation:
    twin = StandSimulation(config, legs)
    twin.restore(start)
    return twin


def stand(config: SimConfig, legs: str, settle_s: float = SETTLE_S) -> StandSimulation:
    """A stand of `config` with its legs `legs`, settled."""
    sim = StandSimulation(config, legs)  # type: ignore[arg-type]
    sim.settle(settle_s)
    return sim


def flight_window(config: SimConfig, share: float = 0.85) -> float:
    """The chirp length (s) that fits a flight of `config`: `share` of the time from FLIGHT_SETTLE_S
    after its first apex to its touchdown (about 0.4 s on the Moon, 0.2 s on Mars)."""
    sim = Simulation(config)
    apex = None
    while sim.time < FLIGHT_LIMIT_S and not sim.fallen:
        events = sim.step()
        if events & EV_APEX and apex is None:
            apex = sim.time
        elif apex is not None and sim.phase is not Phase.FLIGHT:
            return round(share * max(sim.time - apex - FLIGHT_SETTLE_S, 0.0), 3)
    raise NotMeasured(f"no flight within {FLIGHT_LIMIT_S:g} s of simulation")


def measure_flight(
    config: SimConfig, spec: ChirpSpec, flights: int, attach: Callable[[Simulation], None] | None = None
) -> Measurement:
    """A short chirp in each of `flights` flights, from FLIGHT_SETTLE_S after the apex; a flight
    that lands before its chirp ends is not used (the count says how many were). `attach` is given
    the simulation before it starts (a recording listens to it)."""
    if spec.at != "input":
        raise NotMeasured("in flight the loop is measured at the plant input")
    sim = Simulation(config)
    if attach is not None:
        attach(sim)
    settle = round(FLIGHT_SETTLE_S / config.timestep)
    records: list[dict[str, np.ndarray]] = []
    first: Simulation | None = None
    short = 0
    d = excitation(spec)
    limit = sim.time + FLIGHT_LIMIT_S * (flights + 1)
    while len(records) < flights:
        while not sim.step() & EV_APEX:
            if sim.fallen or sim.time > limit:
                raise NotMeasured(
                    f"the robot {'fell' if sim.fallen else 'stopped hopping'} after {len(records)} flights"
                )
        for _ in range(settle):
            if sim.step() & EV_FALL:
                break
        if sim.phase is not Phase.FLIGHT:
            short += 1
            continue
        if first is None:
            first = Simulation(config)
            first.restore(sim.snapshot(with_hops=False))
        # The sign alternates flight by flight: what each flight does of itself (the legs reaching,
        # the terrain's kick) is much alike from one to the next, and would be as correlated with
        # one chirp as the response is; with alternate signs it cancels in the averaged spectra.
        rec = record(sim, d if len(records) % 2 == 0 else -d, "input")
        if not (rec["phase"] == int(Phase.FLIGHT)).all():
            short += 1
            if short > 2 * flights:
                raise NotMeasured(f"flights end before a {spec.length:g} s chirp does: shorten it")
            continue
        records.append(rec)
    result = _compare("flight", sim, spec, records, first)
    if short:
        note = f"{short} flight{'s' * (short != 1)} landed before the chirp ended (not used)"
        result = dataclasses.replace(result, note="; ".join(filter(None, (result.note, note))))
    return result


@dataclasses.dataclass(frozen=True)
class StepResult:
    step_rad: float
    t: np.ndarray  # s from the step
    measured: np.ndarray  # rad, pitch less its value before the step
    predicted: np.ndarray | None
    measured_metrics: StepMetrics
    predicted_metrics: StepMetrics | None

    def to_json(self) -> dict:
        p = self.predicted_metrics
        return {
            "step_deg": math.degrees(self.step_rad),
            "t": self.t.tolist(),
            "measured": self.measured.tolist(),
            "predicted": None if self.predicted is None else self.predicted.tolist(),
            "measured_metrics": dataclasses.asdict(self.measured_metrics),
            "predicted_metrics": None if p is None else dataclasses.asdict(p),
        }

    def lines(self) -> list[str]:
        m, p = self.measured_metrics, self.predicted_metrics
        out = [f"step of the pitch reference, {math.degrees(self.step_rad):g} deg"]
        out.append(f"  {'':14s} {'measured':>10s} {'predicted':>10s}")
        for label, name, scale in (("rise ms", "rise_s", 1e3), ("overshoot %", "overshoot_pct", 1.0)):
            out.append(
                f"  {label:14s} {getattr(m, name) * scale:10.2f} {_fmt(getattr(p, name) * scale) if p else '-':>10s}"
            )
        out.append(f"  {'settling ms':14s} {m.settling_s * 1e3:10.1f} {_fmt(p.settling_s * 1e3) if p else '-':>10s}")
        return out


def step_response(sim: StandSimulation, step_rad: float, seconds: float = 1.5) -> StepResult:
    """Step the reference by `step_rad` on the stand and compare with the model's closed loop."""
    scratch = _twin(sim.config, sim.legs, sim.snapshot(with_hops=False))
    start = sim.state().pitch
    rec = record(sim, np.full(round(seconds / sim.model.opt.timestep), step_rad), "reference")
    sim.set_reference(sim.reference + step_rad)  # the step stays when the record ends
    t = np.arange(len(rec["pitch"])) * sim.model.opt.timestep
    measured = rec["pitch"] - start
    law = linear_law(sim)
    predicted = predicted_metrics = None
    if law is not None:
        _, predicted = predicted_step(loop_of(scratch, law), step_rad, seconds)
        predicted_metrics = metrics(t, predicted, step_rad)
    return StepResult(step_rad, t, measured, predicted, metrics(t, measured, step_rad), predicted_metrics)
