"""A stress battery for the controller: terrains, gravities and disturbances, each case pass or fail.

Each case is one simulation with at most one scheduled disturbance ("this push, this long
after the robot enters this phase, in this hop"). `run_case` is a pure function of its case,
so the battery runs on any pool of workers and gives the same table every time.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Literal

from hopper.config import GRAVITY_PRESETS, SimConfig
from hopper.control import Phase
from hopper.controllers import ControllerError, params_of, with_controller
from hopper.events import EventKind
from hopper.model import robot_of
from hopper.robot import PACKAGED, Robot
from hopper.sim import TORQUE_PULSE_S, Simulation

LANDING_LIMIT_DEG = 3.5  # paper: landing attitude error within 3.5 deg
Group = Literal["terrain", "gravity", "ground", "flight"]


@dataclasses.dataclass(frozen=True)
class Schedule:
    """Apply `kind` of `magnitude` when the robot has been `delay_s` in `phase` during hop `hop`
    (hops counted from 1: hop 1 is the ground before the first liftoff and the first flight)."""

    kind: str  # a hopper.disturbances.DISTURBANCE_LIMITS key
    magnitude: float
    phase: Phase
    delay_s: float
    hop: int = 2


@dataclasses.dataclass(frozen=True)
class Case:
    group: Group
    name: str
    config: SimConfig
    hops: int
    disturbance: Schedule | None = None


@dataclasses.dataclass(frozen=True)
class Outcome:
    case: Case
    hops: int  # completed
    fell: bool
    cause: str  # why it fell, or ""
    worst_landing_deg: float
    worst_peak_deg: float
    peak_wheel_rpm: float
    applied: bool  # the disturbance happened (its phase came)
    fault: str = ""  # the controller's failure (it could not fly, or the PID took over), "" if none

    @property
    def passed(self) -> bool:
        # The criteria: no fall anywhere; landings within the limit except after a push
        # on the ground, whose recovery hop may land less cleanly.
        landed = self.case.group == "ground" or self.worst_landing_deg <= LANDING_LIMIT_DEG
        disturbed = self.case.disturbance is None or self.applied
        return not self.fell and landed and self.hops >= self.case.hops and disturbed and not self.fault


def run_episode(sim: Simulation, hops: int, disturbance: Schedule | None = None) -> bool:
    """Step `sim` to `hops` hops, a fall or its time limit, applying `disturbance` when it is due.

    The one episode runner of the battery and the sweep workers. True if the disturbance happened
    (or there is none): its phase may never come in its hop.
    """
    limit = sim.time + sim.time_limit(hops)
    applied = disturbance is None or _disturb_when_due(sim, disturbance, hops, limit)
    if not sim.fallen and len(sim.hops) < hops:
        sim.run(hops, max_time=limit - sim.time)
    return applied


def _disturb_when_due(sim: Simulation, d: Schedule, hops: int, limit: float) -> bool:
    """Step until the schedule's moment (then disturb), the hops, a fall or `limit` (s).

    The moment: `d.delay_s` after entering `d.phase` in hop `d.hop`.
    """
    mem = sim.controller.mem
    while len(sim.hops) < hops and not sim.fallen and sim.time < limit:
        if (
            len(sim.hops) == d.hop - 1
            and sim.phase is d.phase
            and sim.time - float(mem["phase_start"][0]) >= (d.delay_s - 1e-9)
        ):
            sim.disturb(d.kind, d.magnitude)  # type: ignore[arg-type]
            return True
        if len(sim.hops) >= d.hop:
            return False  # its hop is over: the phase never came
        sim.step()
    return False


def run_case(case: Case) -> Outcome:
    """Simulate one case to its hops, a fall or the time limit."""
    try:
        sim = Simulation(case.config)
    except ControllerError as exc:
        return Outcome(case, 0, False, str(exc), 0.0, 0.0, 0.0, False, str(exc))
    applied = run_episode(sim, case.hops, case.disturbance)
    done = [h for h in sim.hops if h.completed]
    fall = next((e for e in reversed(sim.events) if e.kind is EventKind.FALL), None)
    return Outcome(
        case=case,
        hops=len(done),
        fell=sim.fallen,
        cause=fall.describe() if fall is not None and sim.fallen else (sim.controller_fault or ""),
        worst_landing_deg=max((h.landing_pitch_deg for h in done), default=0.0),
        worst_peak_deg=max((h.peak_pitch_deg for h in sim.hops), default=0.0),
        peak_wheel_rpm=max((h.peak_wheel_rpm for h in sim.hops), default=0.0),
        applied=applied,
        fault=sim.controller_fault or "",
    )


GRAVITIES = (0.2, GRAVITY_PRESETS["ceres"], 0.62, 1.0, GRAVITY_PRESETS["moon"], GRAVITY_PRESETS["mars"], 6.0,
             GRAVITY_PRESETS["earth"])  # fmt: skip


def battery(
    *, seeds: int = 100, gravity_seeds: int = 5, quick: bool = False, controller: SimConfig | None = None
) -> list[Case]:
    """The issue's acceptance cases; `quick` keeps a few of each group (for the tests). Every case flies
    `controller`'s controller and params on `controller`'s model (SimConfig.model; its other settings are
    ignored; default the PID on the packaged robot). The flight's kicks are a share of that robot's wheel."""
    if controller is None:
        return _cases(seeds, gravity_seeds, quick, PACKAGED)
    cases = _cases(seeds, gravity_seeds, quick, robot_of(SimConfig(model=controller.model, terrain="flat")))
    spec, params = controller.controller, params_of(controller)
    flown = [dataclasses.replace(c.config, model=controller.model) for c in cases]
    return [
        dataclasses.replace(c, config=with_controller(f, spec, params.items()))
        for c, f in zip(cases, flown, strict=True)
    ]


def _cases(seeds: int, gravity_seeds: int, quick: bool, robot: Robot) -> list[Case]:
    if quick:
        seeds, gravity_seeds = 2, 1
    cases: list[Case] = []
    for seed in range(seeds):
        cases.append(Case("terrain", f"moon seed {seed}", SimConfig(seed=seed), 20))
    gravities = (GRAVITY_PRESETS["ceres"], GRAVITY_PRESETS["earth"]) if quick else GRAVITIES
    for g in gravities:
        for seed in range(gravity_seeds):
            cases.append(Case("gravity", f"g {g:g} seed {seed}", SimConfig(seed=seed, gravity=g), 10))
    flat = SimConfig(terrain="flat")
    moments = (0.0, 0.15) if quick else (0.0, 0.1, 0.2, 0.4)
    for phase in (Phase.STANCE, Phase.CROUCH):
        for kind, size in (("push_forward", 6.0), ("push_backward", 6.0), ("pitch_kick", 1.5), ("pitch_kick", -1.5)):
            for delay in moments:
                name = f"{kind} {size:+g} at {phase.label} +{delay:g} s"
                cases.append(Case("ground", name, flat, 4, Schedule(kind, size, phase, delay)))
    kick = 0.7 * robot.momentum_capacity  # N m s, as a kick or as a torque pulse of that impulse
    fractions = (0.2, 0.8) if quick else (0.05, 0.2, 0.4, 0.6, 0.8)
    flight = 2.0 * math.sqrt(2.0 * flat.gravity * flat.gait.apex_height) / flat.gravity  # s, nominal
    pulse = kick / TORQUE_PULSE_S  # N m over the pulse: the same angular impulse, spread
    for sign in (1.0, -1.0):
        for fraction in fractions:
            delay = fraction * flight
            name = f"pitch kick {sign * kick:+.2f} N m s at {fraction:.0%} of flight"
            cases.append(Case("flight", name, flat, 4, Schedule("pitch_kick", sign * kick, Phase.FLIGHT, delay)))
            name = f"torque pulse {sign * pulse:+.1f} N m for {TORQUE_PULSE_S:g} s at {fraction:.0%} of flight"
            cases.append(Case("flight", name, flat, 4, Schedule("torque_pulse", sign * pulse, Phase.FLIGHT, delay)))
    return cases


def table(outcomes: list[Outcome]) -> list[str]:
    """Per group: passed / run and the worst figures; then every failed case on its own line.

    The worst figures say how the controller flew, so they leave out the cases whose controller faulted (the
    PID flew on from the fault, hopper.experiments.outcome) and say how many; the passed count keeps them.
    """
    lines = [f"{'group':<8} {'passed':>9} {'worst landing':>14} {'worst peak':>11} {'wheel rpm':>10}"]
    for group in ("terrain", "gravity", "ground", "flight"):
        rows = [o for o in outcomes if o.case.group == group]
        if not rows:
            continue
        ok = sum(o.passed for o in rows)
        flown = [o for o in rows if not o.fault]
        faulted = len(rows) - len(flown)
        if flown:
            land = max(o.worst_landing_deg for o in flown)
            peak = max(o.worst_peak_deg for o in flown)
            wheel = max(o.peak_wheel_rpm for o in flown)
            figures = f"{land:>10.2f} deg {peak:>7.2f} deg {wheel:>10.0f}"
            note = f"  ({faulted} faulted left out)" if faulted else ""
        else:
            figures = f"{'faulted':>14} {'faulted':>11} {'faulted':>10}"
            note = f"  (all {faulted} faulted)"
        lines.append(f"{group:<8} {ok:>4} / {len(rows):<4} {figures}{note}")
    for o in outcomes:
        if not o.passed:
            why = o.cause or (f"landing {o.worst_landing_deg:.2f} deg" if o.hops >= o.case.hops else "too few hops")
            lines.append(f"FAIL {o.case.group}: {o.case.name}: {o.hops}/{o.case.hops} hops; {why}")
    return lines
