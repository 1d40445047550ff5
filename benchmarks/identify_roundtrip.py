"""Issue 21's round trip with known truth: log a mismatched robot, identify it from the default model.

Run: python -m benchmarks.identify_roundtrip [--cases issue,second] [--draws 1-3] [--formats csv,mcap] [--hops 7]
         [--seed 21]

Each case's robot (a hopper.mismatch and a gyro bias, realistic sensing: the IMU's noise and bias
random walk, the motor delay) hops 2 x --hops hops on the flat Moon; the log is written as CSV and
as MCAP and read back (each must equal the captured one sample for sample, so the fit of one is the
fit of the other; --refit-each fits every format anyway). The fit (hopper.logs.sysid, its default
parameters) runs on hops 1..N from the packaged model; hops N+1..2N validate it. Printed: each
parameter's truth, estimate +- sigma and error (pass: 5 %, friction and gyro bias 10 %), and the
replay errors before and after (pitch RMS: re-anchored on the log's state every 0.3 s; whole hops
from their liftoffs with the legs held to the log's angles; whole hops, phases and flights alone on
the log's torques), their ratio (pass: >= 5x over the fit's hops both re-anchored and whole with
the legs held: a whole hop on the torques alone drifts off with friction 0.1 % off, README "From a
log to the model").
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from hopper.config import SensingParams, SimConfig  # noqa: E402
from hopper.logs import replay, sysid  # noqa: E402
from hopper.logs.capture import capture  # noqa: E402
from hopper.logs.io import read_log, write_log  # noqa: E402
from hopper.mismatch import Nominal  # noqa: E402

CASES = {  # name -> (mismatch, gyro bias deg/s)
    # The issue's: torso mass +20 %, wheel inertia -15 %, k_t -10 %, friction 0.6 (0.8 x 0.75), gyro 0.5 deg/s.
    "issue": ((("torso_mass", 1.2), ("wheel_inertia", 0.85), ("motor_torque", 0.9), ("friction", 0.75)), 0.5),
    # Another: the CoM 15 mm forward, the torso's inertia x0.85 and its mass x0.9 apart, k_t +8 %, gyro -0.3 deg/s.
    "second": ((("com_x", 0.015), ("inertia_torso", 0.85), ("mass_torso", 0.9), ("motor_torque", 1.08)), -0.3),
    # A third, the other way: torso mass -10 %, wheel inertia +12 %, k_t +5 %, friction 0.88, CoM 8 mm back, -0.7 deg/s.
    "third": (
        (("torso_mass", 0.9), ("wheel_inertia", 1.12), ("motor_torque", 1.05), ("friction", 1.1), ("com_x", -0.008)),
        -0.7,
    ),
}
# --draws: mismatches none of the above, drawn per case from these ranges (factors; com_x in m,
# the gyro bias in deg/s), so that the fit is tried on robots it was not developed on.
DRAW_RANGES = {
    "torso_mass": (0.85, 1.25),
    "wheel_inertia": (0.8, 1.2),
    "motor_torque": (0.85, 1.15),
    "friction": (0.7, 1.15),
    "com_x": (-0.015, 0.015),
}
DRAW_BIAS = (-0.8, 0.8)


def drawn(k: int) -> tuple[tuple, float]:
    """Draw k's case (mismatch, gyro bias deg/s): every DRAW_RANGES parameter uniform in its range."""
    rng = np.random.default_rng(k)
    mismatch = tuple((name, round(float(rng.uniform(lo, hi)), 4)) for name, (lo, hi) in DRAW_RANGES.items())
    return mismatch, round(float(rng.uniform(*DRAW_BIAS)), 3)


REPLAYS = (f"re-anchored every {replay.REANCHOR_S:g} s", "whole hops, legs held to the log",
           "whole hops, each from its liftoff", "phases, each from its start", "flights alone")  # fmt: skip
JUDGED = REPLAYS[:2]  # the pass's measures
TOLERANCE = {"friction": 0.10, "gyro_bias": 0.10}  # the rest: 5 %
DEFAULT_TOLERANCE = 0.05
OFFSET_TOLERANCE = 0.002  # m, for a CoM offset (a share of 0 is no measure)


def truth_of(mismatch: tuple, bias: float) -> dict[str, float]:
    model, _ = replay.world_model(replay.World())
    base = Nominal.of(model)
    base.apply(model, mismatch)
    out = sysid.nominal(model)
    motor = model.actuator("wheel").id
    k = float(model.actuator_gainprm[motor, 0] / base.actuator_gainprm[motor, 0])
    out["motor_torque"] = k
    out["motor_damping"] = float(model.actuator_biasprm[motor, 2] / base.actuator_biasprm[motor, 2]) / k**2
    out["gyro_bias"] = bias
    return out


def pitch_rms(parts: list) -> float:  # noqa: ANN001 (replay's (Trajectory, Errors) pairs)
    return math.degrees(replay.Errors.concat([e for _, e in parts]).rms("pitch"))


def replay_errors(model, log, first: int, count: int) -> tuple[float, ...]:  # noqa: ANN001
    """Pitch RMS, deg, over the hops (REPLAYS): re-anchored on the log's state every REANCHOR_S and
    replayed whole with the legs held to the log's angles (the measures the pass is judged on), and on
    the log's torques alone: whole (each from its liftoff), by phases (each flight and stance from its
    start), and their flights alone."""
    hops = replay.hops(log)[first : first + count]
    a, b = hops[0][0], hops[-1][1]
    inside = [(s, min(e, b)) for s, e in replay.phases(log) if a <= s < b]
    flights = [f for f in replay.flights(log) if a <= f[0] < b]
    windows = [w for hop in hops for w in replay.windows(log, hop, replay.REANCHOR_S)]
    held = pitch_rms(replay.replay_spans(model, log, hops, servo=True))
    rest = (pitch_rms(replay.replay_spans(model, log, spans)) for spans in (hops, inside, flights))
    return (pitch_rms(replay.replay_spans(model, log, windows)), held, *rest)


def run_case(name: str, formats: list[str], hops: int, refit_each: bool, folder: Path, seed: int = 21) -> bool:
    mismatch, bias = CASES[name] if name in CASES else drawn(int(name.removeprefix("draw")))
    config = SimConfig(
        terrain="flat",
        sensing="realistic",
        seed=seed,  # the IMU's noise and bias walk
        mismatch=mismatch,
        sensor=SensingParams(gyro_turn_on_bias=0.0, gyro_bias_fixed=bias),
    )
    got = capture(config, 2 * hops)
    if got.hops < 2 * hops:
        print(f"{name}: the robot completed {got.hops} of {2 * hops} hops; nothing to fit")
        return False
    truth = truth_of(mismatch, bias)
    ok = True
    fitted = None
    for fmt in formats:
        path = write_log(got.log, folder / f"{name}.{fmt}")
        log = read_log(path)
        same = all(np.array_equal(log.signals[k], v) for k, v in got.log.signals.items())
        same &= np.array_equal(log.time, got.log.time)
        size = path.stat().st_size / 1e6
        print(f"\n== {name}: {dict(mismatch)}, gyro bias {bias:+g} deg/s; {path.name} ({size:.1f} MB)"
              f" {'equals' if same else 'DIFFERS FROM'} the captured log")  # fmt: skip
        if fitted is not None and same and not refit_each:
            print("   the same samples as the log fitted above: the same fit")
            continue
        model, _ = replay.world_model(replay.World())
        nominal, _ = replay.world_model(replay.World())
        span = sysid.hop_span(log, 0, hops)
        started = time.perf_counter()
        fit = sysid.identify(model, log, span)
        seconds = time.perf_counter() - started
        fitted = fit
        print(f"   {'parameter':16s} {'truth':>10s} {'estimate':>10s} {'sigma':>9s} {'error':>8s}  pass")
        for e in fit.estimates:
            t = truth[e.name]
            if t == 0.0:
                err, passed = f"{e.value - t:+.2g}", abs(e.value - t) <= OFFSET_TOLERANCE
            else:
                share = (e.value - t) / abs(t)
                err, passed = f"{100 * share:+.2f}%", abs(share) <= TOLERANCE.get(e.name, DEFAULT_TOLERANCE)
            ok &= passed
            print(f"   {e.name:16s} {t:10.5g} {e.value:10.5g} {e.sigma:9.2g} {err:>8s}  {'yes' if passed else 'NO'}")
        for pname, (low, high) in fit.profile.items():
            print(
                f"   {pname}: profile range (cost within {sysid.PROFILE_SIGMAS:g} sigma of its least) "
                f"{low:.4g}..{high:.4g}"
            )
        for a, b, c in fit.not_separable():
            print(f"   not separable: {a}, {b} ({c:+.5f})")
        for label, first in (("fit", 0), ("validation", hops)):
            before = replay_errors(nominal, log, first, hops)
            after = replay_errors(model, log, first, hops)
            print(f"   replay pitch RMS, {label} hops {first + 1}..{first + hops}, before -> after:")
            for what, e0, e1 in zip(REPLAYS, before, after, strict=True):
                ratio = e0 / e1 if e1 > 0 else math.inf
                passed = ratio >= 5.0
                if label == "fit" and what in JUDGED:
                    ok &= passed
                print(f"     {what:34s} {e0:9.4g} -> {e1:9.3g} deg  {ratio:9.3g}x  {'>= 5x' if passed else 'BELOW 5x'}")
        print(f"   fit: {fit.evaluations} simulations of {fit.windows} windows, {seconds:.0f} s; {fit.message}")
    return ok


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cases", default=",".join(CASES), help=f"comma-separated, of {', '.join(CASES)} ('' for none)")
    p.add_argument("--draws", default="", help="drawn mismatches too, e.g. 1-3 (DRAW_RANGES)")
    p.add_argument("--formats", default="csv,mcap", help="comma-separated, of csv, mcap, npz")
    p.add_argument("--hops", type=int, default=7, help="hops fitted (as many again validate)")
    p.add_argument("--refit-each", action="store_true", help="fit every format's log even when they are equal")
    p.add_argument("--seed", type=int, default=21, help="the capture's seed: its IMU noise and bias walk (default 21)")
    args = p.parse_args()
    names = [n for n in args.cases.split(",") if n]
    for n in names:
        if n not in CASES:
            p.error(f"unknown case {n!r}; the cases: {', '.join(CASES)}")
    if args.draws:
        first, _, last = args.draws.partition("-")
        names += [f"draw{k}" for k in range(int(first), int(last or first) + 1)]
    results = {}
    with tempfile.TemporaryDirectory() as folder:
        for name in names:
            results[name] = run_case(name, args.formats.split(","), args.hops, args.refit_each, Path(folder), args.seed)
    print("\n" + ", ".join(f"{n}: {'pass' if r else 'FAIL'}" for n, r in results.items()))
    return 0 if all(results.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
