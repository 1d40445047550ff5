"""`hopper-sim log check FILE` and `hopper-sim log export IN OUT`: a robot's log against the schema.

check reads FILE (.csv, .mcap, .npz or our own .rrd) and prints what the schema check found: its
samples, duration, rate, gaps, and the columns present and missing; a refused file is one line
on stderr and exit 2. export reads IN the same way and writes it as OUT's suffix says (.csv,
.mcap, .npz): our own .rrd exported to MCAP, for example.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from hopper.app.cli_common import EXIT_OK, fail, same_file, writable_file

from hopper.logs.io import WRITERS, read_log, write_log, writer
from hopper.logs.schema import ACCEL, COMMANDS, MEASUREMENTS, STATE, Log, LogError

GROUPS = (("commands", COMMANDS), ("measurements", MEASUREMENTS), ("accelerometer", ACCEL), ("state", STATE))


def add_parser(commands: argparse._SubParsersAction, epilog: str) -> None:
    """Register `log` (check, export) on hopper-sim's subcommands."""
    log = commands.add_parser("log", help="check a robot's log against the schema, or convert it", epilog=epilog)
    actions = log.add_subparsers(dest="log_command", metavar="check|export", required=True, parser_class=type(log))
    check = actions.add_parser("check", help="samples, duration, rate, gaps and columns of a log", epilog=epilog)
    check.add_argument("file", type=Path, metavar="FILE", help="a .csv, .mcap, .npz or our own .rrd")
    export = actions.add_parser("export", help="write a log in another format (e.g. our .rrd as MCAP)", epilog=epilog)
    export.add_argument("input", type=Path, metavar="IN", help="a .csv, .mcap, .npz or our own .rrd")
    export.add_argument("output", type=writable_file, metavar="OUT", help=f"the log to write: {', '.join(WRITERS)}")


def summary(log: Log) -> list[str]:
    """The schema check of `log`, a line per finding."""
    t = log.time
    lines = [
        f"source: {log.source}",
        f"samples: {len(t):,} over {t[-1] - t[0]:.3f} s ({t[0]:.3f} to {t[-1]:.3f} s)",
        f"rate: {1.0 / log.period:.1f} Hz (median period {log.period * 1e3:.3f} ms)",
    ]
    if log.gaps:
        missing = sum(b - a for a, b in log.gaps)
        spans = ", ".join(f"{a:.3f}-{b:.3f} s" for a, b in log.gaps[:5]) + (", ..." if len(log.gaps) > 5 else "")
        lines.append(f"gaps: {len(log.gaps)} marked, {missing:.3f} s without samples: {spans}")
    else:
        lines.append("gaps: none")
    for name, group in GROUPS:
        present = [c.name for c in group if c.name in log.signals]
        absent = [c.name for c in group if c.name not in log.signals]
        state = "all" if not absent else "none" if not present else "some"
        line = f"{name}: {state} of {len(group)}" + (f" ({', '.join(present)})" if state == "some" else "")
        lines.append(line + (f"; missing (optional): {', '.join(absent)}" if absent else ""))
    lines.append("replay starts from: " + ("the log's state" if log.has_state() else "what the sensors give"))
    return lines


def run(args: argparse.Namespace) -> int:
    """hopper-sim log check / export; a refused log exits 2 (fail) with its one line."""
    check = args.log_command == "check"
    try:
        if check:
            log = read_log(args.file)
        else:
            writer(args.output)  # its suffix, before reading
            if same_file(args.output, args.input):
                fail(f"{args.output}: is the input; write the export to another file")
            log = read_log(args.input)
            path = write_log(log, args.output)
    except LogError as exc:
        fail(str(exc))
    except OSError as exc:  # reading or writing the files (not printing)
        fail(f"{exc.filename or (args.file if check else args.output)}: {exc.strerror or exc}")
    if check:
        print(f"{args.file}: a hopper log" + (" (read with its gaps marked)" if log.gaps else ""))
        for line in summary(log):
            print(f"  {line}")
        return EXIT_OK
    size = path.stat().st_size / 1e6
    print(f"{args.input} -> {path}: {len(log.time):,} samples, {1 + len(log.signals)} columns, {size:.1f} MB")
    if log.gaps:
        print(f"  its {len(log.gaps)} gap(s) kept: the samples around them are written as read")
    return EXIT_OK
