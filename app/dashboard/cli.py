"""`hopper-dashboard`: serve the live dashboard; bad arguments give one line on stderr and exit 2."""

from __future__ import annotations

import contextlib
import io
import logging
import re
import signal
import sys
from collections.abc import Sequence

import tyro
from hopper.app.dashboard.config import DashboardConfig

PROG = "hopper-dashboard"
_BOX = re.compile(r"[│╭╮╰╯─]+")


def _one_line(tyro_output: str) -> str:
    """tyro's boxed error as one line: the box's text up to its first rule."""
    lines = []
    for raw in tyro_output.splitlines()[1:]:  # the first line is the box title
        if "───" in raw or raw.startswith("╰"):
            break
        text = _BOX.sub(" ", raw).strip()
        if text:
            lines.append(text)
    message = " ".join(lines) or "invalid arguments (see --help)"
    return re.sub(r"^Error parsing DashboardConfig: ", "", message)


def parse(args: Sequence[str] | None = None) -> DashboardConfig:
    """Parse and validate; raises SystemExit(2) after printing one line for bad arguments."""
    captured = io.StringIO()
    try:
        with contextlib.redirect_stderr(captured):
            return tyro.cli(DashboardConfig, prog=PROG, args=args)
    except SystemExit as exc:
        if exc.code not in (0, None):
            fail(_one_line(captured.getvalue()))
        sys.stderr.write(captured.getvalue())
        raise
    except ValueError as exc:  # DashboardConfig's own validation (InvalidConfig is a ValueError)
        fail(str(exc))


def fail(message: str, code: int = 2) -> None:
    print(f"{PROG}: error: {message}", file=sys.stderr)
    raise SystemExit(code)


def main(args: Sequence[str] | None = None) -> None:
    config = parse(args)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    logging.getLogger("websockets").setLevel(logging.WARNING)  # one line per connection is noise
    # Import after parsing: --help and argument errors stay fast (no MuJoCo, no viser).
    from hopper.app.dashboard.recording import telemetry_module
    from hopper.app.dashboard.server import Dashboard, PortInUse

    try:
        if config.rrd is not None:
            telemetry_module().check_writable(config.rrd)
        dashboard = Dashboard(config, verbose=False)
    except (PortInUse, ValueError) as exc:
        fail(str(exc))
    except RuntimeError as exc:  # e.g. the rerun viewer asked for cannot start
        fail(f"{type(exc).__name__}: {exc}")

    def on_signal(signum: int, _frame: object) -> None:
        dashboard.stop()

    # Both stop the same way, even where SIGINT arrives ignored (e.g. a background job of a script).
    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    try:
        dashboard.start()
        print(f"{PROG}: serving {dashboard.url}  (Ctrl-C to stop)", flush=True)
        if dashboard.recorder.path is not None:
            print(f"{PROG}: recording to {dashboard.recorder.path}", flush=True)
        if dashboard.recorder.viewer_url:
            print(f"{PROG}: rerun viewer at {dashboard.recorder.viewer_url}", flush=True)
        dashboard.wait()
    except KeyboardInterrupt:
        pass
    finally:
        dashboard.stop()
        print(f"{PROG}: stopped", flush=True)


if __name__ == "__main__":
    main()
