"""`hopper-sim stand`: the robot on a gimbal test stand (or in flight): kicks, reference steps, and the
attitude loop measured by injection against the model's prediction.

    hopper-sim stand --measure [--legs locked|free] [--chirp log|linear|stepped] [--f-min HZ]
        [--f-max HZ] [--amplitude A] [--length S] [--at input|reference] [--bode PATH.png]
    hopper-sim stand --measure --flight --flights 30 [--length 0.4]
    hopper-sim stand --step 2 --kick 0.5 [--kp --ki --kd | --controller SPEC] [--json PATH]
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from hopper.app.cli_common import (
    EXIT_OK,
    add_controller_flags,
    add_model_flag,
    fail,
    finite,
    gains_flags,
    gravity,
    rrd_file,
    with_controller_flags,
    writable_file,
)

from hopper.config import GRAVITY_PRESETS, Gains, InvalidConfig, SimConfig

KICK_WATCH_S = 1.0  # s of the response to a kick that is shown
# Flights a --flight measurement may average: a typo guard, as a sweep's hops are (spec.MAX_HOPS, 1000).
# About 0.1 s of one core a flight here (400 in 45 s, memory flat): ~2 min, ~3000 s simulated on the
# Moon. The default 30 already give a coherence of 0.985 at the crossover.
MAX_FLIGHTS = 1000
FLIGHTS = 30  # --flights' default
SETTLE_S = 0.5  # s, --settle's default
FIGURE_FORMATS = (".png", ".pdf")  # --bode's


def add_parser(commands: argparse._SubParsersAction, epilog: str) -> None:
    """Register `stand` on hopper-sim's subcommands."""
    p = commands.add_parser(
        "stand",
        help="the robot on a gimbal test stand: kicks, reference steps, the loop measured by injection",
        epilog=epilog,
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--legs", choices=("locked", "free"), default=None, help="on the stand: locked in the landing pose (default)"
    )
    p.add_argument("--flight", action="store_true", help="measure in flight (short chirps over many flights)")
    p.add_argument(
        "--flights",
        type=int,
        default=None,  # None: not given (refused without --flight, which alone flies them)
        help=f"flights a --flight measurement averages (default {FLIGHTS}; 1 to {MAX_FLIGHTS})",
    )
    p.add_argument("--gravity", type=gravity, default=GRAVITY_PRESETS["moon"], help="m/s^2 or a preset (default moon)")
    defaults = Gains()  # the flags' defaults are None, to tell a gain given from one left (gains_flags)
    p.add_argument("--kp", type=finite, help=f"the PID's, N m/rad (default {defaults.kp:g})")
    p.add_argument("--ki", type=finite, help=f"the PID's, N m/(rad s) (default {defaults.ki:g})")
    p.add_argument("--kd", type=finite, help=f"the PID's, N m s/rad (default {defaults.kd:g})")
    add_controller_flags(p)
    add_model_flag(p)
    p.add_argument("--sensing", choices=("ideal", "realistic"), default="ideal", help="default ideal")
    p.add_argument("--kick", type=finite, metavar="NMS", help="a pitch kick on the stand, N m s")
    p.add_argument("--step", type=finite, metavar="DEG", help="a step of the pitch reference on the stand, deg")
    p.add_argument("--measure", action="store_true", help="inject a chirp and compare the loop with the model's")
    p.add_argument("--chirp", choices=("log", "linear", "stepped"), default=None, help="default log (flight: linear)")
    p.add_argument("--f-min", type=finite, default=None, metavar="HZ", help="default 1 Hz (flight: 5 Hz)")
    p.add_argument("--f-max", type=finite, default=None, metavar="HZ", help="default 400 Hz (flight: 200 Hz)")
    p.add_argument(
        "--amplitude",
        type=finite,
        default=None,
        metavar="A",
        # hopper.analysis.bench's defaults (not imported here: scipy would slow every --help; a test
        # holds these numbers to them)
        help="N m at the input (default 2; flight 3), rad at the reference (default 0.0349, 2 deg)",
    )
    p.add_argument(
        "--length",
        type=finite,
        default=None,
        metavar="S",
        help="s (default 20; flight: what fits after the apex, ~0.4 s on the Moon)",
    )
    p.add_argument("--steps", type=int, default=24, help="stepped sines: how many frequencies (default 24)")
    p.add_argument(
        "--at",
        choices=("input", "reference"),
        default="input",
        help="where the chirp is injected: the wheel torque or the pitch reference (default input)",
    )
    p.add_argument(
        "--settle",
        type=finite,
        default=None,
        metavar="S",
        help=f"s on the stand before anything (default {SETTLE_S:g})",
    )
    p.add_argument("--bode", type=figure_file, metavar="PATH", help="write the Bode figure: PATH.png or PATH.pdf")
    p.add_argument(
        "--json", type=writable_file, metavar="PATH", help="write the measurements (hopper-sim report reads it)"
    )
    p.add_argument("--rrd", type=rrd_file, metavar="PATH", help="record the run, the injected signal too (.rrd)")


def figure_file(text: str) -> Path:
    """A .png or .pdf path that can be written (cli_common.writable_file). Its suffix says the format:
    matplotlib would add .png to a name without one and write elsewhere than the path printed."""
    path = writable_file(text)
    if path.suffix.lower() not in FIGURE_FORMATS:
        raise argparse.ArgumentTypeError(
            f"{text}: cannot tell the figure's format from '{path.suffix or 'no suffix'}'; "
            f"known: {', '.join(FIGURE_FORMATS)}"
        )
    return path


def _config(args: argparse.Namespace) -> SimConfig:
    try:
        config = SimConfig(
            terrain="flat" if not args.flight else "crater",
            gravity=args.gravity,
            gains=gains_flags(args),  # refused with another --controller, which flies no PID
            sensing=args.sensing,
            model=args.model,
        )
    except (InvalidConfig, ValueError) as exc:
        fail(str(exc))
    return with_controller_flags(config, args)


def _spec(args: argparse.Namespace, config: SimConfig):  # noqa: ANN202 (hopper.analysis.frequency.ChirpSpec)
    from hopper.analysis.bench import flight_window
    from hopper.analysis.frequency import ChirpSpec, InvalidChirp, NotMeasured

    flight = args.flight
    flight_length = 0.0
    if flight and args.length is None:
        try:
            flight_length = flight_window(config)  # what fits after the apex of this robot's flight
        except NotMeasured as exc:
            fail(str(exc))
    length = args.length if args.length is not None else flight_length if flight else 20.0
    try:
        return ChirpSpec(
            # In flight at least 2 cycles of f_min in the chirp (what a shorter flight allows).
            f_min=args.f_min
            if args.f_min is not None
            else max(5.0, math.ceil(20.0 / max(length, 1e-3)) / 10.0)
            if flight
            else 1.0,
            f_max=args.f_max if args.f_max is not None else 200.0 if flight else 400.0,
            amplitude=args.amplitude if args.amplitude is not None else default_amplitude(args.at, flight),
            length=length,
            kind=args.chirp or ("linear" if flight else "log"),
            at=args.at,
            steps=args.steps,
        )
    except InvalidChirp as exc:
        fail(str(exc))


def default_amplitude(at: str, flight: bool) -> float:
    """The chirp's amplitude without --amplitude: N m at the input (the stand's or the flight's), rad
    at the reference (hopper.analysis.bench's defaults)."""
    from hopper.analysis.bench import FLIGHT_AMPLITUDE, REFERENCE_AMPLITUDE, STAND_AMPLITUDE

    if at == "reference":
        return REFERENCE_AMPLITUDE
    return FLIGHT_AMPLITUDE if flight else STAND_AMPLITUDE


def command_stand(args: argparse.Namespace) -> int:
    if not (args.measure or args.step is not None or args.kick is not None):
        fail("stand: say what to do: --measure, --step DEG and/or --kick NMS")
    if args.flight and not args.measure:
        fail("--flight measures the loop in flight: add --measure (kicks and steps are on the stand)")
    if args.flight and (args.kick is not None or args.step is not None):  # there is no stand to act on
        fail(f"{'--kick' if args.kick is not None else '--step'} acts on the stand, --flight measures in flight: "
             "run them one at a time")  # fmt: skip
    if args.flight and args.at == "reference":
        fail("--flight measures the loop at the plant input: drop --at reference (a reference chirp is measured "
             "on the stand)")  # fmt: skip
    if args.bode is not None and not args.measure:
        fail("--bode draws the loop that --measure measures: add --measure")
    if args.flights is not None and not args.flight:
        fail(f"--flights {args.flights} is how many flights --flight averages: add --flight (on the stand one "
             "chirp is measured)")  # fmt: skip
    if args.flights is not None and not 1 <= args.flights <= MAX_FLIGHTS:
        fail(f"--flights must be in [1, {MAX_FLIGHTS}], got {args.flights}")
    for flag, value in (("--legs", args.legs), ("--settle", args.settle)):
        if args.flight and value is not None:  # in flight there is no stand: it would be ignored
            fail(f"{flag} sets the stand, and --flight measures in flight: drop it")
    args.legs = args.legs or "locked"
    args.settle = SETTLE_S if args.settle is None else args.settle
    if not 0.0 <= args.settle <= 60.0:
        fail(f"--settle must be in [0, 60] s, got {args.settle:g}")
    config = _config(args)
    spec = _spec(args, config) if args.measure else None
    from hopper.app.episode import version

    from hopper.analysis import bench
    from hopper.analysis.frequency import NotMeasured

    document: dict[str, Any] = {"kind": "frequency", "version": version(), "settings": _settings(args, config)}
    document["measurements"] = []
    recordings: list = []

    def attach(sim) -> None:  # noqa: ANN001 (hopper.sim.Simulation): record it if asked
        if args.rrd is not None:
            from hopper.app.recordings import open_recording

            try:
                recordings.append(open_recording(sim, args.rrd)[0])
            except (OSError, ValueError) as exc:
                fail(f"cannot record to {args.rrd}: {exc}")

    try:
        sim = None
        if not args.flight:
            sim = bench.stand(config, args.legs, 0.0)
            attach(sim)
            sim.settle(args.settle)
        if args.kick is not None:
            document["kick"] = _kick(sim, args.kick)
        if args.step is not None:
            if not abs(args.step) <= 30.0:
                fail(f"--step must be within +-30 deg, got {args.step:g}")
            result = bench.step_response(sim, math.radians(args.step))
            print("\n".join(result.lines()))
            document["step"] = result.to_json()
        if spec is not None:
            if args.flight:
                flights = FLIGHTS if args.flights is None else args.flights
                measurement = bench.measure_flight(config, spec, flights, attach)
            else:
                measurement = bench.measure_stand(sim, spec)
            print("\n".join(measurement.lines()))
            document["measurements"].append(measurement.to_json())
    except NotMeasured as exc:
        print(f"hopper-sim: not measured: {exc}")
        return 1
    finally:
        for telemetry in recordings:
            telemetry.close()
            print(f"wrote {args.rrd}")
    if args.json:
        args.json.write_text(json.dumps(document))
        print(f"wrote {args.json}")
    if args.bode and document["measurements"]:
        from hopper.report import frequency, style

        fig = frequency.bode(document["measurements"][0])
        fig.tight_layout()
        fig.savefig(args.bode, format=args.bode.suffix[1:].lower())
        style.close(fig)
        print(f"wrote {args.bode}")
    return EXIT_OK


def _kick(sim, magnitude: float) -> dict[str, float]:  # noqa: ANN001 (hopper.stand.StandSimulation)
    """A pitch kick on the stand (N m s): prints the pitch's peak and return, and gives them for the
    JSON (peak in deg, times in s from the kick), with the pitch after it, tick by tick (deg)."""
    try:
        sim.disturb("pitch_kick", magnitude)
    except ValueError as exc:
        fail(str(exc))
    start, peak, peak_t = sim.time, 0.0, 0.0
    before = sim.state().pitch  # the kick acts in the next step: the trace starts from here
    pitch, t = [], []
    for _ in range(round(KICK_WATCH_S / sim.model.opt.timestep)):
        sim.step()
        p = sim.state().pitch
        pitch.append(p)
        t.append(sim.time - start)
        if abs(p) > peak:
            peak, peak_t = abs(p), sim.time - start
    back = next((i for i in range(len(pitch) - 1, -1, -1) if abs(pitch[i]) > 0.1 * peak), 0) + 1
    back_s = back * sim.model.opt.timestep
    print(
        f"kick {magnitude:g} N m s on the stand: peak pitch {math.degrees(peak):.3f} deg at {peak_t * 1e3:.0f} ms, "
        f"back within 10 % of it from {back_s * 1e3:.0f} ms"
    )
    return {
        "magnitude_nms": magnitude,
        "peak_pitch_deg": math.degrees(peak),
        "peak_s": peak_t,
        "back_within_10pct_s": back_s,
        "watched_s": KICK_WATCH_S,
        "t": [0.0, *t],
        "pitch_deg": [math.degrees(p) for p in (before, *pitch)],
    }


def _settings(args: argparse.Namespace, config: SimConfig) -> dict[str, Any]:
    return {
        "legs": "flight" if args.flight else args.legs,
        "gravity": config.gravity,
        "gains": {"kp": config.gains.kp, "ki": config.gains.ki, "kd": config.gains.kd},
        "controller": config.controller,
        "controller_params": dict(config.controller_params),
        "sensing": config.sensing,
    }
