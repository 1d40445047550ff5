"""`hopper-sim size --gravity BODY --out PATH.xml`: the robot with its actuators sized for another gravity.

Writes the packaged robot (or --model's) with its leg and wheel motors scaled from the gravity it
was sized for (--design; default the one a model this command wrote records, else the Moon's: the
paper's robot) by dynamic similarity (hopper.similarity): torques x g / g_design, the wheel's
momentum capacity x sqrt(g / g_design). The written MJCF records the gravity each part is sized for
(<custom><numeric name="hopper_design_gravity_legs|wheel">), so sizing it again is idempotent.
--only legs (or wheel) scales one of them and keeps the other: which one a gravity overloads.
Fly it anywhere with --model PATH.xml.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from hopper.app.cli_common import EXIT_OK, add_model_flag, fail, gravity, mjcf_out

from hopper.config import SimConfig
from hopper.errors import ModelError
from hopper.model import model_source, model_spec, robot_of
from hopper.similarity import PARTS, design_gravity, designs, size_for


def add_parser(commands: argparse._SubParsersAction, epilog: str) -> None:
    """Register `size` on hopper-sim's subcommands."""
    p = commands.add_parser(
        "size",
        help="write the robot with its actuators sized for another gravity (MJCF, for --model)",
        epilog=epilog,
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--gravity", type=gravity, required=True, help="m/s^2 or a preset: the gravity to size for")
    p.add_argument(
        "--design", type=gravity,
        help="m/s^2 or a preset: the gravity the robot was sized for (default: the one a model written by size "
        "records, else moon, the paper's)",
    )  # fmt: skip
    p.add_argument(
        "--only", choices=PARTS, default=None,
        help="scale only the leg motors or only the wheel (its motor and momentum), keeping the other as it is",
    )  # fmt: skip
    add_model_flag(p)
    p.add_argument("--out", type=mjcf_out, required=True, metavar="PATH.xml", help="the MJCF to write")


def run(args: argparse.Namespace) -> int:
    if args.gravity <= 0.0 or (args.design is not None and args.design <= 0.0):
        design = "" if args.design is None else f" and --design {args.design:g}"
        fail(f"gravities must be positive (got --gravity {args.gravity:g}{design} m/s^2)")
    if args.model is not None and args.out.absolute().resolve() == Path(args.model).resolve():
        fail(f"{args.out}: is --model's file; write the sized robot to another file")
    base = SimConfig(model=args.model, terrain="flat")
    before = robot_of(base)
    spec = model_spec(base)
    parts = (args.only,) if args.only else PARTS
    if args.design is not None:
        recorded = {part: g for part in parts if (g := design_gravity(spec, part)) is not None}
        clash = [f"{part} for {g:g}" for part, g in recorded.items() if not math.isclose(g, args.design)]
        if clash:
            fail(f"--design {args.design:g}: {model_source(base)} records its {', '.join(clash)} m/s^2; drop --design")
    sized_from = designs(spec, parts, args.design)  # before size_for records the new gravity
    k = size_for(spec, args.gravity, args.design, parts)
    args.out.write_text(spec.to_xml(), encoding="utf-8")
    try:  # what --model will read back: the file loads and the controller can fly it
        after = robot_of(SimConfig(model=str(args.out.absolute()), terrain="flat"))
    except ModelError as exc:
        args.out.unlink()
        fail(f"the sized robot does not load, nothing written: {exc}")
    which = f"; {args.only} only" if args.only else ""
    if len(set(sized_from.values())) == 1:
        scale = f"from {sized_from[parts[0]]:g} to {args.gravity:g} m/s^2 (torques x {k:.3g}{which})"
    else:  # one part sized before (--only): each from its own
        each = ", ".join(f"{part} from {g:g} (x {args.gravity / g:.3g})" for part, g in sized_from.items())
        scale = f"to {args.gravity:g} m/s^2, each part from its own: {each}"
    source = model_source(base)
    print(f"wrote {args.out}: {source} sized {scale}")
    rows = (
        ("leg motors", "N m", before.leg_torque_limit, after.leg_torque_limit),
        ("wheel stall torque", "N m", before.wheel_torque_limit, after.wheel_torque_limit),
        ("wheel momentum capacity", "N m s", before.momentum_capacity, after.momentum_capacity),
        ("wheel no-load speed", "rad/s", before.wheel_no_load_speed, after.wheel_no_load_speed),
    )
    for name, unit, was, now in rows:
        print(f"  {name:24s} {was:9.4g} -> {now:9.4g} {unit}")
    print(f"fly it with --model {args.out}")
    return EXIT_OK
