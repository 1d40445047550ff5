"""`hopper-sim sweep` and `hopper-sim tune`: experiments at scale on the executors of hopper.experiments."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from hopper.app.cli_common import (
    CLOSED_STDOUT_STATUS,
    EXIT_CONTROLLER,
    EXIT_OK,
    add_model_flag,
    check_executor,
    check_reused,
    checked_controller,
    fail,
    made_out,
    model_file,
    not_flown,
    writable_file,
)

from hopper.config import GAIN_RANGES

SWEEP_EPILOG = (
    "exit status: 0 finished (falls are results), 2 bad spec or arguments, 4 finished, but a controller failed "
    "mid-episode and the PID flew on (it says which and why; those episodes count as failed), 130 interrupted "
    "(Ctrl-C or SIGTERM) before every episode was written: run the same command again and it skips the "
    f"finished episodes; {CLOSED_STDOUT_STATUS}."
)
# tune keeps no folder: an interrupted search is not resumed (and writes no --json).
TUNE_EPILOG = (
    "exit status: 0 finished (falls are results: they count in the score), 2 bad arguments (a --robust spec or "
    "a controller that cannot fly included), 130 interrupted "
    "(Ctrl-C or SIGTERM): nothing is kept and no --json written, the same command starts the search over; "
    f"{CLOSED_STDOUT_STATUS}."
)
AXIS_FLAGS = {
    "kp": "N m/rad: 450, 300,450,600, or START:STOP:NUM (linspace)",
    "ki": "N m/(rad s), as --kp",
    "kd": "N m s/rad, as --kp",
    "gravity": "m/s^2 or moon|mars|ceres|earth, comma-separated, or START:STOP:NUM",
    "seeds": "terrain seeds: N (0..N-1), 3,5,8, or START:STOP (stop excluded)",
    "hops": "hops per episode, e.g. 3 or 3,7",
    "terrain": "crater, flat or crater,flat",
    "wheel": "on, off or on,off",
    "sensing": "ideal, realistic or ideal,realistic",
}


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Register `sweep` and `tune` on hopper-sim's subcommands."""
    sweep = commands.add_parser(
        "sweep", help="a sweep of episodes to Parquet (spec file and/or flags)", epilog=SWEEP_EPILOG
    )
    sweep.add_argument("spec", nargs="?", type=Path, help="TOML spec (hopper/experiments/spec.py); flags override it")
    sweep.add_argument(
        "--out", type=Path, required=True, metavar="DIR", help="output folder: new, empty, or a sweep's (resumed)"
    )
    for name, text in AXIS_FLAGS.items():
        sweep.add_argument(f"--{name}", metavar="VALUES", help=text)
    sweep.add_argument("--gait", action="append", default=[], metavar="NAME=VALUES", help="a GaitParams axis")
    sweep.add_argument(
        "--disturbance",
        action="append",
        default=[],
        metavar="none|KIND:SIZES:PHASE:DELAY[:HOP]",
        help="a disturbance axis entry, e.g. push_forward:2,4:stance:0.1 (repeat for more)",
    )
    sweep.add_argument(
        "--controller",
        metavar="SPECS",
        help="the controllers flown, comma-separated: pid (default), lqr, mpc, FILE.py:Class, module:Class, ...",
    )
    sweep.add_argument(
        "--param", action="append", default=[], metavar="NAME=VALUES", help="an axis of the controllers' params"
    )
    model_options(sweep)
    add_model_flag(sweep)
    executor_options(sweep)

    tune = commands.add_parser(
        "tune", help="search Kp/Ki/Kd (and gait) for the best worst case over seeds and gravities", epilog=TUNE_EPILOG
    )
    tune.add_argument("--trials", type=int, default=40, help="candidates evaluated, the defaults first (default 40)")
    tune.add_argument("--seed", type=int, default=0, help="the optimiser's seed: same seed, same result (default 0)")
    tune.add_argument("--seeds", default="0:4", metavar="SEEDS", help="terrain seeds to tune on (default 0:4)")
    tune.add_argument("--heldout", default="100:108", metavar="SEEDS", help="held-out seeds (default 100:108)")
    tune.add_argument("--gravity", default="moon,mars", metavar="VALUES", help="gravities (default moon,mars)")
    tune.add_argument("--hops", type=int, default=4, help="hops per episode (default 4)")
    tune.add_argument("--terrain", choices=("crater", "flat"), default="crater", help="(default crater)")
    tune.add_argument("--sensing", choices=("ideal", "realistic"), default="ideal", help="(default ideal)")
    for name, (low, high, log) in default_ranges().items():
        limits = GAIN_RANGES[name]  # a negative LOW is beyond every gain's limits
        tune.add_argument(
            f"--{name}-range", metavar="LOW:HIGH",
            help=f"search range ({'log' if log else 'linear'}; default {low:g}:{high:g}; within the gain's limits "
            f"[{limits.low:g}, {limits.high:g}] {limits.unit}; the PID's only)",
        )  # fmt: skip
    tune.add_argument("--gait", action="append", default=[], metavar="NAME=LOW:HIGH", help="also search a gait field")
    tune.add_argument(
        "--controller",
        default="pid",
        metavar="SPEC",
        help="tune this controller's declared params over their ranges instead of the PID's gains (default pid)",
    )
    tune.add_argument(
        "--param-range",
        action="append",
        default=[],
        metavar="NAME=LOW:HIGH",
        help="search one of the --controller's params over this range instead of its declared one (repeatable; "
        "the PID's params are its gains: --kp-range ...)",
    )
    tune.add_argument("--batch", type=int, default=0, help="candidates evaluated together (default: the workers)")
    tune.add_argument(
        "--energy-weight", type=float, default=0.0, metavar="J",
        help="also score the worst episode's electrical energy per hop (wheel and legs, braking not recovered; with "
        "--robust its --quantile over the robots): J joules per hop count as much as a 3.5 deg landing error "
        "(default 0: energy does not count)",
    )  # fmt: skip
    tune.add_argument("--json", type=writable_file, metavar="PATH", help="write the search and its evidence as JSON")
    robust_options(tune)
    add_model_flag(tune)
    executor_options(tune)


def robust_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--robust", type=Path, metavar="SPEC.toml",
        help="tune over robots drawn from SPEC's [model] table (its other keys are ignored): a quantile over them is "
        "the score; the best and the defaults are then judged on --judge-samples robots drawn with --judge-seed",
    )  # fmt: skip
    model_options(p)
    # --objective and --quantile default to None, so that one given without --robust is refused, not ignored.
    p.add_argument("--objective", choices=("landing", "failure"),
                   help="landing: the --quantile of the worst landing error (a failure counts 90 deg); failure: the "
                   "failure probability, ties broken by that quantile (default landing; with --robust)")  # fmt: skip
    p.add_argument("--quantile", type=float,
                   help="the landing error's quantile scored, in (0, 1) (default 0.9; with --robust)")  # fmt: skip
    p.add_argument("--judge-samples", type=int, metavar="N", help="robots the result is judged on (default: SPEC's)")
    p.add_argument("--judge-seed", type=int, metavar="SEED", help="their seed (default: the model's seed + 1)")


def default_ranges() -> dict[str, tuple[float, float, bool]]:
    from hopper.experiments.tune import GAIN_SEARCH

    return GAIN_SEARCH


def model_options(p: argparse.ArgumentParser) -> None:
    """The [model] table's flags (hopper.experiments.uncertainty): they add to a spec file's table."""
    p.add_argument("--samples", type=int, metavar="N", help="robots drawn from the model's distributions")
    p.add_argument("--model-seed", type=int, metavar="SEED", help="the seed they are drawn with")
    p.add_argument(
        "--vary", action="append", default=[], metavar="NAME=uniform|normal:A:B[:relative]",
        help="a sampled parameter, e.g. mass_torso=uniform:0.9:1.1:relative or com_x=normal:0:0.005 (repeatable)",
    )  # fmt: skip


def model_table(args: argparse.Namespace) -> dict[str, Any]:
    """--samples, --model-seed and --vary as a [model] table ({} without them)."""
    from hopper.experiments.spec import SpecError

    table: dict[str, Any] = {}
    if args.samples is not None:
        table["samples"] = args.samples
    if args.model_seed is not None:
        table["seed"] = args.model_seed
    for text in args.vary:
        name, values = _named("vary", text)
        parts = values.split(":")
        if len(parts) not in (3, 4) or (len(parts) == 4 and parts[3] != "relative"):
            raise SpecError(f"--vary {name}: expected uniform|normal:A:B[:relative], got {values!r}")
        table[name] = {parts[0]: [_scalar(parts[1]), _scalar(parts[2])], "relative": len(parts) == 4}
    return table


def executor_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--executor",
        choices=("auto", "local", "ray"),
        default="auto",
        help="auto: Ray for big jobs or with --address/RAY_ADDRESS, local processes otherwise (default auto)",
    )
    p.add_argument(
        "--address",
        help="a Ray cluster's HOST:PORT, or auto for the one `ray start` runs here (default: RAY_ADDRESS, else a new "
        "local Ray)",
    )
    p.add_argument("--workers", type=int, default=None, help="workers (default: all cores of the machine or cluster)")


# -- flags to spec -------------------------------------------------------------------------------


def _scalar(text: str) -> Any:
    for convert in (int, float):
        try:
            return convert(text)
        except ValueError:
            pass
    return text.strip()


def flag_value(name: str, text: str) -> Any:
    """A flag's text in the TOML spec's shape: a scalar, a list (a,b), or a range (a:b:n, seeds a:b)."""
    from hopper.experiments.spec import SpecError

    if ":" in text:
        parts = [_scalar(p) for p in text.split(":")]
        if len(parts) == 2:
            return {"start": parts[0], "stop": parts[1]}
        if len(parts) == 3:
            return {"start": parts[0], "stop": parts[1], "num": parts[2]}
        raise SpecError(f"--{name}: a range is START:STOP:NUM (seeds START:STOP), got {text!r}")
    if "," in text:
        return [_scalar(p) for p in text.split(",") if p.strip()]
    return _scalar(text)


def _disturbance(text: str) -> dict[str, Any]:
    from hopper.experiments.spec import SpecError

    if text.strip() == "none":
        return {"kind": "none"}
    parts = text.split(":")
    if len(parts) not in (4, 5):
        raise SpecError(f"--disturbance: expected none or KIND:SIZES:PHASE:DELAY[:HOP], got {text!r}")
    entry = {"kind": parts[0], "size": flag_value("disturbance", parts[1]), "phase": parts[2]}
    entry["delay"] = _scalar(parts[3])
    if len(parts) == 5:
        entry["hop"] = _scalar(parts[4])
    return entry


def _named(flag: str, text: str) -> tuple[str, str]:
    from hopper.experiments.spec import SpecError

    name, sep, values = text.partition("=")
    if not sep or not name.strip():
        raise SpecError(f"--{flag}: expected NAME=VALUES, got {text!r}")
    return name.strip(), values


def spec_overrides(args: argparse.Namespace) -> dict[str, Any]:
    data: dict[str, Any] = {}
    for name in AXIS_FLAGS:
        text = getattr(args, name)
        if text is not None:
            data[name] = flag_value(name, text)
    if args.gait:
        data["gait"] = {
            name: flag_value(f"gait {name}", values) for name, values in map(lambda t: _named("gait", t), args.gait)
        }
    if args.disturbance:
        data["disturbance"] = [_disturbance(t) for t in args.disturbance]
    if getattr(args, "controller", None):
        data["controller"] = [c.strip() for c in args.controller.split(",") if c.strip()]
    if model_table(args):
        data["model"] = model_table(args)
    if args.model is not None:
        data["mjcf"] = args.model
    if getattr(args, "param", None):
        data["params"] = {
            name: flag_value(f"param {name}", values) for name, values in map(lambda t: _named("param", t), args.param)
        }
    return data


def check_controllers(spec: Any) -> None:  # noqa: ANN401 (hopper.experiments.spec.SweepSpec)
    """Every controller of the sweep builds and flies a probe tick, or one line and exit 2 before any work."""
    from hopper.config import SimConfig

    first = [(name, values[0]) for name, values in spec.params]
    for controller in spec.controller:
        checked_controller(SimConfig(model=spec.mjcf), controller, [] if controller == "pid" else first)


def check_workers(args: argparse.Namespace) -> None:
    """--workers at least 1, and no --address that --executor local would ignore."""
    if args.workers is not None and args.workers < 1:
        fail(f"--workers must be at least 1, got {args.workers}")
    check_executor(args)


# -- commands ------------------------------------------------------------------------------------


def command_sweep(args: argparse.Namespace) -> int:
    from hopper.config import Gains
    from hopper.experiments.spec import GAINS, SpecError, load_spec, parse_spec
    from hopper.experiments.store import SpecMismatch

    check_workers(args)
    try:
        overrides = spec_overrides(args)
        spec = load_spec(args.spec, overrides) if args.spec is not None else parse_spec(overrides)
    except SpecError as exc:
        fail(str(exc))
    default = Gains()  # what the episodes of a controller other than the PID hold (SweepSpec.flown)
    gains = [n for n in GAINS if getattr(args, n) is not None or getattr(spec, n) != (getattr(default, n),)]
    if gains and "pid" not in spec.controller:  # a gain axis that no episode would fly
        flown = "controller " + ", ".join(spec.controller)
        fail(f"{gains[0]} {not_flown(flown, 'sweep its params with --param')}")
    if spec.mjcf is not None:  # a spec file's, checked as --model's
        try:
            model_file(spec.mjcf)
        except argparse.ArgumentTypeError as exc:
            fail(f"mjcf: {exc}")
    check_controllers(spec)

    from hopper.experiments.executor import ExecutorError, choose
    from hopper.experiments.runner import late_stop, run_sweep
    from hopper.experiments.store import DamagedSweep
    from hopper.interrupts import clear, held

    check_sweep_out(args.out)
    # OUT is written to now; the folder made for it is removed again if the executor cannot start.
    with made_out(args.out):
        try:
            run = run_sweep(spec, args.out, lambda todo: choose(args.executor, todo, args.workers, args.address))
        except (SpecMismatch, DamagedSweep, ExecutorError) as exc:
            fail(str(exc))
    # Every episode is written: a stop now would cut nothing short. It waits for the whole summary and
    # is then dropped, so that the status says what the sweep did (0 or 4), not 130.
    status = EXIT_OK
    try:
        with held():
            status = sweep_summary(args.out, spec, run)
    except KeyboardInterrupt:
        clear()
        print(late_stop(args.out), file=sys.stderr)
    return status


def sweep_summary(out: Path, spec: Any, run: Any) -> int:  # noqa: ANN401 (SweepSpec, SweepRun)
    """Print a finished sweep's summary (OUT's episodes of `spec` and this `run`); its exit status."""
    from hopper.experiments.runner import workers
    from hopper.experiments.store import SweepStore
    from hopper.experiments.summary import axis_lines, detail_lines, overall_line

    episodes, others = SweepStore(out, spec).spec_episodes()
    print(f"{out}: {overall_line(episodes)}")
    if others:
        print(f"{out} also holds {others} rows of episodes this spec does not fly (an older version's, whose "
              "other controllers flew every gain point): not counted")  # fmt: skip
    for line in axis_lines(episodes, spec.axes()) + detail_lines(episodes):
        print(line)
    if spec.model is not None and episodes.num_rows:
        from hopper.experiments.montecarlo import summary_lines

        for line in summary_lines(episodes, spec.model.samples, spec.model.seed):
            print(line)
    startup = f" (start-up {run.startup_s:.1f} s, episodes {run.work_s:.1f} s)" if run.startup_s else ""
    if run.ran == 0 and run.skipped == run.total:
        print(f"this run: nothing left to run, all {run.total} episodes were already done")
    else:
        print(
            f"this run: {run.ran} episodes on {run.executor} ({workers(run.workers)}) in {run.wall_s:.1f} s"
            f"{startup}; {run.skipped} were already done"
        )
    return controllers_status(episodes)


def controllers_status(episodes: Any) -> int:  # noqa: ANN401 (a pyarrow Table)
    """EXIT_CONTROLLER, saying which controller failed and why on stderr (as `run` does), if any
    episode's controller faulted and the PID flew on; EXIT_OK otherwise (falls are results)."""
    import numpy as np

    from hopper.experiments.outcome import faults

    causes = faults(episodes)
    if not (causes != "").any():
        return EXIT_OK
    names = np.array(episodes.column("controller").to_pylist(), dtype=object)
    parts = []
    for name in dict.fromkeys(names[causes != ""]):  # each faulting controller, its first cause
        mine = names == name
        hit = mine & (causes != "")
        parts.append(f"controller {name} failed in {hit.sum()} of {mine.sum()} episodes: {causes[hit][0]}")
    why = "; ".join(parts)
    print(f"hopper-sim: error: {why} (the PID flew on; counted failed)", file=sys.stderr)
    return EXIT_CONTROLLER


def check_sweep_out(out: Path) -> None:
    """OUT is new, empty or a sweep's folder (resumed): anything else is refused in one line, before
    any work; a sweep's own episodes/ or hops/ folder names the sweep to resume instead."""
    from hopper.experiments.store import is_sweep_folder

    if out.name in ("episodes", "hops") and (out.parent / "spec.toml").is_file():
        fail(f"--out: {out} is the {out.name}/ dataset of the sweep in {out.parent}: give --out {out.parent} "
             "to resume that sweep, or a new folder")  # fmt: skip
    check_reused(out, is_sweep_folder, "a sweep's folder (no spec.toml)")


def command_tune(args: argparse.Namespace) -> int:
    from hopper.experiments.spec import SpecError, parse_spec
    from hopper.experiments.tune import TuneSetup, report_lines, tune

    check_workers(args)
    for flag, value, least in (("--trials", args.trials, 1), ("--hops", args.hops, 1), ("--batch", args.batch, 0)):
        if value < least:
            fail(f"{flag} must be at least {least}, got {value}")
    check_flown_ranges(args)
    try:
        axes = parse_spec(
            {
                "seeds": flag_value("seeds", args.seeds),
                "gravity": flag_value("gravity", args.gravity),
                "hops": args.hops,
            }
        )
        heldout = parse_spec({"seeds": flag_value("heldout", args.heldout)}).seeds
        ranges = {name: _range(f"{name}-range", getattr(args, f"{name}_range") or f"{low:g}:{high:g}", log)
                  for name, (low, high, log) in default_ranges().items()}  # fmt: skip
        if args.controller != "pid":
            ranges = controller_ranges(args)
        for text in args.gait:
            name, values = _named("gait", text)
            ranges[name] = _range(f"gait {name}", values, False)
        model, judge = robust_models(args)
        setup = TuneSetup(
            seeds=axes.seeds, heldout=heldout, gravities=axes.gravity, hops=args.hops, terrain=args.terrain,
            sensing=args.sensing, ranges=ranges, trials=args.trials, batch=args.batch, seed=args.seed,
            energy_weight=args.energy_weight, controller=args.controller, model=model, judge=judge,
            mjcf=args.model, **{k: getattr(args, k) for k in ("objective", "quantile") if getattr(args, k) is not None},
        )  # fmt: skip
    except (SpecError, ValueError) as exc:
        fail(str(exc))

    from hopper.experiments.executor import ExecutorError, choose

    try:
        result = tune(setup, lambda episodes: choose(args.executor, episodes, args.workers, args.address))
    except ExecutorError as exc:
        fail(str(exc))
    for line in report_lines(setup, result):
        print(line)
    if args.json:
        args.json.write_text(json.dumps(result.as_dict(setup), indent=2))
    return EXIT_OK


def check_flown_ranges(args: argparse.Namespace) -> None:
    """A range given for params the controller does not fly is refused, as sweep refuses such an axis:
    --kp-range and co. are the PID's, --param-range another controller's."""
    gains = [name for name in default_ranges() if getattr(args, f"{name}_range") is not None]
    if gains and args.controller.strip() != "pid":
        flown = f"--controller {args.controller}"
        fail(f"--{gains[0]}-range: {gains[0]} {not_flown(flown, 'search its params with --param-range')}")
    if args.param_range and args.controller.strip() == "pid":
        fail("--param-range searches another --controller's params: the PID's are its gains, searched with "
             "--kp-range, --ki-range and --kd-range")  # fmt: skip


def robust_models(args: argparse.Namespace) -> tuple[Any, Any]:  # (ModelAxis | None, ModelAxis | None)
    """--robust's tuning robots and judging robots (None, None without it)."""
    import tomllib

    from hopper.experiments.spec import SpecError
    from hopper.experiments.uncertainty import UncertaintyError, parse_model

    flags = model_table(args)
    if args.robust is None:
        robust_only = {"--samples": args.samples, "--model-seed": args.model_seed, "--vary": args.vary or None,
                       "--judge-samples": args.judge_samples, "--judge-seed": args.judge_seed,
                       "--objective": args.objective, "--quantile": args.quantile}  # fmt: skip
        given = [flag for flag, value in robust_only.items() if value is not None]
        if given:
            raise SpecError(f"{', '.join(given)} {'needs' if len(given) == 1 else 'need'} --robust SPEC.toml")
        return None, None
    try:
        data = tomllib.loads(args.robust.read_text(encoding="utf-8"))
    except OSError as exc:
        raise SpecError(f"cannot read {args.robust}: {exc.strerror or exc}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise SpecError(f"{args.robust} is not valid TOML: {exc}") from None
    if not isinstance(data.get("model"), dict):
        raise SpecError(f"{args.robust} has no [model] table of distributions")
    if args.judge_samples is not None and args.judge_samples < 1:  # 0 is not "the file's count"
        raise SpecError(f"--judge-samples must be at least 1, got {args.judge_samples}")
    try:  # the tuning robots: the file's [model] table, --samples, --model-seed and --vary over it
        model = parse_model({**data["model"], **flags})
    except UncertaintyError as exc:
        tuning = {"model.samples": ("--samples", args.samples), "model.seed": ("--model-seed", args.model_seed)}
        raise SpecError(_flag_named(str(exc), args.robust, tuning)) from None
    # The judging robots: the same distributions, the file's count (--samples is the tuning's), another seed.
    samples = data["model"].get("samples", model.samples) if args.judge_samples is None else args.judge_samples
    try:
        judge = parse_model({**data["model"], **flags, "samples": samples,
                             "seed": model.seed + 1 if args.judge_seed is None else args.judge_seed})  # fmt: skip
    except UncertaintyError as exc:
        judging = {
            "model.samples": ("--judge-samples", args.judge_samples),
            "model.seed": ("--judge-seed", args.judge_seed),
        }
        raise SpecError(_flag_named(str(exc), args.robust, judging)) from None
    return model, judge


def _flag_named(text: str, spec: Path, flags: dict[str, tuple[str, int | None]]) -> str:
    """A [model] error in the words of what set the value: `flags` maps model.samples and model.seed
    to (flag, its value); a flag given is named, else the value is SPEC's."""
    for key, (flag, given) in flags.items():
        if text.startswith(f"{key}:"):
            return f"{flag}{text[len(key) :]}" if given is not None else f"{spec}: {text}"
    return text


def controller_ranges(args: argparse.Namespace) -> dict[str, tuple[float, float, bool]]:
    """A controller's declared params and ranges (linear), each --param-range in place of its own."""
    from hopper.config import SimConfig
    from hopper.controllers import ControllerError, load_class
    from hopper.controllers.loading import canonical, declared_params

    checked_controller(SimConfig(model=args.model), args.controller)
    args.controller = canonical(args.controller)
    try:
        declared = {p.name: p for p in declared_params(load_class(args.controller))}
    except ControllerError as exc:
        fail(str(exc))
    ranges = {name: (p.range[0], p.range[1], False) for name, p in declared.items()}
    for text in args.param_range:
        name, values = _named("param-range", text)
        if name not in declared:
            known = ", ".join(declared) or "none"
            fail(f"--param-range: {args.controller} declares no param {name!r} (its params: {known})")
        ranges[name] = _range(f"param-range {name}", values, False)
    if not ranges:
        fail(f"{args.controller} declares no params to tune")
    return ranges


def _range(name: str, text: str, log: bool) -> tuple[float, float, bool]:
    from hopper.experiments.spec import SpecError

    low, sep, high = text.partition(":")
    try:
        lo, hi = float(low), float(high)
    except ValueError:
        raise SpecError(f"--{name}: expected LOW:HIGH, got {text!r}") from None
    if not sep or not lo < hi or (log and lo <= 0):
        raise SpecError(f"--{name}: expected LOW:HIGH with LOW < HIGH{' and LOW > 0' if log else ''}, got {text!r}")
    return lo, hi, log


COMMANDS = {"sweep": command_sweep, "tune": command_tune}


def run(args: argparse.Namespace) -> int:
    return COMMANDS[args.command](args)


if __name__ == "__main__":
    sys.exit("run it as hopper-sim sweep|tune")
