"""`hopper-sim capture`, `replay` and `identify`: from a log to the model (issue 21).

capture logs a simulated robot of known truth (any mismatch, realistic sensing); replay flies a
log's commands open loop from its state and reports the errors; identify fits the model to a log
and writes the identified robot as MJCF.
"""

from __future__ import annotations

import argparse
import copy
import math
import sys
from pathlib import Path

import mujoco
import numpy as np
from hopper.app.cli_common import (
    CLOSED_STDOUT_STATUS,
    EXIT_FELL,
    EXIT_OK,
    add_model_flag,
    fail,
    finite,
    gravity,
    made_out,
    mjcf_out,
    model_file,
    same_file,
    seed,
    writable_file,
)

from hopper.config import GRAVITY_PRESETS, MISMATCH_FACTORS, MISMATCH_OFFSETS, SensingParams, SimConfig, check_mismatch
from hopper.errors import HopperError, ModelError
from hopper.logs import gaps
from hopper.logs.io import READERS, WRITERS, read_log, write_log, writer
from hopper.logs.replay import HELD, REANCHOR_S, Errors, hops, replay_hops, simulate, world_model
from hopper.logs.schema import Log
from hopper.logs.sysid import DEFAULT_FIT, PARAMS, PROFILE_SIGMAS, STAGES
from hopper.logs.world import DEFAULT_DELAY_TICKS, World, resolve
from hopper.mismatch import Nominal
from hopper.model import MODEL_XML

COMMANDS = ("capture", "replay", "identify")
INTERRUPTED = "130 interrupted (Ctrl-C or SIGTERM)"
CAPTURE_EPILOG = (
    "exit status: 0 the log written, 1 the robot fell or the run reached its time limit before the hops asked "
    f"(the log holds the hops it did; it says which), 2 bad arguments, {INTERRUPTED}, {CLOSED_STDOUT_STATUS}."
)
REPLAY_EPILOG = (
    "exit status: 0 replayed (the errors printed, the figure written with --out), 2 bad arguments or a log it "
    f"cannot read or replay as asked (one line, before any replay), {INTERRUPTED}, {CLOSED_STDOUT_STATUS}."
)
IDENTIFY_EPILOG = (
    "exit status: 0 fitted and the MJCF written, 2 bad arguments or a log it cannot read (one line, before the "
    f"fit), {INTERRUPTED}: no MJCF is written, {CLOSED_STDOUT_STATUS}."
)
LOG_KINDS = ", ".join(s if s != ".rrd" else "our own .rrd" for s in READERS)  # as `log check` says


def mismatch_pair(text: str) -> tuple[str, float]:
    """NAME=VALUE, a hopper.mismatch factor or offset (checked by SimConfig)."""
    name, sep, value = text.partition("=")
    if not sep:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    try:
        return check_mismatch(((name.strip(), finite(value)),))[0]
    except (ValueError, argparse.ArgumentTypeError) as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_world_flags(p: argparse.ArgumentParser, help_suffix: str, from_log: bool = False) -> None:
    """--terrain, --seed, --gravity; `from_log`: each defaults to the log's world (None here)."""
    default = "the log's, else " if from_log else ""
    p.add_argument(
        "--terrain", choices=("flat", "crater"), default=None if from_log else "flat",
        help=f"(default {default}flat) {help_suffix}",
    )  # fmt: skip
    p.add_argument(
        "--seed", type=seed, default=None if from_log else 0,
        help=f"terrain seed (default {default}0)" + ("" if from_log else "; also the IMU's"),
    )  # fmt: skip
    p.add_argument(
        "--gravity", type=gravity, default=None if from_log else GRAVITY_PRESETS["moon"],
        help=f"m/s^2 or moon|mars|ceres|earth (default {default}moon)",
    )  # fmt: skip


def add_commands(commands: argparse._SubParsersAction) -> None:  # noqa: SLF001 (argparse's own type)
    cap = commands.add_parser(
        "capture", help="log a simulated robot of known truth, for replay and identify", epilog=CAPTURE_EPILOG
    )
    cap.add_argument("out", type=writable_file, metavar="OUT", help=f"the log to write: {', '.join(WRITERS)}")
    cap.add_argument("--hops", type=int, default=14, help="hops to log (default 14)")
    cap.add_argument(
        "--mismatch", type=mismatch_pair, action="append", default=[], metavar="NAME=VALUE",
        help=f"the robot differs from the model: factors {', '.join(MISMATCH_FACTORS)}; offsets (m) "
        f"{', '.join(MISMATCH_OFFSETS)}",
    )  # fmt: skip
    cap.add_argument("--gyro-bias", type=finite, metavar="DEG_S", help="the IMU gyro's bias (default: a random draw)")
    cap.add_argument("--sensing", choices=("ideal", "realistic"), default="realistic", help="(default realistic)")
    add_world_flags(cap, "the ground it hops on")
    add_model_flag(cap)

    rep = commands.add_parser(
        "replay", help="fly a log's commands open loop from its state: errors and a figure", epilog=REPLAY_EPILOG
    )
    rep.add_argument("log", type=Path, help=f"the log: {LOG_KINDS}")
    add_model_flags(rep)
    rep.add_argument("--from", dest="start", type=finite, metavar="T", help="one replay from the log's state at T s")
    rep.add_argument("--to", dest="stop", type=finite, metavar="T", help="...until T s (default: the log's end)")
    rep.add_argument("--hops", type=int, metavar="N", help="replay hops 1..N, each from its liftoff (default all)")
    rep.add_argument(
        "--every", type=finite, metavar="S",
        help=f"re-anchor each hop on the log's state every S s (multiple shooting; {REANCHOR_S:g} measures a "
        "model where a whole open-loop stance drifts off; default: each hop whole)",
    )  # fmt: skip
    rep.add_argument(
        "--legs", choices=("torque", "servo"), default="torque",
        help="the legs fly the log's torques alone (default), or with a servo to the log's angles too: a whole "
        "hop then measures the torso and the wheel, not the open-loop stance's chaos",
    )  # fmt: skip
    rep.add_argument(
        "--out", type=Path, metavar="DIR",
        help="write replay.png and .pdf (errors over time) in this folder (made if missing, in one that exists)",
    )  # fmt: skip

    ide = commands.add_parser(
        "identify", help="fit the model to a log; print estimates, write the MJCF", epilog=IDENTIFY_EPILOG
    )
    ide.add_argument("log", type=Path, help=f"the log: {LOG_KINDS}")
    add_model_flags(ide)
    ide.add_argument("--out", type=mjcf_out, required=True, metavar="PATH.xml", help="the identified MJCF")
    ide.add_argument("--hops", type=int, default=7, help="fit on hops 1..N (default 7)")
    left_out = [name for name in PARAMS if name not in DEFAULT_FIT]
    ide.add_argument(
        "--params", metavar="A,B,...",
        help=f"the parameters to fit (default these {len(DEFAULT_FIT)}: {', '.join(DEFAULT_FIT)}; not "
        f"{' or '.join(left_out)}, which the wheel's response cannot tell apart from motor_torque: name them to "
        "fit them too)",
    )  # fmt: skip
    ide.add_argument(
        "--windows", type=windows, default=STAGES, metavar="S,S,...",
        help=f"the fit's stages: replay windows, s (default {','.join(f'{w:g}' for w in STAGES)})",
    )  # fmt: skip
    ide.add_argument("--max-evaluations", type=int, default=60, help="the optimiser's budget (default 60)")
    ide.add_argument(
        "--truth", type=truth_pair, action="append", default=[], metavar="NAME=VALUE",
        help="the known truth, for the table: a mismatch (as capture's --mismatch) or gyro_bias=DEG_S",
    )  # fmt: skip


def add_model_flags(p: argparse.ArgumentParser) -> None:
    add_world_flags(p, "the ground the log was recorded on", from_log=True)
    p.add_argument(
        "--delay-ticks", type=int, metavar="N",
        help=f"ticks (1 ms) from a logged wheel command to the motor (default the log's, else {DEFAULT_DELAY_TICKS})",
    )  # fmt: skip
    add_model_flag(p)
    p.add_argument(
        "--drive", type=drive_model, metavar="PATH.xml|packaged",
        help="the robot whose wheel motor the log's torque commands were made for: the drive inverts it to a "
        "voltage, and the model replayed turns that into torque with its own motor (default the log's robot if the "
        "log says, as a capture's does, else the packaged one)",
    )  # fmt: skip


def drive_model(text: str) -> str:
    """--drive: an MJCF of the robot (checked as --model is) or the word packaged."""
    return text if text == "packaged" else model_file(text)


def windows(text: str) -> tuple[float, ...]:
    """Comma-separated window lengths, s, each positive."""
    try:
        values = tuple(finite(w) for w in text.split(","))
    except (ValueError, argparse.ArgumentTypeError):
        raise argparse.ArgumentTypeError(f"expected seconds separated by commas, got {text!r}") from None
    if not values or min(values) <= 0.0:
        raise argparse.ArgumentTypeError(f"window lengths must be positive, got {text!r}")
    return values


def truth_pair(text: str) -> tuple[str, float]:
    if text.partition("=")[0].strip() == "gyro_bias":
        return "gyro_bias", finite(text.partition("=")[2])
    return mismatch_pair(text)


def replay_world(args: argparse.Namespace, log: Log) -> World:
    """The world to fly the log in (the flags, else the log's: hopper.logs.world.resolve); says which."""
    try:
        world, origin = resolve(
            log.world, args.terrain, args.seed, args.gravity, args.model, args.delay_ticks, args.drive
        )  # fmt: skip
    except ModelError as exc:  # the log's robot, whose motor the drive inverts, is not there
        fail(f"{exc}; say which motor with --drive PATH.xml (or packaged)")
    except ValueError as exc:  # a delay the kernel's line cannot hold
        fail(f"--delay-ticks: {exc}")
    print(f"world: {world.describe()} ({origin})")
    return world


def run(args: argparse.Namespace) -> int:
    try:
        if args.command == "capture":
            return command_capture(args)
        if args.command == "replay":
            return command_replay(args)
        return command_identify(args)
    except HopperError as exc:
        fail(str(exc))


def command_capture(args: argparse.Namespace) -> int:
    from hopper.logs.capture import capture

    if args.hops < 1:
        fail(f"--hops must be at least 1, got {args.hops}")
    writer(args.out)  # its suffix, before capturing (LogError: one line, exit 2)
    sensor = SensingParams()
    if args.gyro_bias is not None:
        sensor = SensingParams(gyro_turn_on_bias=0.0, gyro_bias_fixed=args.gyro_bias)
    config = SimConfig(
        terrain=args.terrain, seed=args.seed, gravity=args.gravity, sensing=args.sensing, sensor=sensor,
        mismatch=tuple(args.mismatch), model=args.model,
    )  # fmt: skip
    got = capture(config, args.hops, source=str(args.out))
    write_log(got.log, args.out)
    print(f"wrote {args.out}: {len(got.log.time)} samples, {got.log.time[-1]:.3f} s, {got.hops} hop(s)")
    if got.hops < args.hops:
        why = "the robot fell" if got.fell else "the run reached its time limit"
        print(f"hopper-sim: capture stopped short: {why} after {got.hops} of {args.hops} hops (the log holds them)")
        return EXIT_FELL
    return EXIT_OK


def error_line(label: str, e: Errors) -> str:
    timing = e.timing()
    return (
        f"{label}: pitch RMS {math.degrees(e.rms('pitch')):.3f} deg, wheel speed RMS {e.rms('wheel_speed'):.3f} rad/s, "
        f"{timing}"
    )


def replay_flags(args: argparse.Namespace) -> None:
    """Refuse flags that the replay asked would ignore (--from T replays one span, to --to; --hops
    and --every replay hops from their liftoffs) or cannot take, before the log is read."""
    if args.start is None and args.stop is not None:
        fail(f"--to {args.stop:g} needs --from: --to ends the one replay --from starts")
    if args.start is not None:
        for flag, value in (("--hops", args.hops), ("--every", args.every)):
            if value is not None:
                fail(f"{flag} replays hops from their liftoffs; --from {args.start:g} replays one span: give one")
    if args.hops is not None and args.hops < 1:
        fail(f"--hops must be at least 1, got {args.hops}")
    if args.every is not None and args.every <= 0.0:
        fail(f"--every must be a positive number of seconds, got {args.every:g}")


def command_replay(args: argparse.Namespace) -> int:
    replay_flags(args)
    # made and written to now, before the replay, in a folder that exists (as identify's and export's
    # files must be); unmade if the log's checks refuse
    with made_out(args.out):
        return _replay(args)


def _replay(args: argparse.Namespace) -> int:
    log = read_log(args.log)
    world = replay_world(args, log)
    model, window = world_model(world)
    servo = args.legs == "servo"
    if args.start is not None:
        t = log.time
        if not t[0] <= args.start < t[-1]:
            fail(f"--from {args.start:g} s is outside the log's {t[0]:g}..{t[-1]:g} s")
        half = 0.5 * log.period  # the sample nearest to the time asked (a CSV's times are rounded)
        a = int(np.searchsorted(t, args.start - half))
        b = len(t) if args.stop is None else int(np.searchsorted(t, args.stop - half))
        if b <= a + 1:
            fail(f"--to {args.stop:g} s leaves nothing to replay after --from {args.start:g} s")
        from hopper.logs.replay import errors

        said(gaps.note(log, f"the replay from {t[a]:.3f} s", (a, b), whole=False))
        parts = []
        for x, y in gaps.pieces(log, (a, b)):  # one replay, or one each side of a gap
            traj = simulate(
                model, log, x, y, delay_ticks=world.command_delay, window=window, servo=servo, drive=world.drive
            )  # fmt: skip
            parts.append((f"from {t[x]:.3f} s" + (f", {HELD}" if servo else ""), errors(log, traj)))
    else:
        found = len(hops(log))
        if args.hops is not None and args.hops > found:
            fail(f"--hops {args.hops}: the log has {found} hop(s)")
        anchored = "" if args.every is None else f", re-anchored every {args.every:g} s"
        anchored += f", {HELD}" if servo else ""
        parts = []
        for i, (a, b) in enumerate(hops(log)[: args.hops]):
            # A whole hop across a gap is left out; re-anchored, it starts again at the gap's far side.
            if said(gaps.note(log, f"hop {i + 1}", (a, b), whole=args.every is None)) and args.every is None:
                continue
            done = replay_hops(
                model, log, 1, first=i, delay_ticks=world.command_delay, window=window, every=args.every, servo=servo,
                drive=world.drive,
            )  # fmt: skip
            parts.append((f"hop {i + 1} from {log.time[a]:.3f} s{anchored}", Errors.concat([e for _, e in done])))
        if not parts:
            fail("each hop asked holds a gap, and a whole hop is not scored across one: re-anchor with --every")
    for label, e in parts:
        print(error_line(label, e))
    total = Errors.concat([e for _, e in parts])
    print(error_line(f"all ({len(parts)} replay(s), {total.time.size} samples)", total))
    if args.out is not None:
        from hopper.app.replay_figure import error_figure

        from hopper.report.style import save

        paths = save(error_figure(parts, args.log.name), args.out, "replay")
        print(f"wrote {', '.join(str(p) for p in paths)}")
    return EXIT_OK


def said(note: str | None, command: str = "replay") -> bool:
    """Print `note` (a gap's, hopper.logs.gaps.note) on stderr if there is one; whether there was."""
    if note is not None:
        print(f"{command}: {note}", file=sys.stderr)
    return note is not None


def truth_values(model: mujoco.MjModel, truth: list[tuple[str, float]]) -> dict[str, float]:
    """Every parameter's true value when the log's robot is `model` with the mismatch `truth` (and
    its gyro_bias, deg/s); {} when no truth is given."""
    if not truth:
        return {}
    from hopper.logs.sysid import nominal

    robot = copy.copy(model)
    base = Nominal.of(robot)
    base.apply(robot, tuple((n, v) for n, v in truth if n != "gyro_bias"))
    out = nominal(robot)
    motor = robot.actuator("wheel").id
    k = float(robot.actuator_gainprm[motor, 0] / base.actuator_gainprm[motor, 0])
    out["motor_torque"] = k
    out["motor_damping"] = float(robot.actuator_biasprm[motor, 2] / base.actuator_biasprm[motor, 2]) / k**2
    out["gyro_bias"] = dict(truth).get("gyro_bias", 0.0)
    return out


def command_identify(args: argparse.Namespace) -> int:
    from hopper.logs import sysid

    names = sysid.DEFAULT_FIT if args.params is None else tuple(p.strip() for p in args.params.split(",") if p.strip())
    unknown = [n for n in names if n not in sysid.PARAMS] or ([] if names else ["(none)"])
    if unknown:
        fail(f"--params: unknown parameter(s) {', '.join(unknown)}; choose from {', '.join(sysid.PARAMS)}")
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        fail(f"--params: {', '.join(twice)} given more than once")
    if args.hops < 1:
        fail(f"--hops must be at least 1, got {args.hops}")
    if args.max_evaluations < 1:
        fail(f"--max-evaluations must be at least 1, got {args.max_evaluations}")
    identify_out(args)
    log = read_log(args.log)
    world = replay_world(args, log)
    (model, _), (fresh, _) = world_model(world), world_model(world)  # the fit edits `model`
    span = sysid.hop_span(log, 0, args.hops)
    for i, hop in enumerate(hops(log)[: args.hops]):  # the fit's windows are cut at a gap (replay.windows)
        note = gaps.note(log, f"hop {i + 1}", hop, whole=False)
        said(note and f"{note} (the fit's windows too); the whole-hop replays leave it out", "identify")
    measures = (
        (f"re-anchored every {REANCHOR_S:g} s", REANCHOR_S, False),
        (f"whole, each from its liftoff, {HELD}", None, True),
        ("whole, each from its liftoff", None, False),
    )
    if all(gaps.crossed(log, hop) for hop in hops(log)[: args.hops]):  # no whole hop to score
        measures = measures[:1]
    drive, delay = world.drive, world.command_delay
    before = [sysid.replay_error(fresh, log, 0, args.hops, delay, e, s, drive) for _, e, s in measures]
    fit = sysid.identify(
        model, log, span, names, stages=args.windows, delay_ticks=delay, max_evaluations=args.max_evaluations,
        progress=lambda line: print(f"identify: {line}", file=sys.stderr), drive=drive,
    )  # fmt: skip
    after = [sysid.replay_error(model, log, 0, args.hops, delay, e, s, drive) for _, e, s in measures]
    truth = truth_values(fresh, args.truth)
    print(table(fit, truth))
    for (what, _, _), e0, e1 in zip(measures, before, after, strict=True):
        print(error_line(f"replay of hops 1..{args.hops} ({what}) before", e0))
        print(error_line(f"replay of hops 1..{args.hops} ({what}) after ", e1))
        r0, r1 = e0.rms("pitch"), e1.rms("pitch")
        ratio = "both diverged" if math.isinf(r0) and math.isinf(r1) else f"{r0 / r1 if r1 > 0 else math.inf:.3g}x"
        print(f"  pitch RMS before / after: {ratio}")
    print(
        f"fit: {fit.windows} windows of {args.windows[-1]:g} s at the last stage, {fit.evaluations} simulations, "
        f"{fit.seconds:.0f} s; "
        f"residual RMS on those windows, the starting model -> the identified: "
        + ", ".join(f"{c} {fit.residual_before[c]:.3g} -> {fit.residual_after[c]:.3g}" for c in fit.residual_after)
    )
    spec = mujoco.MjSpec.from_file(args.model or str(MODEL_XML))  # the robot the fit started from
    sysid.to_spec(spec, fresh, fit.values)
    args.out.write_text(spec.to_xml())
    print(f'wrote {args.out} (the identified robot; the gyro bias in <numeric name="gyro_bias">, rad/s)')
    return EXIT_OK


def identify_out(args: argparse.Namespace) -> None:
    """Refuse (one line, exit 2, before any work) an --out that would overwrite the log or the model the
    fit starts from (the same file by its resolved path: symlinks, ./x and x)."""
    out, start = args.out, args.model or str(MODEL_XML)
    if same_file(out, args.log):
        fail(f"--out {out}: is the log; write the identified MJCF to another file")
    if same_file(out, start):
        fail(f"--out {out}: is the model the fit starts from ({start}); write the identified MJCF to another file")


def table(fit, truth: dict[str, float]) -> str:  # noqa: ANN001 (a sysid.Fit)
    """The estimates, one a line: name, unit, nominal, truth if known, estimate +- sigma; then what is not separable."""
    row = "{:16s} {:10s} {:>10s} {:>10s} {:>10s} {:>9s} {:>7s}{}"
    lines = [row.format("parameter", "unit", "nominal", "truth", "estimate", "sigma", "error", "")]
    tangled = {n for a, b, _ in fit.not_separable() for n in (a, b)}
    for e in fit.estimates:
        t = truth.get(e.name)
        error = "" if t is None else f"{100 * (e.value - t) / abs(t):+.2f}%" if t else f"{e.value - t:+.3g}"
        flag = "  not separable" if e.name in tangled else ""
        known = "" if t is None else f"{t:.5g}"
        lines.append(
            row.format(e.name, e.unit, f"{e.nominal:.5g}", known, f"{e.value:.5g}", f"{e.sigma:.2g}", error, flag)
        )
    for name, (low, high) in fit.profile.items():
        lines.append(
            f"{name}: its cost is within {PROFILE_SIGMAS:g} sigma of its least from {low:.4g} to {high:.4g} "
            "(its line search's profile; wide where the feet never slip)"
        )
    for a, b, c in fit.not_separable():
        lines.append(f"not separable: {a} and {b} (correlation {c:+.4f}): only a combination of them is identified")
    names = {e.name for e in fit.estimates}
    if {"wheel_inertia", "wheel_armature"} <= names:
        spin, sigma = fit.combined(("wheel_inertia", "wheel_armature"))
        t = truth.get("wheel_inertia", 0.0) + truth.get("wheel_armature", 0.0) if "wheel_inertia" in truth else None
        error = "" if t is None else f" ({100 * (spin - t) / t:+.2f}% of the truth, {t:.5g})"
        lines.append(f"wheel spin inertia (wheel_inertia + wheel_armature): {spin:.5g} +- {sigma:.2g} kg m^2{error}")
    return "\n".join(lines)
