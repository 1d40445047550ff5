"""What hopper-sim's commands share: exit statuses, one-line errors, argument types, the run flags.

Imported by hopper.app.sim_cli and by the commands it delegates to (report_cli, sweep_cli); it
imports none of them, so hopper-sim's modules form no import cycle.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import select
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

from hopper.config import GRAVITY_PRESETS, Gains, InvalidConfig, SimConfig, check_seed
from hopper.scenarios import SCENARIOS
from hopper.schedule import KickSchedule, parse

if TYPE_CHECKING:
    from hopper.robot import Robot

EXIT_OK, EXIT_FELL, EXIT_USAGE, EXIT_SHORT, EXIT_CONTROLLER, EXIT_INTERRUPTED = 0, 1, 2, 3, 4, 130
EXIT_CLOSED_STDOUT = 141  # 128 + SIGPIPE: what a shell reports for a tool a closed pipe ended
# Every command's exit-status text says it in these words (hopper-dashboard's too).
CLOSED_STDOUT_STATUS = "141 the reader of its output went away (e.g. | head): it stops quietly, as Unix tools do"
EXIT_STATUSES = (
    "exit status: 0 success, 1 the robot fell (run), a case failed (stress) or a kick under the physical limit "
    "fell (envelope), 2 bad arguments (a controller that cannot fly included), 3 the run stopped short of the "
    "hops asked without a fall (run; it says why), 4 the controller failed mid-run and the PID flew on (run, and "
    "compare, league or sweep once finished; it says why), 130 interrupted (Ctrl-C or SIGTERM; for compare, league, "
    "stress and envelope, before their last result was in: a later stop lets them finish), "
    f"{CLOSED_STDOUT_STATUS}. compare exits 0 once it has finished without a controller fault: with the wheel off "
    "the robot is expected to fall."
)


class Parser(argparse.ArgumentParser):
    """argparse with errors on one line (no usage dump) and one prefix, subcommands included, and no
    abbreviated flags: `compare --seed 1` would silently mean `--seeds 1`. Every subcommand is built
    with this class (add_subparsers' parser_class), so allow_abbrev=False reaches each of them.
    `name` is the errors' prefix: hopper-sim's unless another program says its own."""

    def __init__(self, *args: object, allow_abbrev: bool = False, name: str = "hopper-sim", **kwargs: object) -> None:
        super().__init__(*args, allow_abbrev=allow_abbrev, **kwargs)  # type: ignore[arg-type]
        self.name = name

    def error(self, message: str) -> NoReturn:
        fail(message, self.name)


def fail(message: str, name: str = "hopper-sim") -> NoReturn:
    print(f"{name}: error: {message}", file=sys.stderr)
    raise SystemExit(EXIT_USAGE)


def output_closed() -> bool:
    """Called on a BrokenPipeError: True if the reader of stdout (or stderr) went away, as in
    `hopper-sim run | head -1` (or `2>&1 | head -1`).

    The streams it went from then point at /dev/null, so that the interpreter's final flush of what
    is still buffered raises no second time (Python's signal docs, "Note on SIGPIPE"); the caller
    exits EXIT_CLOSED_STDOUT without a traceback. False for any other pipe or socket (a tcp://
    controller's, a worker's): that error is a fault to show, not a reader gone.
    """
    gone = [stream for stream in (sys.stdout, sys.stderr) if _reader_gone(stream)]
    if not gone:
        return False
    devnull = os.open(os.devnull, os.O_WRONLY)
    for stream in gone:
        os.dup2(devnull, stream.fileno())
    os.close(devnull)
    return True


def _reader_gone(stream: object) -> bool:
    """The pipe or socket `stream` writes to has no reader left: its buffered bytes cannot be
    flushed (EPIPE), or, with nothing buffered, the kernel reports an error on it (poll's POLLERR,
    which Linux and the BSDs set on a pipe without readers)."""
    try:
        stream.flush()  # type: ignore[attr-defined]
    except BrokenPipeError:
        return True
    except (OSError, ValueError, AttributeError):  # closed, or no stream at all
        return False
    try:
        poller = select.poll()
        poller.register(stream.fileno(), select.POLLOUT)  # type: ignore[attr-defined]
        return any(event & select.POLLERR for _, event in poller.poll(0))
    except (OSError, ValueError, AttributeError):  # no file descriptor (a test's captured stream), no poll
        return False


def missing_folder(path: Path) -> str | None:
    """Why the output `path` cannot be made: the folder it would be made in is missing or is no
    folder; None if that folder exists. Every output path of hopper-sim's commands, a file's or a
    folder's, is made in a folder that exists: a mistyped parent is refused, never created."""
    folder = path.parent
    if folder.is_dir():
        return None
    return f"{folder} is not a folder" if folder.exists() else f"folder {folder} does not exist"


def writable_file(text: str) -> Path:
    """An output path that can really be written (checked before any simulation).

    It is opened for appending, as hopper.telemetry.check_writable does for .rrd: permission bits
    say little for root, /proc, read-only mounts or ACLs. A file that did not exist is removed again.
    """
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a directory")
    missing = missing_folder(path)
    if missing:
        raise argparse.ArgumentTypeError(missing)
    existed = path.exists()
    try:
        with open(path, "ab"):
            pass
    except OSError as exc:
        raise argparse.ArgumentTypeError(f"cannot write {text}: {exc.strerror or exc}") from None
    if not existed:
        path.unlink(missing_ok=True)
    return path


def mjcf_out(text: str) -> Path:
    """writable_file for an MJCF the command writes: its name must end in .xml, as --model then reads it."""
    from hopper.model import MJCF_SUFFIX

    if Path(text).suffix != MJCF_SUFFIX:
        raise argparse.ArgumentTypeError(
            f"{text}: an MJCF file is read back (--model) only if its name ends in {MJCF_SUFFIX}: give such a path"
        )
    return writable_file(text)


def same_file(a: Path | str, b: Path | str) -> bool:
    """`a` and `b` name one file: the same resolved path (symlinks, ./x and x), or, both there, the
    same inode (a hard link)."""
    a, b = Path(a), Path(b)
    if a.resolve() == b.resolve():
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:  # either is not there
        return False


WRITE_PROBE = ".hopper-write-test"  # written and removed again: a folder proven writable


def make_writable_folder(path: Path) -> None:
    """Make the folder `path` (its parent must exist) and write in it; OSError if that cannot be done.

    Written to, not judged by its permission bits, which say little for root, /proc or a read-only mount.
    """
    path.mkdir(exist_ok=True)
    probe = path / WRITE_PROBE
    probe.write_bytes(b"")
    probe.unlink()


def check_out(out: Path, flag: str = "--out") -> list[Path]:
    """OUT is a folder, or can be made one in a folder that exists (missing_folder: as a file's path
    must be), that can be written: made and written to now, before any work; one line and exit 2
    otherwise. Returns the folders it made (OUT, or none; see made_out)."""
    missing = missing_folder(out)
    if missing:
        fail(f"{flag}: {missing}")
    if out.exists() and not out.is_dir():
        fail(f"{flag}: {out} is not a folder")
    made = [] if out.exists() else [out]
    try:  # written to, not judged by permission bits (root, /proc, read-only mounts)
        make_writable_folder(out)
    except OSError as exc:
        remove_empty(made)
        fail(f"{flag}: cannot write to {out}: {exc.strerror or exc}")
    return made


def check_reused(out: Path, ours: Callable[[Path], bool], what: str, flag: str = "--out") -> None:
    """An OUT that exists and holds anything must be `what` (`ours(OUT)` says so): a command never
    writes into, nor replaces, a folder of something else. One line and exit 2 otherwise, before any
    work, saying what OUT holds."""
    names = entries(out) if out.is_dir() else []
    if names and not ours(out):
        fail(f"{flag}: {out} holds {held_text(names)}, and is not {what}: give a new or empty folder")


def check_replaced(out: Path, ours: Callable[[Path], bool], what: str, noun: str, flag: str = "--out") -> None:
    """check_reused for a command that replaces OUT whole (staged_out): OUT is also refused if it is
    the folder the command runs in, as replaced it would leave the shell in a removed folder. `noun`
    names what replaces it ("a report")."""
    check_reused(out, ours, what, flag)
    if out.exists() and same_file(out, Path.cwd()):
        fail(f"{flag}: {out} is the folder this command runs in, which {noun} replaces whole: give another")


@contextlib.contextmanager
def staged_out(out: Path, flag: str = "--out") -> Iterator[Path]:
    """made_out(OUT), then a hidden folder beside OUT to write into (hopper.report.folder.staged) that
    takes OUT's place whole as the block ends: stopped before, OUT is as it was. One line and exit 2
    if that folder cannot be made (the folder holding OUT is not writable)."""
    from hopper.report.folder import staged

    with made_out(out, flag), contextlib.ExitStack() as stack:
        try:
            partial = stack.enter_context(staged(out))
        except OSError as exc:
            fail(f"{flag}: cannot write beside {out}: {exc.strerror or exc}")
        yield partial


def entries(folder: Path) -> list[str]:
    """The names in `folder`, sorted, a folder's with a trailing /, the write probe left out."""
    names = (p.name + ("/" if p.is_dir() else "") for p in folder.iterdir() if p.name != WRITE_PROBE)
    return sorted(names)


def held_text(names: list[str], shown: int = 4) -> str:
    """'a, b and c', or the first `shown` names and how many more."""
    if len(names) > shown:
        return f"{', '.join(names[:shown])} and {len(names) - shown} more"
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"


@contextlib.contextmanager
def made_out(out: Path | None, flag: str = "--out") -> Iterator[None]:
    """check_out(OUT) (nothing without one); if the block then stops on an exception (a check that
    refuses, Ctrl-C), the folder check_out made is removed again if still empty: a refused command
    leaves no empty folder behind, and never removes one it did not make or that holds anything."""
    made = check_out(out, flag) if out is not None else []
    try:
        yield
    except BaseException:
        remove_empty(made)
        raise


def remove_empty(folders: list[Path]) -> None:
    """Remove each of `folders` (innermost first) while they are empty; stop at the first that is not."""
    for folder in folders:
        try:
            folder.rmdir()  # refuses a folder that holds anything
        except OSError:
            return


def seed(text: str) -> int:
    """A seed, in SimConfig's bounds (hopper.config.check_seed), in its words."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid int value: {text!r}") from None
    try:
        return check_seed(value)
    except InvalidConfig as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def at_least(low: int) -> Callable[[str], int]:
    """An argparse type: an integer of at least `low` (argparse's int takes 0 and negatives)."""

    def check(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"invalid int value: {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be at least {low}, got {value}")
        return value

    return check


def rrd_file(text: str) -> Path:
    """A .rrd path that can really be written (hopper.telemetry.check_writable opens it)."""
    from hopper.telemetry import check_writable

    try:
        return check_writable(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def part_limit(low: float, unit: str) -> Callable[[str], float]:
    """A finite rollover limit of at least `low` (a part must hold the ~1.1 MB scene)."""

    def check(text: str) -> float:
        value = finite(text)
        if value < low:
            raise argparse.ArgumentTypeError(f"must be at least {low:g} {unit}, got {text}")
        return value

    return check


def finite(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text} is not a finite number")
    return value


def gravity(text: str) -> float:
    """A number in m/s^2 or a preset name (moon, mars, ceres, earth)."""
    if text.lower() in GRAVITY_PRESETS:
        return GRAVITY_PRESETS[text.lower()]
    try:
        return finite(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is neither m/s^2 nor one of {', '.join(GRAVITY_PRESETS)}") from None


def schedule(text: str) -> KickSchedule:
    """A repeatable test's kick, KIND:MAGNITUDE[@DELAYms][,every:N] (hopper.schedule.parse)."""
    try:
        return parse(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def controller_param(text: str) -> tuple[str, float]:
    """NAME=VALUE, a controller's declared param (hopper.controllers.Param)."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    try:
        return name.strip(), finite(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{name.strip()}: {value!r} is not a finite number") from None


def model_file(text: str) -> str:
    """A user's MJCF of the robot (--model), loaded and checked now (its names, hopper.robot's
    assumptions): its absolute path, so that workers started elsewhere find it."""
    from hopper.errors import ModelError
    from hopper.model import robot_of

    path = str(Path(text).expanduser().absolute())
    try:
        robot_of(SimConfig(model=path, terrain="flat"))
    except ModelError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return path


def add_model_flag(p: argparse.ArgumentParser) -> None:
    """--model, as every command that flies the robot takes it (README: Your own model)."""
    p.add_argument(
        "--model",
        type=model_file,
        metavar="PATH.xml",
        help="fly your own MJCF of the robot, its constants read from it (README: Your own model; default the "
        "packaged models/hopper.xml)",
    )


def add_controller_flags(p: argparse.ArgumentParser) -> None:
    """--controller and --controller-param, as every command that flies the robot takes them."""
    p.add_argument(
        "--controller",
        default="pid",
        metavar="SPEC",
        help="the flight's wheel law: pid (default), lqr, mpc, policy, policy:WEIGHTS.json (trained weights), "
        "FILE.py:Class, package.module:Class, an entry point of the hopper.controllers group, or "
        "tcp://127.0.0.1:PORT (README: Bring your own controller, Learned control)",
    )
    p.add_argument(
        "--controller-param",
        type=controller_param,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="set one of the controller's declared params (repeatable; for pid: kp, ki, kd)",
    )


def checked_controller(config: SimConfig, spec: str, values: object = ()) -> SimConfig:
    """`config` flying `spec` with param `values`, checked as a run would start it: one line and exit 2
    if it cannot fly (a missing file, a wrong signature, an exception, NaN, a call over budget)."""
    from hopper.controllers import ControllerError, with_controller
    from hopper.sim import Simulation

    try:
        config = with_controller(config, spec, values)  # type: ignore[arg-type]
        Simulation(config)  # builds, configures and probes the controller
    except ControllerError as exc:
        fail(str(exc))
    return config


def with_controller_flags(config: SimConfig, args: argparse.Namespace) -> SimConfig:
    """`config` flying the flags' controller (--controller, --controller-param), checked; a param
    given twice is refused, not the last one taken."""
    names = [name for name, _ in args.controller_param]
    twice = sorted({name for name in names if names.count(name) > 1})
    if twice:
        fail(f"--controller-param {', '.join(twice)} given more than once: give each param once")
    return checked_controller(config, args.controller, args.controller_param)


def not_flown(controllers: str, remedy: str) -> str:
    """The refusal of a PID gain (or its range) given where `controllers` fly no PID, after the gain's name."""
    return f"is the PID's gain, which {controllers} does not fly: {remedy}"


def gains_flags(args: argparse.Namespace) -> Gains:
    """--kp, --ki, --kd (each None unless given) as the PID's gains, the defaults for those not given.

    One line and exit 2 if a given gain would be ignored: another --controller flies no PID, and
    --controller-param kp=... sets the same gain."""
    given = [name for name in ("kp", "ki", "kd") if getattr(args, name) is not None]
    if given and args.controller.strip() != "pid":
        fail(f"--{given[0]} {not_flown(f'--controller {args.controller}', 'set its params with --controller-param')}")
    both = [name for name in given if name in {n for n, _ in args.controller_param}]
    if both:
        fail(f"--{both[0]} and --controller-param {both[0]}=... both set {both[0]}: give one")
    return Gains(**{name: getattr(args, name) for name in given})


def check_executor(args: argparse.Namespace) -> None:
    """--address names a Ray cluster: refused with --executor local, which would not use it, and, as
    any other executor joins it (or RAY_ADDRESS's), refused now if no Ray head answers there."""
    if args.executor == "local" and args.address:
        fail("--address names a Ray cluster, which --executor local does not use: drop one of them")
    if args.executor != "local":
        from hopper.experiments.executor import ExecutorError, check_address

        try:
            check_address(args.address)
        except ExecutorError as exc:
            fail(str(exc))


def run_all(
    episodes: list,
    executor_kind: str,
    workers: int,
    address: str | None,
    desc: str,
    finish: Callable[[dict], int],
    command: str,
    noun: str = "episode",
) -> int:
    """Every episode on the chosen executor with a progress bar (`desc`), then `finish(done)` (done:
    episode_id -> EpisodeResult), which prints and writes what `command` makes of them: its exit
    status. `noun` names one episode where the command's own word differs ("run" for compare).
    A stop that comes once every result is in cuts nothing short (finish_complete)."""
    from tqdm import tqdm

    from hopper.experiments.executor import ExecutorError, choose, chunks

    try:
        executor = choose(executor_kind, episodes, workers, address)  # type: ignore[arg-type]
    except ExecutorError as exc:
        fail(str(exc))
    why = getattr(executor, "why", "")  # InProcess's: why not the workers asked for
    if why:
        n = len(episodes)
        print(f"running {n} {noun}{'s' if n != 1 else ''} in this process: {why}", file=sys.stderr)
    done = {}

    def gather() -> None:
        try:
            with tqdm(total=len(episodes), desc=desc, unit="ep", file=sys.stderr) as bar:
                for chunk in executor.map(chunks(episodes, executor.workers)):
                    done.update((r.episode.episode_id, r) for r in chunk)
                    bar.update(len(chunk))
        finally:
            executor.close()

    return finish_complete(gather, lambda: len(done) == len(episodes), lambda: finish(done), command, noun)


def finish_complete(
    gather: Callable[[], None], complete: Callable[[], bool], finish: Callable[[], int], command: str, noun: str
) -> int:
    """`gather()` the results, then `finish()` (the command's table, its files): finish's exit status.

    A stop (Ctrl-C, SIGTERM: KeyboardInterrupt) while gathering interrupts the command (130) unless
    `complete()`, every result in: then, like one that comes while finish runs (held until it ends),
    it cut nothing short. It is dropped, said in a line, and the command ends as a complete one, with
    its table and its status (0, or 1 or 4 on what it found), as `hopper-sim sweep` does; so does a
    second stop that comes while that finish runs."""
    from hopper.interrupts import clear, held

    status = None
    try:
        gather()
        with held():
            status = finish()
    except KeyboardInterrupt:
        if not complete():
            raise
        try:
            with held():  # another stop, held until the command is finished: it cuts nothing short either
                clear()
                print(late_stop(command, noun), file=sys.stderr)
                if status is None:  # it came before finish: the results are all in, so finish them
                    status = finish()
        except KeyboardInterrupt:
            if status is None:
                raise
            clear()
    return status


def late_stop(command: str, noun: str) -> str:
    """What a stop signal that came after `command` had every result did: nothing."""
    return f"hopper-sim: the stop came after every {noun} was done: {command} is complete"


def add_run_flags(p: argparse.ArgumentParser) -> None:
    """The flags of one simulated robot (terrain, gravity, gains, sensing, gait), as run and compare take them."""
    defaults = Gains()  # the flags' defaults are None, to tell a gain given from one left (gains_flags)
    p.add_argument("--hops", type=int, default=7, help="hops to complete (default 7)")
    p.add_argument(
        "--terrain",
        choices=("crater", "flat"),
        default="crater",
        help="the crater field or flat ground (default crater)",
    )
    p.add_argument(
        "--gravity",
        type=gravity,
        default=GRAVITY_PRESETS["moon"],
        help="m/s^2 or moon|mars|ceres|earth (default moon, 1.625)",
    )
    p.add_argument("--kp", type=finite, help=f"the PID's, N m/rad (default {defaults.kp:g})")
    p.add_argument("--ki", type=finite, help=f"the PID's, N m/(rad s) (default {defaults.ki:g})")
    p.add_argument("--kd", type=finite, help=f"the PID's, N m s/rad (default {defaults.kd:g})")
    add_controller_flags(p)
    add_model_flag(p)
    p.add_argument(
        "--sensing",
        choices=("ideal", "realistic"),
        default="ideal",
        help="what the controller reads: the true pitch, or a simulated IMU's estimate (default ideal)",
    )
    p.add_argument("--json", type=writable_file, metavar="PATH", help="write the results as JSON")
    p.add_argument(
        "--scenario",
        choices=tuple(SCENARIOS),
        default="default",
        help="gait preset: default, or paper (the paper's backward leg sweep in flight; hopper/scenarios.py)",
    )


def capped(config: SimConfig, robot: Robot | None = None) -> str | None:
    """A note when the flown robot (`config`'s, or `robot` if it is known) has legs that cap the hop
    at `config`'s gravity (it is sized for less), naming the command that sizes it; None otherwise."""
    from hopper.control.gait import legs_cap  # numba's import, not paid by --help
    from hopper.model import robot_of

    robot = robot or robot_of(config)
    cap = legs_cap(config.gravity, config.gait, robot)
    if cap is None:
        return None
    return (
        f"note: at {config.gravity:g} m/s^2 this robot's {robot.leg_torque_limit:g} N m legs cap the hop at "
        f"{cap[0]:.2f} m of the {cap[1]:g} m asked; `hopper-sim size --gravity {config.gravity:g} --out FILE` "
        "writes it sized for this gravity, for --model (README: A robot sized for another gravity)"
    )
