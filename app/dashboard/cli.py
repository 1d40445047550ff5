"""`hopper-dashboard`: serve the live dashboard; bad arguments give one line on stderr and exit 2."""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

from hopper.app import cli_common
from hopper.app.cli_common import (
    CLOSED_STDOUT_STATUS,
    EXIT_CLOSED_STDOUT,
    add_controller_flags,
    add_model_flag,
    capped,
    gravity,
    output_closed,
    seed,
)
from hopper.app.dashboard.config import LIGHTING, DashboardConfig, check_sessions_dir
from hopper.app.dashboard.pacing import MAX

from hopper.config import GAIN_RANGES, GRAVITY_PRESETS
from hopper.controllers import ControllerError
from hopper.interrupts import raise_if_stop_requested, stop_like_ctrl_c

if TYPE_CHECKING:
    from hopper.app.dashboard.server import Dashboard

PROG = "hopper-dashboard"
DEFAULTS = DashboardConfig()
EXIT_STATUSES = (
    "exit status: 0 stopped by Ctrl-C or SIGTERM (any recording closed, the port freed), 2 bad arguments, "
    f"a port in use or an --rrd or --sessions-dir that cannot be written, {CLOSED_STDOUT_STATUS} (the server "
    "stopped as on Ctrl-C)."
)


class Parser(cli_common.Parser):
    """hopper-sim's parser (no abbreviated flags: `--sess DIR` is refused, not taken for
    --sessions-dir) with this program's prefix: `hopper-dashboard: error: ...`."""

    def error(self, message: str) -> NoReturn:
        fail(message)


class Help(argparse.ArgumentDefaultsHelpFormatter):
    """Defaults shown after each help text, except where there is none (e.g. no --rrd)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        return action.help if action.default is None else super()._get_help_string(action)


def choice(*options: str) -> Callable[[str], str]:
    """An argparse type accepting only `options` (argparse's own `choices` wording differs by version)."""

    def check(text: str) -> str:
        if text not in options:
            raise argparse.ArgumentTypeError(f"invalid choice {text!r} (choose from {', '.join(options)})")
        return text

    return check


def speed(text: str) -> float:
    """An argparse type: a speed (x real time), or 'max' for MAX (the range is DashboardConfig's check)."""
    if text.strip().lower() == "max":
        return MAX
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid speed {text!r} (a number, x real time, or max)") from None


def parser() -> Parser:
    """The flags of DashboardConfig, one each, with units and defaults in the help."""
    p = Parser(prog=PROG, description=DashboardConfig.__doc__, epilog=EXIT_STATUSES, formatter_class=Help)
    p.add_argument("--host", default=DEFAULTS.host, help="address to serve on (loopback by default)")
    p.add_argument("--port", type=int, default=DEFAULTS.port, help="TCP port to serve on; refused if in use")
    p.add_argument("--seed", type=seed, default=DEFAULTS.seed, help="terrain seed, a non-negative integer below 2^64")
    p.add_argument(
        "--terrain", type=choice("crater", "flat"), default=DEFAULTS.terrain, metavar="{crater,flat}", help="terrain"
    )
    p.add_argument(
        "--sensing",
        type=choice("ideal", "realistic"),
        default=DEFAULTS.sensing,
        metavar="{ideal,realistic}",
        help="what the controller reads: the true pitch, or a simulated IMU's estimate (noise, bias, delay)",
    )
    p.add_argument(
        "--gravity",
        type=gravity,  # hopper-sim's (a name or m/s^2); DashboardConfig takes a preset's only
        default="moon",  # a name, as typed: argparse passes a string default through the type
        metavar="{" + ",".join(GRAVITY_PRESETS) + "}",
        help="the gravity at start, by its preset's name (the Gravity control's)",
    )
    for name, what in (("kp", "proportional"), ("ki", "integral"), ("kd", "derivative")):
        low, high, unit = GAIN_RANGES[name]
        p.add_argument(
            f"--{name}",
            type=float,
            default=getattr(DEFAULTS, name),
            help=f"wheel PID {what} gain in [{low:g}, {high:g}] {unit}",
        )
    p.add_argument(
        "--speed",
        type=speed,
        default=DEFAULTS.speed,
        metavar="X|max",
        help="simulation speed: max (as fast as the machine allows) or x real time",
    )
    p.add_argument(
        "--rrd", type=Path, default=DEFAULTS.rrd, metavar="PATH", help="record the whole session to this .rrd file"
    )
    p.add_argument(
        "--rerun-viewer",
        type=choice("spawn", "serve", "off"),
        default=DEFAULTS.rerun_viewer,
        metavar="{spawn,serve,off}",
        help="stream the recording to a rerun viewer: spawn one, serve one on loopback, or neither",
    )
    p.add_argument(
        "--sessions-dir",
        type=Path,
        default=DEFAULTS.sessions_dir,
        metavar="DIR",
        help="folder for recordings started with the Record button",
    )
    p.add_argument(
        "--token",
        default=DEFAULTS.token,
        metavar="TOKEN|auto",
        help="access token every client must present (required off loopback); 'auto' prints a new one in the URL",
    )
    p.add_argument(
        "--public-view", action="store_true", help="clients without the token may watch, read-only, instead of no data"
    )
    p.add_argument(
        "--idle-timeout",
        type=float,
        default=DEFAULTS.idle_timeout,
        metavar="S",
        help="s without input after which the operator's control passes to the next viewer",
    )
    p.add_argument(
        "--rrd-max-mb",
        type=float,
        metavar="MB",
        help="roll recordings over into numbered parts (name-001.rrd, ...) of about this many MB",
    )
    p.add_argument(
        "--rrd-max-min",
        type=float,
        metavar="MIN",
        help="roll recordings over into numbered parts of this many minutes of simulation",
    )
    p.add_argument(
        "--rrd-flush-s",
        type=float,
        default=DEFAULTS.rrd_flush_s,
        metavar="S",
        help="wall seconds between recording flushes: the most a killed server loses",
    )
    p.add_argument(
        "--lighting",
        type=choice(*LIGHTING),
        default=DEFAULTS.lighting,
        metavar="{" + ",".join(LIGHTING) + "}",
        help="the scene's lighting; simple (no environment light, no shadows) for browsers without a GPU",
    )
    add_controller_flags(p)
    add_model_flag(p)
    p.add_argument(
        "--controller-choice",
        action="append",
        default=[],
        metavar="SPEC",
        help="another controller the Gains tab offers (repeatable; the built-ins always are)",
    )
    return p


def parse(args: Sequence[str] | None = None) -> DashboardConfig:
    """Parse and validate; raises SystemExit(2) after printing one line for bad arguments."""
    namespace = parser().parse_args(args)
    namespace.controller_param = tuple(namespace.controller_param)
    namespace.controller_choice = tuple(namespace.controller_choice)
    try:
        return DashboardConfig(**vars(namespace))
    except (ValueError, ControllerError) as exc:  # DashboardConfig's own validation (InvalidConfig is a ValueError)
        fail(str(exc))


def fail(message: str, code: int = 2) -> NoReturn:
    print(f"{PROG}: error: {message}", file=sys.stderr)
    raise SystemExit(code)


def open_dashboard(config: DashboardConfig) -> Dashboard:
    """The dashboard, built but not started; one line and exit 2 for what the arguments cannot give."""
    # Import here: --help and argument errors stay fast (no MuJoCo, no viser).
    from hopper.app.dashboard.recording import telemetry_module
    from hopper.app.dashboard.server import Dashboard, PortInUse

    try:
        if config.rrd is not None:
            telemetry_module().check_writable(config.rrd)
        check_sessions_dir(config.sessions_dir)
        return Dashboard(config, verbose=False)
    except (PortInUse, ValueError, ControllerError) as exc:
        fail(str(exc))
    except RuntimeError as exc:  # e.g. the rerun viewer asked for cannot start
        fail(f"{type(exc).__name__}: {exc}")


def serve(dashboard: Dashboard) -> int:
    """Run until Ctrl-C or SIGTERM (both raise KeyboardInterrupt), then stop: recording closed, port freed.

    0, or EXIT_CLOSED_STDOUT if the reader of stdout went away (`| head -1`): the server stops then too."""
    try:
        raise_if_stop_requested()  # a signal during start-up may have been swallowed (hopper/interrupts.py)
        dashboard.start()
        # The token's one appearance: this line on stdout, for whoever started the server.
        print(f"{PROG}: serving {dashboard.page_url}  (Ctrl-C to stop)", flush=True)
        note = capped(dashboard.sim.config, dashboard.sim.robot)  # it stumbles where its legs are too weak
        if note is not None:
            print(f"{PROG}: {note}", flush=True)
        if dashboard.recorder.path is not None:
            print(f"{PROG}: recording to {dashboard.recorder.path}", flush=True)
        if dashboard.recorder.viewer_url:
            print(f"{PROG}: rerun viewer at {dashboard.recorder.viewer_url}", flush=True)
        dashboard.wait()
    except BrokenPipeError:
        # Decided before stop(): viser then prints "Server stopped" (with rich) to /dev/null, where
        # it would otherwise meet the closed pipe itself and point stdout there first.
        if not output_closed():
            raise
        return EXIT_CLOSED_STDOUT
    finally:
        _stop(dashboard)
    return 0


def _stop(dashboard: Dashboard) -> None:
    """dashboard.stop(), again if a second stop signal came before it held the rest (stop is idempotent
    and holds signals once it has begun): the first one's KeyboardInterrupt goes on, the second is spent."""
    while True:
        try:
            dashboard.stop()
            return
        except KeyboardInterrupt:
            continue


def main(args: Sequence[str] | None = None) -> int:
    """Exit 0 when stopped by Ctrl-C or SIGTERM, the usual way to stop a server; 2 for bad arguments;
    141 once the reader of stdout has gone (the server stopped first, as on Ctrl-C)."""
    stop_like_ctrl_c()
    config = parse(args)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    logging.getLogger("websockets").setLevel(logging.WARNING)  # one line per connection is noise
    status = 0
    try:
        with contextlib.suppress(KeyboardInterrupt):  # a signal during start-up unwinds Dashboard's own clean-up
            status = serve(open_dashboard(config))
        print(f"{PROG}: stopped", flush=True)  # to /dev/null if serve found stdout closed
    except BrokenPipeError:  # this last line's reader went away
        if not output_closed():
            raise
        return EXIT_CLOSED_STDOUT
    except SystemExit as exc:
        if not banner_found_output_closed(exc):
            raise
        return EXIT_CLOSED_STDOUT
    return status


def banner_found_output_closed(exc: SystemExit) -> bool:
    """viser prints its banner with rich, whose Console.on_broken_pipe (documented, Python's recipe)
    points stdout at /dev/null and raises SystemExit(1) once stdout's reader has gone: True for that
    exit. The Dashboard being built has closed its recording on the way out; the process ends, its
    port with it. (No other SystemExit(1) comes out of serve: this module's own refusals exit 2.)"""
    if exc.code != 1:
        return False
    try:
        return os.path.samestat(os.fstat(sys.stdout.fileno()), os.stat(os.devnull))
    except (OSError, ValueError):
        return False


if __name__ == "__main__":
    sys.exit(main())
