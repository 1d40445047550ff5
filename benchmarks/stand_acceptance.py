"""Issue 20's acceptance for the stand and the injection: measured against predicted, per gain set.

Run: python -m benchmarks.stand_acceptance [--flights 30] [--gravity 1.625] [--sensing ideal]
     [--amplitude 2] [--flight-amplitude 3] [--gains KP/KI/KD ...] [--seed 0]

For PID 450/50/30, soft 200/20/12, stiff 900/100/45, 300/30/20 and the LQR: the loop's crossover
(Hz) and phase margin (deg), measured by a chirp at the plant input and predicted by the model, on
the stand with the legs locked and free (one 20 s log chirp 1-400 Hz, 2 N m; pass: within 10 %
and 5 deg, coherence >= 0.9 at the crossover) and in flight (a 0.4 s linear chirp 5-200 Hz, 3 N m,
in each of --flights flights; shorter where flights are, f_min then 2 cycles of it; pass: within
20 % and 10 deg, or "not measurable" when the crossover is below what the records resolve). Then
a 2 deg step of the reference on the stand with the legs locked: rise, overshoot and settling,
measured and predicted.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from hopper.analysis.bench import (  # noqa: E402
    FLIGHT_AMPLITUDE,
    STAND_AMPLITUDE,
    flight_window,
    measure_flight,
    measure_stand,
    stand,
    step_response,
)
from hopper.analysis.frequency import ChirpSpec, InvalidChirp, NotMeasured  # noqa: E402
from hopper.config import Gains, SimConfig  # noqa: E402
from hopper.controllers import with_controller  # noqa: E402

SETS = {
    "PID 450/50/30": Gains(kp=450.0, ki=50.0, kd=30.0),
    "soft 200/20/12": Gains(kp=200.0, ki=20.0, kd=12.0),
    "stiff 900/100/45": Gains(kp=900.0, ki=100.0, kd=45.0),
    "PID 300/30/20": Gains(kp=300.0, ki=30.0, kd=20.0),
    "LQR": None,
}
STAND_CHIRP = ChirpSpec(f_min=1.0, f_max=400.0, amplitude=STAND_AMPLITUDE, length=20.0)
FLIGHT_CHIRP = ChirpSpec(f_min=5.0, f_max=200.0, amplitude=FLIGHT_AMPLITUDE, length=0.4, kind="linear")
TOLERANCE = {"stand": (0.10, 5.0, 0.9), "flight": (0.20, 10.0, 0.0)}  # crossover share, PM deg, coherence


def config_of(gains: Gains | None, terrain: str, gravity: float, sensing: str, seed: int = 0) -> SimConfig:
    base = SimConfig(terrain=terrain, gravity=gravity, sensing=sensing, seed=seed)  # type: ignore[arg-type]
    return with_controller(base, "lqr") if gains is None else SimConfig(**{**base.__dict__, "gains": gains})


def row(name: str, where: str, result) -> str:  # noqa: ANN001 (hopper.analysis.bench.Measurement)
    m, p = result.measured, result.predicted
    share, pm_tol, coh_tol = TOLERANCE["flight" if where == "flight" else "stand"]
    pc, pp = p.margins.crossover_hz, p.margins.phase_margin_deg
    if m is None:
        verdict = "not measurable" if "cannot resolve" in result.note or "stays below" in result.note else "FAIL"
        return f"{name:18s} {where:13s} {'-':>8s} {pc:8.2f} {'-':>7s} {pp:7.1f} {'-':>6s}  {verdict}: {result.note}"
    ok = abs(m.crossover_hz / pc - 1.0) <= share and abs(m.phase_margin_deg - pp) <= pm_tol and m.coherence >= coh_tol
    saturated = f" (the motor saturated on {result.saturated_ticks} ticks)" if result.saturated_ticks else ""
    return (
        f"{name:18s} {where:13s} {m.crossover_hz:8.2f} {pc:8.2f} {m.phase_margin_deg:7.1f} {pp:7.1f} "
        f"{m.coherence:6.3f}  {'pass' if ok else 'FAIL'}{saturated}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--flights", type=int, default=30)
    parser.add_argument("--gravity", type=float, default=1.625)
    parser.add_argument("--sensing", choices=("ideal", "realistic"), default="ideal")
    parser.add_argument("--amplitude", type=float, default=STAND_CHIRP.amplitude, help="N m, the stand's chirp")
    parser.add_argument("--flight-amplitude", type=float, default=FLIGHT_CHIRP.amplitude, help="N m, in flight")
    parser.add_argument("--gains", action="append", metavar="KP/KI/KD", help="other PID sets instead of the five")
    parser.add_argument("--seed", type=int, default=0, help="the IMU's noise and biases (realistic sensing)")
    args = parser.parse_args()
    sets = SETS
    if args.gains:
        try:
            sets = {
                f"PID {g}": Gains(**dict(zip(("kp", "ki", "kd"), map(float, g.split("/")), strict=True)))
                for g in args.gains
            }
        except (TypeError, ValueError) as exc:
            parser.error(f"--gains takes KP/KI/KD, e.g. 600/60/35: {exc}")
    stand_chirp = dataclasses.replace(STAND_CHIRP, amplitude=args.amplitude)
    flight_chirp = dataclasses.replace(FLIGHT_CHIRP, amplitude=args.flight_amplitude)
    print(f"{'set':18s} {'where':13s} {'fc meas':>8s} {'fc pred':>8s} {'PM meas':>7s} {'PM pred':>7s} {'coh':>6s}")
    steps = []
    for name, gains in sets.items():
        for legs in ("locked", "free"):
            sim = stand(config_of(gains, "flat", args.gravity, args.sensing, args.seed), legs)
            print(row(name, f"stand {legs}", measure_stand(sim, stand_chirp)), flush=True)
            if legs == "locked":
                fresh = stand(config_of(gains, "flat", args.gravity, args.sensing, args.seed), legs)
                steps.append((name, step_response(fresh, math.radians(2.0))))
        config = config_of(gains, "crater", args.gravity, args.sensing, args.seed)
        length = min(flight_chirp.length, flight_window(config))
        chirp = dataclasses.replace(
            flight_chirp, length=length, f_min=max(flight_chirp.f_min, math.ceil(20.0 / length) / 10.0)
        )
        try:
            print(row(name, "flight", measure_flight(config, chirp, args.flights)), flush=True)
        except (NotMeasured, InvalidChirp) as exc:
            print(f"{name:18s} {'flight':13s} not measurable: {exc}", flush=True)
    print("\nstep of the reference, 2 deg, stand with the legs locked: measured / predicted")
    print(f"{'set':18s} {'rise ms':>15s} {'overshoot %':>15s} {'settling ms':>15s}")
    for name, s in steps:
        m, p = s.measured_metrics, s.predicted_metrics
        print(
            f"{name:18s} {m.rise_s * 1e3:7.2f}/{p.rise_s * 1e3:7.2f} {m.overshoot_pct:7.2f}/{p.overshoot_pct:7.2f} "
            f"{m.settling_s * 1e3:7.1f}/{p.settling_s * 1e3:7.1f}"
        )


if __name__ == "__main__":
    main()
