"""The league: every controller flown on one battery, one row of figures each.

The battery (the same episodes for every controller, realistic sensing throughout): crater seeds
at the Moon, gravities from 0.2 to 10 m/s^2, pushes and kicks on the ground, kicks and torque
pulses in flight, and a robot that is not the nominal one (hopper.mismatch). It runs on the sweep
executors (all cores, or Ray), so a league of N controllers is N x len(battery) episodes.

The flight figures (landing to saturation) say how a controller flew, so they leave out its episodes
whose controller faulted (the PID flew on from the fault, hopper.experiments.outcome); the success,
fall and fault counts keep them.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np

from hopper.config import GRAVITY_PRESETS, SimConfig
from hopper.control.phases import Phase
from hopper.experiments.spec import Episode
from hopper.experiments.stress import Schedule
from hopper.experiments.worker import EpisodeResult
from hopper.robot import PACKAGED, Robot
from hopper.sim import TORQUE_PULSE_S

GRAVITIES = (
    0.2,
    GRAVITY_PRESETS["ceres"],
    0.62,
    GRAVITY_PRESETS["moon"],
    GRAVITY_PRESETS["mars"],
    6.0,
    GRAVITY_PRESETS["earth"],
    10.0,
)  # fmt: skip  m/s^2
MISMATCHES = (
    (("torso_mass", 1.2),),
    (("wheel_inertia", 0.85), ("motor_torque", 0.9)),
    (("leg_mass", 1.25), ("friction", 0.6)),
)


@dataclasses.dataclass(frozen=True)
class Entry:
    """One episode of the battery, before a controller is chosen."""

    group: str  # terrain, gravity, ground, flight, mismatch
    gravity: float
    seed: int
    hops: int
    terrain: str = "crater"
    disturbance: Schedule | None = None
    mismatch: tuple[tuple[str, float], ...] = ()


def battery(quick: bool = False, robot: Robot = PACKAGED) -> list[Entry]:
    """The league's episodes; `quick` keeps a few of each group (for the tests). The flight's kicks
    are a share of `robot`'s wheel."""
    seeds = 2 if quick else 10
    entries = [Entry("terrain", GRAVITY_PRESETS["moon"], s, 10) for s in range(seeds)]
    for g in (GRAVITY_PRESETS["ceres"], GRAVITY_PRESETS["earth"]) if quick else GRAVITIES:
        entries += [Entry("gravity", g, 100 + s, 7) for s in range(1 if quick else 2)]
    moon = GRAVITY_PRESETS["moon"]
    ground = [("push_forward", 4.0, Phase.STANCE), ("pitch_kick", 1.0, Phase.CROUCH)]
    for kind, size, phase in ground if quick else ground + [("push_backward", 4.0, Phase.CROUCH)]:
        entries.append(Entry("ground", moon, 200, 4, "flat", Schedule(kind, size, phase, 0.1, hop=2)))
    kick = 0.5 * robot.momentum_capacity  # N m s
    flight = 2.0 * math.sqrt(2.0 * moon * SimConfig().gait.apex_height) / moon  # s, nominal
    fractions = (0.3,) if quick else (0.2, 0.5, 0.8)
    for sign in (1.0, -1.0):
        for f in fractions:
            kicked = Schedule("pitch_kick", sign * kick, Phase.FLIGHT, f * flight, hop=2)
            pulse = Schedule("torque_pulse", sign * kick / TORQUE_PULSE_S, Phase.FLIGHT, f * flight, hop=3)
            entries += [Entry("flight", moon, 300, 4, "flat", kicked), Entry("flight", moon, 301, 4, "flat", pulse)]
    for i, mismatch in enumerate(MISMATCHES[:1] if quick else MISMATCHES):
        entries += [Entry("mismatch", moon, 400 + 10 * i + s, 7, mismatch=mismatch) for s in range(1 if quick else 2)]
    return entries


def episodes(
    controller: str, params: Iterable[tuple[str, float]], entries: list[Entry], mjcf: str | None = None
) -> list[Episode]:
    """The battery flown by one controller (realistic sensing, the default gait) on `mjcf`'s robot
    (SimConfig.model; None: the packaged one)."""
    params = tuple(params)
    return [
        Episode(kp=450.0, ki=50.0, kd=30.0, gravity=e.gravity, seed=e.seed, hops_target=e.hops, terrain=e.terrain,
                wheel=True, sensing="realistic", disturbance=e.disturbance, controller=controller, params=params,
                mismatch=e.mismatch, mjcf=mjcf)
        for e in entries
    ]  # fmt: skip


@dataclasses.dataclass(frozen=True)
class Row:
    """One controller's figures over the battery. The flight figures (landing to saturation) go over the
    `flown` episodes, those without a controller fault; None where there is none (every episode faulted,
    or no hop to measure)."""

    controller: str
    episodes: int
    success_pct: float  # episodes with every hop done, no fall, no controller fault
    falls: int
    faults: int
    flown: int  # episodes without a controller fault: the flight figures are over these
    landing_p50_deg: float | None  # |pitch| at touchdown over every completed hop
    landing_p95_deg: float | None
    landing_max_deg: float | None
    peak_pitch_deg: float | None  # the largest mid-air |pitch| of any hop
    rms_rate_deg_s: float | None  # mean over hops of each flight's RMS pitch rate
    energy_j: float | None  # mean electrical energy per completed hop (wheel and legs, hopper.control.energy), J
    saturation_s: float | None  # mean per hop
    compute_us: float  # mean per controller call over every episode (0: the compiled PID, in the kernel's ~1 us tick)
    worst: str  # the failed episode most worth a look, "" if none

    def as_dict(self) -> dict[str, object]:
        return dataclasses.asdict(self)


def row(controller: str, results: list[EpisodeResult]) -> Row:
    """Aggregate one controller's episodes: the counts over all, the flight figures over those it flew to the end."""
    flown = [r for r in results if not r.controller_fault]  # after a fault the PID flew: not this controller's hops
    hops = [h for r in flown for h in r.hops]
    done = [h for h in hops if h.completed]
    landing = np.array([abs(h.landing_pitch_deg) for h in done])
    ok = [not r.fell and not r.controller_fault and sum(h.completed for h in r.hops) >= r.episode.hops_target
          for r in results]  # fmt: skip
    failed = [r for r, good in zip(results, ok, strict=True) if not good]
    energy = [h.wheel_energy_j + h.leg_energy_j for h in done]
    worst = ""
    if failed:
        r = failed[0]
        e = r.episode
        what = r.controller_fault or ("fell" if r.fell else f"{sum(h.completed for h in r.hops)}/{e.hops_target} hops")
        worst = f"g {e.gravity:g} seed {e.seed}{' ' + e.settings()['disturbance'] if e.disturbance else ''}: {what}"
    return Row(
        controller=controller,
        episodes=len(results),
        success_pct=100.0 * sum(ok) / max(len(results), 1),
        falls=sum(r.fell for r in results),
        faults=len(results) - len(flown),
        flown=len(flown),
        landing_p50_deg=_or_none(np.percentile, landing, 50),
        landing_p95_deg=_or_none(np.percentile, landing, 95),
        landing_max_deg=_or_none(np.max, landing),
        peak_pitch_deg=_or_none(np.max, [h.peak_pitch_deg for h in hops]),
        rms_rate_deg_s=_or_none(np.mean, [h.rms_pitch_rate_deg_s for h in hops]),
        energy_j=_or_none(np.mean, energy),
        saturation_s=_or_none(np.mean, [h.saturation_time_s for h in hops]),
        compute_us=float(np.mean([r.compute_us for r in results])) if results else 0.0,
        worst=worst,
    )


def _or_none(reduce: Callable[..., Any], values: Sequence[float] | np.ndarray, *args: float) -> float | None:
    """`reduce(values, *args)` as a float, None (JSON null) for no values."""
    return float(reduce(values, *args)) if len(values) else None


HEADINGS = ("controller", "ok %", "land p50", "p95", "max deg", "peak deg", "rms deg/s", "J/hop", "sat s", "us/call")


def table(rows: list[Row]) -> list[str]:
    """The league as aligned text, then for each controller with a failure: its falls, its controller faults
    (left out of the flight figures) and its worst failure."""
    width = max([len(HEADINGS[0]), *(len(r.controller) for r in rows)])
    lines = [f"{HEADINGS[0]:<{width}} " + " ".join(f"{h:>9}" for h in HEADINGS[1:])]
    for r in rows:
        figures = (r.landing_p50_deg, r.landing_p95_deg, r.landing_max_deg, r.peak_pitch_deg, r.rms_rate_deg_s,
                   r.energy_j, r.saturation_s)  # fmt: skip
        none = "faulted" if r.episodes and not r.flown else "n/a"  # every episode faulted, or no hop to measure
        cells = [f"{r.success_pct:>9.2f}", *(f"{none:>9}" if v is None else f"{v:>9.2f}" for v in figures)]
        compute = f"{r.compute_us:>9.2f}" if r.compute_us else f"{'compiled':>9}"  # no Python call to time
        lines.append(f"{r.controller:<{width}} " + " ".join(cells) + f" {compute}")
    for r in rows:
        if r.worst:
            lines.append(f"{r.controller}: {r.falls} fell, {_faults(r)}; e.g. {r.worst}")
    return lines


def _faults(r: Row) -> str:
    """ "k controller faults" and, where there are any, that the figures from the landing to the saturation
    leave them out (the PID flew on from each fault), or have nothing left when every episode faulted."""
    counted = f"{r.faults} controller fault{'s' if r.faults != 1 else ''}"
    if not r.faults:
        return counted
    if r.flown:
        return f"{counted} (left out of the figures from land p50 to sat s: the PID flew on from each fault)"
    return f"{counted} (every episode, so no figure from land p50 to sat s is its own: the PID flew on from each fault)"
