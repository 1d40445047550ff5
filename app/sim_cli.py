"""`hopper-sim`: the headless runner (one run, or wheel on vs off over many seeds)."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import functools
import json
import math
import multiprocessing
import os
import statistics
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from hopper.app import log_cli, report_cli, size_cli, stand_cli, sweep_cli, sysid_cli
from hopper.app.cli_common import (
    EXIT_CLOSED_STDOUT,
    EXIT_CONTROLLER,
    EXIT_FELL,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_SHORT,
    EXIT_STATUSES,
    Parser,
    add_controller_flags,
    add_model_flag,
    add_run_flags,
    capped,
    check_executor,
    check_replaced,
    checked_controller,
    fail,
    finish_complete,
    finite,
    gains_flags,
    output_closed,
    part_limit,
    rrd_file,
    run_all,
    schedule,
    seed,
    staged_out,
    with_controller_flags,
    writable_file,
)
from hopper.app.episode import settings, simulate, version
from hopper.app.episode import sim_config as sim_config  # re-exported: results' docs named it here first
from hopper.app.recordings import FileLimits
from hopper.terrain import CraterParams

from hopper.config import TOTAL_MASS, GaitParams, InvalidConfig, SimConfig
from hopper.interrupts import children_ignore_ctrl_c, each, stop_like_ctrl_c
from hopper.scenarios import scenario

if TYPE_CHECKING:
    from hopper.analysis.envelope import Row

CRATER_DEFAULTS = CraterParams()

# The JSON keys of a hop, in table order, with their column headings.
HOP_COLUMNS = {
    "distance_m": "dist m",
    "apex_height_m": "apex m",
    "flight_time_s": "flight s",
    "peak_pitch_deg": "peak deg",
    "rms_pitch_rate_deg_s": "rms deg/s",
    "landing_pitch_deg": "land deg",
    "saturation_time_s": "sat s",
    "peak_wheel_rpm": "wheel rpm",
    "wheel_energy_j": "wheel J",  # electrical energy over the hop, ground and flight (hopper.control.energy)
    "leg_energy_j": "legs J",
    "cost_of_transport": "CoT",
}
# The response metrics (hopper.metrics.ResponseMetrics): from the scheduled kick, or the liftoff.
RESPONSE_COLUMNS = {
    "response_start_s": "from s",
    "response_peak_deg": "peak deg",
    "overshoot_deg": "over deg",
    "settling_time_s": "settle s",
    "peak_wheel_torque_nm": "torque Nm",
    "peak_momentum_pct": "moment %",
    "landing_error_deg": "land deg",
}


def parser() -> Parser:
    top = Parser(prog="hopper-sim", description=__doc__, epilog=EXIT_STATUSES)
    commands = top.add_subparsers(dest="command", required=True, parser_class=Parser)
    run = commands.add_parser("run", help="simulate one robot until N hops or a fall", epilog=EXIT_STATUSES)
    add_run_flags(run)
    run.add_argument("--seed", type=seed, default=0, help="terrain seed (default 0)")
    run.add_argument("--no-wheel", action="store_true", help="zero wheel torque, wheel free to spin")
    run.add_argument("--rrd", type=rrd_file, metavar="PATH", help="record a rerun .rrd session")
    run.add_argument(
        "--schedule",
        type=schedule,
        metavar="KIND:MAG[@MSms][,every:N]",
        help="kick every (Nth) flight the same way, e.g. pitch_kick:0.3@150ms or torque_pulse:10@every:3 "
        "(delay after liftoff, default 150 ms); kinds pitch_kick, push_forward, push_backward, torque_pulse",
    )
    run.add_argument(
        "--rerun-viewer",
        choices=("spawn", "serve", "off"),
        default="off",
        help="also watch live in a rerun viewer (default off)",
    )
    run.add_argument(
        "--rrd-max-mb", type=part_limit(2.0, "MB"), metavar="MB", help="roll --rrd over into parts of about MB each"
    )
    run.add_argument(
        "--rrd-max-min",
        type=part_limit(0.05, "min"),
        metavar="MIN",
        help="roll --rrd over into parts of MIN minutes of simulation each",
    )

    compare = commands.add_parser("compare", help="wheel on vs off over seeds 0..K-1", epilog=EXIT_STATUSES)
    add_run_flags(compare)
    compare.add_argument("--seeds", type=int, default=10, help="number of seeds (default 10)")
    compare.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="processes (default: all cores)")
    compare.add_argument(
        "--executor", choices=("auto", "local", "ray"), default="auto", help="as for sweep (default auto)"
    )
    compare.add_argument("--address", help="a Ray cluster's address (as for sweep)")

    stress = commands.add_parser(
        "stress",
        help="the controller's stress battery (terrains, gravities, pushes, kicks): a pass/fail table",
        epilog=EXIT_STATUSES,
    )
    stress.add_argument("--seeds", type=int, help="Moon terrain seeds, 20 hops each (default 100)")
    stress.add_argument("--gravity-seeds", type=int, help="seeds per gravity, 10 hops each (default 5)")
    stress.add_argument(
        "--groups", type=groups, default=STRESS_GROUPS, help="any of terrain,gravity,ground,flight (default all four)"
    )
    stress.add_argument("--quick", action="store_true", help="a few cases of each group (what the tests run)")
    stress.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="processes (default: all cores)")
    stress.add_argument("--json", type=writable_file, metavar="PATH", help="write every case's outcome as JSON")
    add_controller_flags(stress)
    add_model_flag(stress)

    league = commands.add_parser(
        "league",
        help="every controller on one battery (terrains, gravities 0.2-10, pushes, kicks, model mismatch): a table",
        epilog=EXIT_STATUSES,
    )
    league.add_argument(
        "--controllers",
        default="pid,lqr,mpc,policy",
        metavar="SPECS",
        help="comma-separated: pid, lqr, mpc, policy, policy:WEIGHTS.json, FILE.py:Class, module:Class, tcp://... "
        "(default: the built-ins)",
    )
    league.add_argument("--quick", action="store_true", help="a few episodes of each group (what the tests run)")
    league.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="processes (default: all cores)")
    league.add_argument(
        "--executor", choices=("auto", "local", "ray"), default="auto", help="as for sweep (default auto)"
    )
    league.add_argument("--address", help="a Ray cluster's address (as for sweep)")
    league.add_argument("--json", type=writable_file, metavar="PATH", help="write the table and every episode as JSON")
    add_model_flag(league)

    envelope = commands.add_parser(
        "envelope",
        help="pitch kicks of every size, direction and moment in flight against the physical limit: table and figure",
        epilog=EXIT_STATUSES,
    )
    envelope.add_argument(
        "--sizes", type=float_list, default="0.25:5:0.25", metavar="LIST|START:STOP:STEP",
        help="kick sizes, N m s, each flown both ways (default 0.25:5:0.25)",
    )  # fmt: skip
    envelope.add_argument(
        "--moments", type=float_list, default="0.1,0.3,0.5,0.7,0.9", metavar="LIST",
        help="moments of the kick as fractions of the undisturbed flight (default 0.1,0.3,0.5,0.7,0.9)",
    )  # fmt: skip
    envelope.add_argument(
        "--out", type=Path, metavar="DIR",
        help="folder for envelope.png, .pdf and .json: new, empty or an earlier envelope's (replaced whole at the end)",
    )  # fmt: skip
    envelope.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="processes (default: all cores)")
    add_model_flag(envelope)

    sweep_cli.add_commands(commands)  # sweep and tune
    sysid_cli.add_commands(commands)  # capture, replay, identify
    export = commands.add_parser(
        "terrain", help="export a crater field as a grayscale PNG (as the paper does)", epilog=EXIT_STATUSES
    )
    export.add_argument("--seed", type=seed, default=0, help="terrain seed (default 0)")
    export.add_argument("--png", type=png_file, required=True, metavar="PATH.png", help="16-bit grayscale PNG")
    export.add_argument(
        "--x0", type=terrain_x0, default=CRATER_DEFAULTS.x0, metavar="M",
        help=f"world x (m) of the window's -x edge; the field has no end (default {CRATER_DEFAULTS.x0:g}, the start)",
    )  # fmt: skip
    report_cli.add_parser(commands, EXIT_STATUSES)
    stand_cli.add_parser(commands, EXIT_STATUSES)
    log_cli.add_parser(commands, EXIT_STATUSES)
    size_cli.add_parser(commands, EXIT_STATUSES)
    return top


X0_LIMIT_M = 1e9  # float64 still resolves the 0.05 m cells there (to ~1e-7 m), and numpy's tile seeds fit


def png_file(text: str) -> Path:
    """A writable PATH.png (PIL picks the format from the suffix; only PNG holds 16-bit grey)."""
    if Path(text).suffix.lower() != ".png":
        raise argparse.ArgumentTypeError(f"{text}: the file must end in .png (16-bit grayscale PNG)")
    return writable_file(text)


def terrain_x0(text: str) -> float:
    """--x0, m: a finite number within X0_LIMIT_M of the start."""
    value = finite(text)
    if abs(value) > X0_LIMIT_M:
        raise argparse.ArgumentTypeError(f"must lie within +-{X0_LIMIT_M:g} m, got {text}")
    return value


def make_config(args: argparse.Namespace, seed: int, wheel: bool) -> SimConfig:
    """The flags' robot, its controller checked (one line and exit 2 if it cannot fly)."""
    config = SimConfig(
        seed=seed,
        terrain=args.terrain,
        gravity=args.gravity,
        wheel=wheel,
        gains=gains_flags(args),
        sensing=args.sensing,
        gait=scenario(args.scenario).gait,
        model=args.model,
    )
    return with_controller_flags(config, args)


def hop_table(hops: list[dict[str, Any]]) -> str:
    lines = ["hop " + " ".join(f"{h:>9}" for h in HOP_COLUMNS.values())]
    for hop in hops:
        row = " ".join(f"{hop[k]:9.3f}" if abs(hop[k]) < 100 else f"{hop[k]:9.1f}" for k in HOP_COLUMNS)
        lines.append(f"{hop['index']:>3}{'*' if not hop['completed'] else ' '}{row}")
    return "\n".join(lines)


def response_table(hops: list[dict[str, Any]], schedule: str | None = None) -> str:
    """Each hop's response: from the kick (k) or the liftoff; a settling time with > did not settle
    by the touchdown (a lower bound). Then a line of the completed hops' means and worsts."""
    lines = ["resp" + " ".join(f"{h:>9}" for h in RESPONSE_COLUMNS.values())]
    for hop in hops:
        cells = [f"{hop[k]:9.3f}" if abs(hop[k]) < 100 else f"{hop[k]:9.1f}" for k in RESPONSE_COLUMNS]
        if not hop["settled"]:
            cells[3] = f"{'>' + format(hop['settling_time_s'], '.3f'):>9}"
        lines.append(f"{hop['index']:>3}{'k' if hop['kicked'] else ' '}{' '.join(cells)}")
    done = [h for h in hops if h["completed"]]
    if done:
        lines.append(
            f"response from {'the kick (' + schedule + ')' if schedule else 'liftoff'}: "
            f"mean overshoot {statistics.fmean(h['overshoot_deg'] for h in done):.2f} deg, "
            f"worst settling {max(h['settling_time_s'] for h in done):.3f} s, "
            f"peak torque {max(h['peak_wheel_torque_nm'] for h in done):.1f} N m, "
            f"peak momentum {max(h['peak_momentum_pct'] for h in done):.0f} % of capacity, "
            f"worst landing error {max(abs(h['landing_error_deg']) for h in done):.2f} deg"
        )
    return "\n".join(lines)


def summary(result: dict[str, Any]) -> str:
    done = [h for h in result["hops"] if h["completed"]]
    s = result["settings"]
    wheel = "on" if s["wheel"] else "off (zero torque, free to spin)"
    gains, law = s["gains"], result.get("controller") or {"spec": "pid"}
    if law["spec"] == "pid":
        flown = f"kp {gains['kp']:g} ki {gains['ki']:g} kd {gains['kd']:g}"
    else:
        values = " ".join(f"{k} {v:g}" for k, v in law["params"].items())
        flown = f"controller {law['spec']} ({law['name']}{': ' + values if values else ''}; "
        trip = law["round_trip_us"]
        flown += f"{law['compute_us']:.1f} us a call" + (
            f", round trip p50 {trip['p50']:.1f} us p99 {trip['p99']:.1f} us)" if trip else ")"
        )
    lines = [
        (f"model {s['model']}, " if s.get("model") else "")
        + f"terrain {s['terrain']}, seed {s['seed']}, gravity {s['gravity']:g} m/s^2, "
        f"{flown}, wheel {wheel}: {len(done)} hops"
        + (", FELL" if result["fell"] else "")
        + f"; {result['sim_time_s']:.2f} s simulated in {result['wall_time_s']:.2f} s wall"
        + f" ({result['sim_time_s'] / max(result['wall_time_s'], 1e-9):.0f}x real time)"
    ]
    if done:

        def stat(key: str) -> float:
            return max(h[key] for h in done)

        mean_distance = statistics.fmean(h["distance_m"] for h in done)
        lines.append(
            f"mean distance {mean_distance:.3f} m/hop, {energy_means(done, s['gravity'], robot_mass(s))}; "
            f"worst: peak pitch {stat('peak_pitch_deg'):.2f} deg, "
            f"landing pitch {stat('landing_pitch_deg'):.2f} deg, saturation {stat('saturation_time_s'):.3f} s/hop, "
            f"wheel {stat('peak_wheel_rpm'):.0f} rpm"
        )
    if any(not h["completed"] for h in result["hops"]):
        lines.append("* the flight that ended in the fall")
    if law.get("fault"):
        lines.append(f"the controller failed and the PID flew on: {law['fault']}")
    return "\n".join(lines)


def trapped(result: dict[str, Any]) -> str | None:
    """A note when the run's robot was trapped (hopper.metrics.trapped_at): it hopped on without
    falling, but went nowhere. None for a gait that hops in place (a zero forward speed)."""
    from hopper.metrics import TRAP_HOPS, TRAP_M, trapped_at

    if result["settings"]["gait"]["forward_speed"] == 0.0:
        return None
    hop = trapped_at([h["distance_m"] for h in result["hops"] if h["completed"]])
    if hop is None:
        return None
    return (
        f"note: trapped from hop {hop + 1}: {TRAP_HOPS} hops got the robot less than {TRAP_M:g} m further "
        "(a crater it does not climb out of)"
    )


def energy_per_hop(hops: list[dict[str, Any]]) -> float:
    """Mean electrical energy (J) of the completed hops, wheel and legs (0 without one)."""
    done = [h for h in hops if h["completed"]]
    return statistics.fmean(h["wheel_energy_j"] + h["leg_energy_j"] for h in done) if done else 0.0


def robot_mass(settings: dict[str, Any]) -> float:
    """kg, the mass of the robot a result's `settings` flew (its --model's, else the packaged one's)."""
    if settings.get("model") is None:
        return TOTAL_MASS
    from hopper.model import robot_of

    return robot_of(sim_config(settings)).mass


def energy_means(done: list[dict[str, Any]], gravity: float, mass: float = TOTAL_MASS) -> str:
    """The completed hops' mean energy and their cost of transport: all their energy over m g times
    all their distance."""
    from hopper.metrics import cost_of_transport  # numba's import, not paid by --help

    wheel, legs = (statistics.fmean(h[k] for h in done) for k in ("wheel_energy_j", "leg_energy_j"))
    distance = sum(abs(h["distance_m"]) for h in done)
    transport = cost_of_transport(len(done) * (wheel + legs), mass, gravity, distance)
    return (
        f"energy {wheel + legs:.1f} J/hop (wheel {wheel:.1f}, legs {legs:.1f}; braking not recovered), "
        f"cost of transport {transport:.2f}"  # NaN if they went nowhere
    )


def peak_deviation(result: dict[str, Any]) -> float:
    """Largest mid-air pitch deviation of a run (deg), the fall's flight included."""
    return max((h["peak_pitch_deg"] for h in result["hops"]), default=0.0)


def command_run(args: argparse.Namespace) -> int:
    def report(result: dict[str, Any]) -> None:
        print(hop_table(result["hops"]))
        print(response_table(result["hops"], result["settings"]["schedule"]))
        print(summary(result))
        if args.rrd:
            print(f"recording: {', '.join(result.get('rrd_parts', [str(args.rrd)]))}")
        if args.json:
            args.json.write_text(json.dumps(result, indent=2))

    limits = FileLimits(max_mb=args.rrd_max_mb, max_min=args.rrd_max_min)
    if limits.rolls and (args.rrd is None or args.rerun_viewer != "off"):
        fail("--rrd-max-mb and --rrd-max-min need --rrd and cannot be combined with --rerun-viewer")
    config = make_config(args, args.seed, wheel=not args.no_wheel)
    result = simulate(config, args.hops, args.rrd, args.rerun_viewer, report, limits=limits, kicks=args.schedule)
    for note in (capped(config), trapped(result)):
        if note:
            print(note)
    if result["short"] is not None:
        print(f"hopper-sim: error: {result['short']}", file=sys.stderr)
        return EXIT_SHORT
    fault = result["controller"]["fault"]
    if fault:
        print(f"hopper-sim: error: controller {config.controller} failed: {fault}", file=sys.stderr)
        return EXIT_CONTROLLER
    return EXIT_FELL if result["fell"] else EXIT_OK


def command_compare(args: argparse.Namespace) -> int:
    from hopper.experiments.spec import Episode

    gait, default = scenario(args.scenario).gait, GaitParams()
    changed = tuple(
        (f.name, getattr(gait, f.name))
        for f in dataclasses.fields(GaitParams)
        if getattr(gait, f.name) != getattr(default, f.name)
    )  # the scenario's gait, as a sweep's gait axes
    flown = make_config(args, 0, True)  # checks the controller before any episode
    g, params = flown.gains, flown.controller_params
    episodes = [
        Episode(kp=g.kp, ki=g.ki, kd=g.kd, gravity=args.gravity, seed=seed, hops_target=args.hops,
                terrain=args.terrain, wheel=wheel, sensing=args.sensing, gait=changed,
                controller=flown.controller, params=params, mjcf=flown.model, trace=seed == 0)
        for seed in range(args.seeds)
        for wheel in (True, False)
    ]  # fmt: skip
    finish = functools.partial(_compare_results, args, flown, episodes)
    return run_all(episodes, args.executor, args.workers, args.address, "runs", finish, "compare", noun="run")


def _compare_results(args: argparse.Namespace, flown: SimConfig, episodes: list, done: dict) -> int:
    """compare's table, median and JSON from every run's result (`done`: episode_id -> EpisodeResult);
    its exit status."""
    from hopper.experiments.reduction import SeedPair, median_reduction

    results = []
    for episode in episodes:
        r = done[episode.episode_id]
        results.append({
            "settings": settings(episode.config(), episode.hops_target), "seed": episode.seed,
            "wheel": episode.wheel, "fell": r.fell, "sim_time_s": r.sim_time_s, "wall_time_s": r.wall_s,
            "fault": r.controller_fault,  # why the PID flew on from mid-run, "" if it did not (run's controller.fault)
            "hops": [hop.as_dict() for hop in r.hops],
            **({"trace": r.trace} if r.trace is not None else {}),  # as run's: what report draws
        })  # fmt: skip
    rows, pairs = [], []
    print(
        f"{'seed':>4} {'on: hops':>9} {'peak deg':>9} {'off: hops':>10} {'peak deg':>9} {'reduction':>10}"
        f" {'on: J/hop':>10}"
    )
    for on, off in zip(results[::2], results[1::2], strict=False):
        peak_on, peak_off = peak_deviation(on), peak_deviation(off)
        pair = SeedPair(on["seed"], peak_on, peak_off, faulted_runs=bool(on["fault"]) + bool(off["fault"]))
        pairs.append(pair)
        reduction = pair.reduction_pct
        left_out = bool(pair.faulted_runs)  # of the median: a faulted run's figures are not the controller's
        rows.append({"seed": on["seed"], "peak_on_deg": peak_on, "peak_off_deg": peak_off, "reduction_pct": reduction,
                     "left_out": left_out})  # fmt: skip

        def hops(r: dict[str, Any]) -> str:
            ended = (" fell" if r["fell"] else "") + (" fault" if r["fault"] else "")
            return f"{sum(h['completed'] for h in r['hops'])}{ended}"

        print(
            f"{on['seed']:>4} {hops(on):>9} {peak_on:9.2f} {hops(off):>10} {peak_off:9.2f} {reduction:9.1f}%"
            f" {energy_per_hop(on['hops']):10.1f}"
        )
    reduced = median_reduction(pairs)  # over the seeds the controller flew to the end
    print(reduced.line())
    faulted = [r for r in results if r["fault"]]
    if args.json:
        doc = {"median_peak_reduction_pct": reduced.median_pct, "controller_faults": len(faulted), "seeds": rows,
               "runs": results}  # fmt: skip
        args.json.write_text(json.dumps(doc, indent=2))
    if faulted:  # the PID flew the rest of those runs: their figures are not the controller's (run's exit 4)
        which = ", ".join(f"seed {r['seed']} wheel {'on' if r['wheel'] else 'off'}" for r in faulted)
        print(f"hopper-sim: error: controller {flown.controller} failed in {len(faulted)} of {len(results)} runs "
              f"({which}) and the PID flew on from there: {faulted[0]['fault']}", file=sys.stderr)  # fmt: skip
        return EXIT_CONTROLLER
    return EXIT_OK  # falls with the wheel off are the expected result here, not a failure


def command_terrain(args: argparse.Namespace) -> int:
    from hopper.terrain import CraterField, CraterParams, write_png

    params = CraterParams()
    first = math.floor(args.x0 / params.cell)  # the field's grid column at or before --x0
    heights = CraterField(params, args.seed).columns(first, params.shape[1])
    write_png(heights, args.png)
    print(
        f"{args.png}: {heights.shape[1]} x {heights.shape[0]} cells of {params.cell} m "
        f"({params.length} m x {params.width} m from x = {first * params.cell:g} m), "
        f"relief {np.ptp(heights):.3f} m, seed {args.seed}"
    )
    return 0


STRESS_GROUPS = ("terrain", "gravity", "ground", "flight")


def groups(text: str) -> tuple[str, ...]:
    """A comma-separated subset of the stress battery's groups."""
    chosen = tuple(g.strip() for g in text.split(",") if g.strip())
    unknown = [g for g in chosen if g not in STRESS_GROUPS]
    if unknown or not chosen:
        raise argparse.ArgumentTypeError(f"{text!r}: choose from {','.join(STRESS_GROUPS)}")
    return chosen


def command_stress(args: argparse.Namespace) -> int:
    from hopper.experiments.stress import battery

    flown = with_controller_flags(SimConfig(model=args.model), args)
    seeds, gravity_seeds = args.seeds or 100, args.gravity_seeds or 5  # None: not given (check_counts refuses 0)
    cases = battery(seeds=seeds, gravity_seeds=gravity_seeds, quick=args.quick, controller=flown)
    cases = [c for c in cases if c.group in args.groups]
    outcomes: list = []
    gather = functools.partial(_fly_cases, cases, args.workers, "cases", outcomes)
    finish = functools.partial(_stress_results, args, outcomes)
    return finish_complete(gather, lambda: len(outcomes) == len(cases), finish, "stress", "case")


def _fly_cases(cases: list, workers: int, desc: str, outcomes: list) -> None:
    """Fly `cases` (hopper.experiments.stress.run_case) on a pool of up to `workers` processes with a
    progress bar (`desc`), each outcome appended to `outcomes` as it comes: a stop then knows how many
    are in (finish_complete)."""
    from tqdm import tqdm

    from hopper.experiments.stress import run_case

    with children_ignore_ctrl_c():  # pool workers leave Ctrl-C to this process, which stops them
        pool = multiprocessing.get_context("spawn").Pool(max(1, min(workers, len(cases))))
    with pool:
        runs = each(pool.imap(run_case, cases, chunksize=1))
        for outcome in tqdm(runs, total=len(cases), desc=desc, unit="case", file=sys.stderr):
            outcomes.append(outcome)  # one by one: a stop then knows how many are in


def _stress_results(args: argparse.Namespace, outcomes: list) -> int:
    """The stress battery's table and JSON from every case's outcome; its exit status."""
    from hopper.experiments.stress import table

    print("\n".join(table(outcomes)))
    if args.json:
        rows = [
            {"group": o.case.group, "case": o.case.name, "passed": o.passed, "hops": o.hops, "fell": o.fell,
             "cause": o.cause, "worst_landing_deg": o.worst_landing_deg, "worst_peak_deg": o.worst_peak_deg,
             "peak_wheel_rpm": o.peak_wheel_rpm, "fault": o.fault, "settings": settings(o.case.config, o.case.hops)}
            for o in outcomes
        ]  # fmt: skip
        args.json.write_text(json.dumps({"version": version(), "cases": rows}, indent=2))
    return EXIT_OK if all(o.passed for o in outcomes) else EXIT_FELL


def command_league(args: argparse.Namespace) -> int:
    from hopper.controllers.loading import canonical
    from hopper.experiments import league

    specs = [canonical(c) for c in args.controllers.split(",") if c.strip()]
    if not specs:
        fail("--controllers: name at least one controller")
    twice = sorted({spec for spec in specs if specs.count(spec) > 1})
    if twice:  # its rows would pool the episodes of both
        fail(f"--controllers: {', '.join(twice)} named more than once")
    for spec in specs:  # each flies a probe tick before any episode
        checked_controller(SimConfig(sensing="realistic", model=args.model), spec)
    from hopper.model import robot_of

    entries = league.battery(quick=args.quick, robot=robot_of(SimConfig(terrain="flat", model=args.model)))
    episodes = [e for spec in specs for e in league.episodes(spec, (), entries, args.model)]
    finish = functools.partial(_league_results, args, specs, entries, episodes)
    return run_all(episodes, args.executor, args.workers, args.address, "league", finish, "league")


def _league_results(args: argparse.Namespace, specs: list[str], entries: list, episodes: list, done: dict) -> int:
    """The league's table and JSON from every episode's result (`done`: episode_id -> EpisodeResult)."""
    from hopper.experiments import league

    rows = [league.row(spec, [done[e.episode_id] for e in episodes if e.controller == spec]) for spec in specs]
    print(f"league: {len(entries)} episodes per controller, realistic sensing; landing |pitch| in deg")
    print("\n".join(league.table(rows)))
    if args.json:
        runs = [
            {"settings": settings(r.episode.config(), r.episode.hops_target), "group": None, "fell": r.fell,
             "fault": r.controller_fault, "compute_us": r.compute_us, "hops": [h.as_dict() for h in r.hops]}
            for r in (done[e.episode_id] for e in episodes)
        ]  # fmt: skip
        doc = {"version": version(), "kind": "league", "rows": [r.as_dict() for r in rows], "runs": runs}
        args.json.write_text(json.dumps(doc, indent=2))
    faulted = [r for r in rows if r.faults]
    if faulted:  # the PID flew on from each fault, as in compare and sweep (run's exit 4); the table says which
        which = ", ".join(f"{r.controller} in {r.faults} of {r.episodes}" for r in faulted)
        print(f"hopper-sim: error: a controller failed mid-episode and the PID flew on from there: {which}",
              file=sys.stderr)  # fmt: skip
        return EXIT_CONTROLLER
    return EXIT_OK


def float_list(text: str) -> list[float]:
    """'a,b,c' or 'start:stop:step' (stop included) as a list of finite floats."""
    try:
        if ":" in text:
            start, stop, step = (float(v) for v in text.split(":"))
            if not step > 0 or stop < start:
                raise ValueError
            values = [round(start + i * step, 9) for i in range(int((stop - start) / step + 1e-9) + 1)]
        else:
            values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give numbers a,b,c or start:stop:step") from None
    if not values or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"{text!r}: give finite numbers")
    return values


def command_envelope(args: argparse.Namespace) -> int:
    """Fly the envelope's grid on all cores; print its table, write the figure and JSON if asked."""
    from hopper.disturbances import DISTURBANCE_LIMITS
    from hopper.report.envelope import is_envelope_folder

    top = DISTURBANCE_LIMITS["pitch_kick"][0]
    if not all(0 < v <= top for v in args.sizes):
        fail(f"--sizes must lie in (0, {top:g}] N m s")
    if not all(0 < v < 1 for v in args.moments):
        fail("--moments are fractions of the flight, between 0 and 1")
    if args.out:  # before the minutes of flying, not after
        check_replaced(args.out, is_envelope_folder, "an envelope's folder (envelope.png, .pdf and .json)",
                       "an envelope")  # fmt: skip
    # Written beside --out and swapped in whole at the end: stopped before, --out is as it was.
    with staged_out(args.out) if args.out else contextlib.nullcontext() as partial:
        status = _fly_envelope(args, partial)
    if args.out:
        print(f"wrote {args.out / 'envelope.png'}, .pdf and .json")
    return status


def _fly_envelope(args: argparse.Namespace, folder: Path | None) -> int:
    """Fly the envelope's kicks; its table printed, its figure and JSON written into `folder` if given.
    Its exit status: EXIT_FELL if a kick under the physical limit fell. A stop once every kick has flown
    cuts nothing short (finish_complete): the envelope is written whole."""
    from hopper.analysis import envelope

    config = SimConfig(terrain="flat", model=args.model)
    moments = envelope.flight_moments(config)
    flight = moments[-1].t + moments[-1].to_go
    sizes = [s * v for v in args.sizes for s in (1.0, -1.0)]
    cases = envelope.envelope_cases(config, sizes, args.moments, flight)
    outcomes: list = []
    gather = functools.partial(_fly_cases, cases, args.workers, "kicks", outcomes)

    def finish() -> int:
        rows = _envelope_results(args, folder, outcomes, moments, flight)
        return EXIT_FELL if any(r.falls_below_limit for r in rows) else EXIT_OK

    return finish_complete(gather, lambda: len(outcomes) == len(cases), finish, "envelope", "kick")


def _envelope_results(
    args: argparse.Namespace, folder: Path | None, outcomes: list, moments: list, flight: float
) -> list[Row]:
    """The envelope's rows from every kick's outcome: its table printed, its figure and JSON written."""
    from hopper.analysis import envelope
    from hopper.experiments.stress import LANDING_LIMIT_DEG

    rows = envelope.rows(outcomes, moments, args.moments, flight)
    print(f"flat Moon, kicks in the second flight ({flight:.3f} s); landing limit {LANDING_LIMIT_DEG:g} deg")
    print("\n".join(envelope.table(rows)))
    if folder is not None:
        from hopper.report.envelope import figure

        figure(outcomes, moments, folder)
        cases_json = [
            {"size": o.case.disturbance.magnitude, "delay_s": o.case.disturbance.delay_s, "fell": o.fell,
             "landing_deg": o.worst_landing_deg, "peak_deg": o.worst_peak_deg, "hops": o.hops}
            for o in outcomes
        ]  # fmt: skip
        payload = {"version": version(), "flight_s": flight, "rows": [dataclasses.asdict(r) for r in rows],
                   "cases": cases_json}  # fmt: skip
        (folder / "envelope.json").write_text(json.dumps(payload, indent=2))
    return rows


def check_counts(args: argparse.Namespace) -> None:
    """Refuse counts below one before any work (argparse's int accepts 0 and negatives), and flags
    the command would ignore: --executor local with --address, stress --quick with its seed counts."""
    for name in ("hops", "seeds", "workers", "gravity_seeds"):
        value = getattr(args, name, None)
        if value is not None and value < 1:
            fail(f"--{name.replace('_', '-')} must be at least 1, got {value}")
    if hasattr(args, "executor"):
        check_executor(args)
    if args.command == "stress" and args.quick:
        given = [f"--{n.replace('_', '-')}" for n in ("seeds", "gravity_seeds") if getattr(args, n) is not None]
        if given:
            fail(f"--quick flies its own few seeds, so it ignores {given[0]}: drop one of them")


def dispatch(argv: list[str] | None) -> int:
    """Parse the arguments and run the command they name; its exit status."""
    args = parser().parse_args(argv)
    if args.command == "terrain":
        return command_terrain(args)
    if args.command in ("sweep", "tune"):
        return sweep_cli.run(args)
    if args.command in sysid_cli.COMMANDS:
        return sysid_cli.run(args)
    if args.command == "report":
        return report_cli.command_report(args)
    if args.command == "stand":
        return stand_cli.command_stand(args)
    if args.command == "log":
        return log_cli.run(args)
    if args.command == "size":
        return size_cli.run(args)
    check_counts(args)
    if args.command == "league":
        return command_league(args)
    if args.command == "stress":
        return command_stress(args)
    if args.command == "envelope":
        return command_envelope(args)
    try:
        make_config(args, 0, True)  # validate gains and gravity before any work
        return command_run(args) if args.command == "run" else command_compare(args)
    except (InvalidConfig, ValueError) as exc:
        fail(str(exc))


def main(argv: list[str] | None = None) -> int:
    """Exit status (EXIT_STATUSES): 0 success, 1 the robot fell (run), 2 bad arguments, 3 stopped
    short, 4 the controller failed, 130 interrupted, 141 the reader of stdout went away."""
    stop_like_ctrl_c()  # SIGTERM unwinds like Ctrl-C, so recordings are closed
    try:
        status = dispatch(argv)
        sys.stdout.flush()  # a closed stdout fails here, not in the interpreter's own flush at exit
        return status
    except KeyboardInterrupt:
        print("hopper-sim: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # `hopper-sim run | head -1`: the reader has what it wanted
        if not output_closed():
            raise
        return EXIT_CLOSED_STDOUT


if __name__ == "__main__":
    sys.exit(main())
