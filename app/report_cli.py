"""`hopper-sim report INPUT --out DIR`: the paper's figures of a run, a recording or a sweep.

INPUT is a run's JSON (`hopper-sim run --json`), a comparison's (`compare --json`: wheel on and
off over seeds), a rerun recording (`.rrd`), or a sweep (its output directory, or a Parquet file
or folder of its `episodes` dataset). DIR receives every figure as PNG and PDF and report.html,
one self-contained page with the figures and the settings.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

from hopper.app.cli_common import EXIT_OK, check_replaced, fail, staged_out
from hopper.app.episode import sim_config, simulate

from hopper.controllers import ControllerError
from hopper.report.folder import is_report_folder
from hopper.trace import TRACE_COLUMNS

KINDS = ("run JSON", "compare JSON", "league JSON", "stand JSON", ".rrd recording", "sweep directory or Parquet")


def add_parser(commands: argparse._SubParsersAction, epilog: str) -> None:
    """Register `report` on hopper-sim's subcommands."""
    report = commands.add_parser(
        "report", help="figures (PNG, PDF) and one HTML page from a run's JSON, a .rrd or a sweep", epilog=epilog
    )
    report.add_argument("input", type=Path, metavar="INPUT", help="; ".join(KINDS))
    report.add_argument(
        "--out", type=Path, required=True, metavar="DIR",
        help="folder for the figures and report.html: new, empty or an earlier report's (replaced whole at the end)",
    )  # fmt: skip
    report.add_argument("--seed", type=int, default=None, help="compare JSON: the seed whose time series is drawn")
    report.add_argument(
        "--controller",
        metavar="SPEC",
        help="run or compare JSON: draw the runs re-flown by this controller (their other settings kept)",
    )
    report.add_argument(
        "--no-simulate",
        action="store_true",
        help="simulate nothing: not a run JSON's wheel-off twin, nor the runs of an older JSON without a trace",
    )


def kind(path: Path) -> str:
    """Which input `path` is ('json', 'rrd', 'sweep'); ValueError with the reason otherwise."""
    if not path.exists():
        raise ValueError(f"{path} does not exist")
    if path.is_dir():
        if (path / "episodes").is_dir() or any(path.glob("*.parquet")):
            return "sweep"
        raise ValueError(f"{path} is a folder without an episodes/ dataset or Parquet files")
    suffix = path.suffix.lower()
    if suffix in (".json", ".rrd", ".parquet"):
        return {".json": "json", ".rrd": "rrd", ".parquet": "sweep"}[suffix]
    raise ValueError(f"{path}: expected a .json, .rrd, .parquet or a sweep directory")


def _simulated(settings: dict[str, Any], wheel: bool) -> dict[str, Any]:
    """The run `settings` describe, with the wheel on or off, simulated again (deterministic)."""
    config = dataclasses.replace(sim_config(settings), wheel=wheel)
    print(f"simulating seed {config.seed}, wheel {'on' if wheel else 'off'}, {settings['hops']} hops", file=sys.stderr)
    return simulate(config, int(settings["hops"]))


def _flown_by(settings: dict[str, Any], spec: str) -> dict[str, Any]:
    """The settings' controller and params replaced by `spec`'s defaults (ControllerError if it cannot fly)."""
    from hopper.controllers import with_controller
    from hopper.sim import Simulation

    config = with_controller(sim_config(settings), spec)
    Simulation(config)  # the pre-run check, before any figure
    return {"controller": config.controller, "controller_params": list(config.controller_params)}


def _drawn_seed(results: list[dict[str, Any]], seed: int | None) -> Any:
    """The seed whose time series the report draws: `seed` if given, else the first wheel-on run's (the
    first run's if none has the wheel on). Only its runs need a trace."""
    if seed is not None:
        return seed
    on = [r for r in results if bool(r.get("wheel", r["settings"].get("wheel", True)))]
    return (on or results)[0]["settings"].get("seed")


def refuse_run_flags(args: argparse.Namespace, what: str) -> None:
    """ValueError, one line, for a flag that only a run or compare JSON's report uses: with `what` (the
    input, in words) it would be ignored."""
    given = [
        flag
        for flag, value in (("--seed", args.seed), ("--controller", getattr(args, "controller", None)),
                            ("--no-simulate", args.no_simulate))
        if value is not None and value is not False
    ]  # fmt: skip
    if given:
        raise ValueError(f"{given[0]} is for a run or compare JSON; {what} has no runs to draw or simulate: drop it")


def _check_seed(seed: int, results: list[dict[str, Any]], twin: bool, path: Path) -> None:
    """--seed names a wheel-on run of the file (`twin`: a run JSON's wheel-off twin, simulated with the
    wheel on, counts too); ValueError, one line with the seeds there are, otherwise."""
    on = {r["settings"].get("seed") for r in results if bool(r.get("wheel", r["settings"].get("wheel", True)))}
    if twin:
        on |= {r["settings"].get("seed") for r in results}
    if seed not in on:
        there = ", ".join(str(s) for s in sorted(on, key=str)) or "none"
        raise ValueError(f"--seed {seed}: no wheel-on run of that seed in {path} (its wheel-on seeds: {there})")


def _json_report(path: Path, args: argparse.Namespace):  # noqa: ANN202 (hopper.report.build.Report)
    from hopper.report.build import run_report
    from hopper.report.runs import hop_dicts, kind_of, run_from_result

    try:
        document = json.loads(path.read_text())
        named = document.get("kind") if isinstance(document, dict) else None
        what = None if named in ("league", "frequency") else kind_of(document)
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: {exc}") from None
    if named in ("league", "frequency"):  # hopper-sim league --json, stand --json
        from hopper.report.frequency import frequency_report
        from hopper.report.league import league_report

        refuse_run_flags(args, f"a {'league' if named == 'league' else 'stand'} JSON")
        try:
            if named == "league":
                return league_report(document, f"Hopper league report: {path.name}")
            return frequency_report(document, f"Hopper loop measurement: {path.name}")
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from None
    results = document["runs"] if what == "compare" else [document]
    for result in results:
        try:  # a hand-edited result: one line naming what is wrong, before any simulation
            if not isinstance(result, dict) or not isinstance(result.get("settings"), dict):
                raise ValueError("a result must be an object with a settings object")
            hop_dicts(result.get("hops"))
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from None
    if args.seed is not None:  # checked against the file, before any run is simulated
        _check_seed(args.seed, results, twin=what == "run" and not args.no_simulate, path=path)
    source = f"{what} JSON"
    drawn = _drawn_seed(results, args.seed)
    runs = []
    for number, result in enumerate(results, 1):
        # The same flights by another controller (getattr: a Namespace may be built without the flag).
        if getattr(args, "controller", None):
            settings = {**result["settings"], **_flown_by(result["settings"], args.controller)}
            result = _simulated(settings, bool(settings["wheel"]))
            source = f"{what} JSON, re-flown by {args.controller}"
        elif result.get("trace") is None and what == "compare" and result["settings"].get("seed") != drawn:
            result = {**result, "trace": {column: [] for column in TRACE_COLUMNS}}  # not drawn: hops suffice
        elif result.get("trace") is None:  # an older JSON, or a compare seed other than the first
            if args.no_simulate:
                which = f"run {number} of {len(results)} in {path}" if what == "compare" else f"{path}"
                why = "compare keeps its first seed's only" if what == "compare" else "an older run JSON"
                raise ValueError(f"{which} holds no trace ({why}): drop --no-simulate to simulate it again for one")
            result = _simulated(result["settings"], bool(result["settings"]["wheel"]))
            source = f"{what} JSON, re-simulated for its trace"
        runs.append(run_from_result(result, source))
    on = [r for r in runs if r.wheel]
    off = [r for r in runs if not r.wheel]
    if what == "run" and not args.no_simulate:  # the paper's comparison needs the other wheel state
        twin = run_from_result(_simulated(runs[0].settings, not runs[0].wheel), "re-simulated")
        (off if runs[0].wheel else on).append(twin)
    if args.seed is not None:  # its run first (_check_seed made sure there is one)
        on = [r for r in on if r.seed == args.seed] + [r for r in on if r.seed != args.seed]
    title = f"Hopper run report: {path.name}"
    seeds = sorted({r.seed for r in runs})
    subtitle = f"{source}: {len(on)} run(s) with the wheel on, {len(off)} with it off; seeds {seeds}"
    faulted = [r for r in runs if r.fault]
    if faulted:
        subtitle += (f"; the controller failed in {len(faulted)} of them and the PID flew on from there "
                     f"(failed runs): {faulted[0].fault}")  # fmt: skip
    return run_report(on, off, title, subtitle)


def _rrd_report(path: Path):  # noqa: ANN202
    from hopper.report.build import run_report
    from hopper.report.rrd import read_run

    run = read_run(path)
    subtitle = (
        f"read from the recording with rerun's reader; {len(run.hops)} hop(s). A recording holds no gait "
        "parameters, so no wheel-off twin is simulated: report a run's JSON for the comparison."
    )
    on, off = ([run], []) if run.wheel else ([], [run])
    return run_report(on, off, f"Hopper recording report: {path.name}", subtitle)


def _sweep_report(path: Path):  # noqa: ANN202
    from hopper.report.sweep import load, sweep_report

    return sweep_report(load(path), f"Hopper sweep report: {path.name}")


def command_report(args: argparse.Namespace) -> int:
    try:
        what = kind(args.input)
    except ValueError as exc:
        fail(str(exc))
    check_report_out(args.out)
    # --out is made and written to now, before the input is read; unmade (if it was made here and is
    # still empty) when the input is refused: a bad input leaves no empty folder behind. The report
    # is written beside it and takes its place whole at the end: stopped before, --out is as it was.
    with staged_out(args.out) as partial:
        from hopper.report.build import write

        try:
            if what == "json":
                report = _json_report(args.input, args)
            elif what == "rrd":
                refuse_run_flags(args, "a recording")
                report = _rrd_report(args.input)
            else:
                refuse_run_flags(args, "a sweep")
                report = _sweep_report(args.input)
        except (ValueError, KeyError, ControllerError) as exc:
            fail(str(exc.args[0]) if isinstance(exc, KeyError) and exc.args else str(exc))  # a KeyError's str quotes
        names = [p.name for p in write(report, partial)]
    print(f"{len(names)} files in {args.out}: {', '.join(names)}")
    return EXIT_OK


def check_report_out(out: Path) -> None:
    """--out is new, empty or an earlier report's folder (which the report replaces whole); anything
    else is refused in one line, before any work, as is the folder the command runs in."""
    what = "a report's folder (report.html with its PNG and PDF figures)"
    check_replaced(out, is_report_folder, what, "a report")
