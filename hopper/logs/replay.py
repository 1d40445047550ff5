"""Replay a log beside the simulation: the log's commands, open loop, from the log's state at a moment.

`simulate` is pure: a model, a log and a span of its rows in, the simulated signals out (the
model's own data, never a Simulation). The wheel's commands go through what the robot's drive
does (the delay line, then the voltage that gives the torque at the wheel speed it measures, as
hopper.control.wheel.wheel_ctrl inverts the motor its controller knows: `drive`, the motor the log's
commands were made for, hopper.logs.world.World.drive; by default the packaged robot's): the
model's own motor then turns that voltage into torque, so the robot that made the log replays it
exactly and a model whose motor is not the robot's turns the same commands into other torques, as
a real one does. `replay_hops` flies each hop
of the log from its liftoff; `errors` compares the two (pitch, wheel speed, contact timing).

The legs fly the log's torques alone by default. With `servo`, a joint servo around those torques
also holds them to the log's encoder angles, as a bench replaying a robot's log holds its legs:
an open-loop stance is an inverted pendulum on slipping feet, chaotic (REANCHOR_S), and with the
legs held a whole hop measures the torso and the wheel instead (README, "From a log to the model").
"""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np

from hopper.errors import HopperError
from hopper.layout import LEG_JOINTS, ModelLayout
from hopper.logs import gaps
from hopper.logs.schema import STATE, Log
from hopper.logs.world import DEFAULT_DELAY_TICKS, World
from hopper.model import build_model, set_terrain, terrain_window
from hopper.robot import PACKAGED, Robot

MIN_FLIGHT_S = 0.1  # s: both feet off the ground this long is a flight (a stance's flicker is shorter)
# s: a replay re-anchored on the log's state this often measures the model, not the chaos of an
# open-loop stance: on the robot the true model with its friction 0.1 % off replays whole
# hops 3.5 deg RMS off (README, "From a log to the model"); 0.3 s holds about half a lunar flight.
REANCHOR_S = 0.3
# The legs' servo to the log's angles (`servo`): stiff enough that a hop's contacts come where the
# log's did (1 deg costs 0.35 N m of the legs' 30), soft beside what the legs' torques already do.
LEG_SERVO_KP = 20.0  # N m/rad at each leg joint
LEG_SERVO_KD = 2.0  # N m s/rad: about critical on a leg's ~0.05 kg m^2 at the knee
HELD = "legs held to the log's angles"  # how a replay with `servo` is labelled (CLI, dashboard)
LEG_COMMANDS = tuple(f"{j}_torque_cmd" for j in LEG_JOINTS)
SIMULATED = ("pitch", "pitch_rate", "wheel_speed", "x", "z", *LEG_JOINTS, "foot_L_force", "foot_R_force")


class ReplayError(HopperError, ValueError):
    """A log that cannot be replayed as asked (no state to start from, a span outside it, ...)."""


def world_model(world: World):  # noqa: ANN201
    """(the world's robot compiled in it, the terrain window it holds: simulate moves it)."""
    config = world.config()
    window = terrain_window(config)
    return build_model(config, window), window


@dataclasses.dataclass(frozen=True)
class Trajectory:
    """The simulated signals over rows `first`..`first + len(time) - 1` of the log, schema names and units."""

    first: int
    time: np.ndarray  # s, (n,)
    signals: dict[str, np.ndarray]  # SIMULATED names -> (n,)


def check_replayable(log: Log) -> None:
    if not log.has_state():
        missing = ", ".join(c.name for c in STATE if c.name not in log.signals)
        raise ReplayError(f"{log.source}: a replay starts from the log's state, and it has no {missing} column(s)")


def leg_rates(log: Log, start: int, stop: int) -> np.ndarray:
    """The legs' joint rates (rad/s) at rows start..stop-1, a column each of LEG_JOINTS, by backward
    differences of their encoders (exact for MuJoCo's integrators, which move q by dt times the new
    velocity; a central difference misses the swing that starts at a liftoff); row 0 by the forward one."""
    k = np.arange(start, stop)
    a, b = np.maximum(k - 1, 0), np.maximum(k, 1)
    dt = log.time[b] - log.time[a]
    return np.column_stack([(log.signals[j][b] - log.signals[j][a]) / dt for j in LEG_JOINTS])


def set_state(model: mujoco.MjModel, data: mujoco.MjData, log: Log, k: int) -> None:
    """Put the robot into the log's state at row k: pitch, legs, wheel speed and the torso CoM's position
    and velocity as logged (the model's own CoM offset accounted for), the legs' rates leg_rates'; the
    wheel's angle (which nothing depends on) at 0."""
    lay = ModelLayout.of(model)
    s, time = log.signals, log.time
    mujoco.mj_resetData(model, data)
    data.time = float(time[k])
    for joint, q, v, rate in zip(LEG_JOINTS, lay.q_legs, lay.v_legs, leg_rates(log, k, k + 1)[0], strict=True):
        data.qpos[q] = s[joint][k]
        data.qvel[v] = rate
    rate = s["pitch_rate"][k]
    data.qpos[lay.q_pitch], data.qvel[lay.v_pitch], data.qvel[lay.v_wheel] = s["pitch"][k], rate, s["wheel_speed"][k]
    mujoco.mj_kinematics(model, data)  # the root at 0: where the torso's CoM is from its frame
    r = data.xipos[lay.torso] - data.xpos[lay.torso]
    x0, z0 = lay.torso_origin
    data.qpos[lay.q_x], data.qpos[lay.q_z] = s["x"][k] - x0 - r[0], s["z"][k] - z0 - r[2]
    data.qvel[lay.v_x], data.qvel[lay.v_z] = s["vx"][k] - rate * r[2], s["vz"][k] + rate * r[0]
    mujoco.mj_forward(model, data)


def poses(model: mujoco.MjModel, signals: dict[str, np.ndarray], every: int = 1) -> np.ndarray:
    """qpos rows of the robot at every `every`-th sample of `signals` (SIMULATED or log names: pitch,
    the legs and the torso CoM's x, z in m), as set_state places it, the wheel's angle at 0; a sample
    that is not finite (a diverged replay) holds the pose before it."""
    lay = ModelLayout.of(model)
    data = mujoco.MjData(model)
    rows = range(0, len(signals["pitch"]), every)
    out = np.empty((len(rows), model.nq))
    x0, z0 = lay.torso_origin
    for i, k in enumerate(rows):
        values = [signals[name][k] for name in ("pitch", "x", "z", *LEG_JOINTS)]
        if not all(math.isfinite(v) for v in values):
            out[i] = out[i - 1] if i else data.qpos
            continue
        mujoco.mj_resetData(model, data)
        data.qpos[lay.q_pitch] = values[0]
        data.qpos[list(lay.q_legs)] = values[3:]
        mujoco.mj_kinematics(model, data)  # the root at 0: where the torso's CoM is from its frame
        r = data.xipos[lay.torso] - data.xpos[lay.torso]
        data.qpos[lay.q_x], data.qpos[lay.q_z] = values[1] - x0 - r[0], values[2] - z0 - r[2]
        out[i] = data.qpos
    return out


def place_terrain(model: mujoco.MjModel, window, x: float) -> None:  # noqa: ANN001 (a terrain.Window)
    """Move the model's terrain window under world x (m) if it is not there already."""
    if window.follow(x, urgent=False):
        set_terrain(model, window)


def simulate(
    model: mujoco.MjModel,
    log: Log,
    start: int,
    stop: int,
    *,
    delay_ticks: int = DEFAULT_DELAY_TICKS,
    data: mujoco.MjData | None = None,
    window=None,  # noqa: ANN001 (a terrain.Window: moved under the start if given)
    drive: Robot = PACKAGED,
    servo: bool = False,
) -> Trajectory:
    """Fly rows start..stop-1 of `log` open loop on `model` from the log's state at row `start`
    (with `servo`, the legs also held to the log's angles: LEG_SERVO_KP, LEG_SERVO_KD), the wheel's
    commands turned into voltages by inverting `drive`'s motor (the one they were made for).

    Row k's simulated values are those of t_k, as the log's are (hopper.logs.capture): pitch, rates
    and positions before the step that applies row k's commands, the feet's forces of its forward pass.
    A state that goes non-finite (a diverging open-loop flight) stops the run: the rest is NaN.
    Rows that run across a gap in the log are refused (hopper.logs.gaps: cut them there).
    """
    check_replayable(log)
    n = len(log.time)
    if not 0 <= start < stop <= n:
        raise ReplayError(f"{log.source}: rows {start}..{stop} are outside its {n} samples")
    across = gaps.crossed(log, (start, stop))
    if across:
        a, b = across[0]
        raise ReplayError(
            f"{log.source}: a replay of {log.time[start]:.3f}..{log.time[stop - 1]:.3f} s reads across a gap "
            f"({a:.3f}-{b:.3f} s without samples): it flies no commands the log does not hold"
        )
    data = mujoco.MjData(model) if data is None else data
    lay = ModelLayout.of(model)
    if window is not None:
        place_terrain(model, window, float(log.signals["x"][start]))
    set_state(model, data, log, start)
    s = log.signals
    wheel_cmd = s["wheel_torque_cmd"]
    delayed = np.zeros(stop - start)  # what the delay line hands the drive at each row
    src = np.arange(start, stop) - delay_ticks
    ok = src >= 0
    delayed[ok] = wheel_cmd[src[ok]]
    legs = np.column_stack([s[c][start:stop] for c in LEG_COMMANDS]) / lay.leg_gear
    if servo:  # the log's angles and their rates, as set_state takes them
        angles, rates = np.column_stack([s[j][start:stop] for j in LEG_JOINTS]), leg_rates(log, start, stop)
    m = stop - start
    out = np.full((m, len(SIMULATED)), np.nan)
    q, v, sensors, ctrl = data.qpos, data.qvel, data.sensordata, data.ctrl
    a_wheel, a_legs, torso = lay.a_wheel, list(lay.a_legs), lay.torso
    q_legs, v_legs = list(lay.q_legs), list(lay.v_legs)
    xipos = data.xipos
    limit, damping = drive.wheel_torque_limit, drive.wheel_damping
    for i in range(m):
        w = v[lay.v_wheel]
        u = (delayed[i] + damping * w) / limit  # hopper.control.wheel.wheel_ctrl
        ctrl[a_wheel] = 1.0 if u > 1.0 else -1.0 if u < -1.0 else u
        if servo:
            held = LEG_SERVO_KP * (angles[i] - q[q_legs]) + LEG_SERVO_KD * (rates[i] - v[v_legs])
            ctrl[a_legs] = legs[i] + held / lay.leg_gear
        else:
            ctrl[a_legs] = legs[i]
        row = out[i]
        row[0], row[1], row[2] = q[lay.q_pitch], v[lay.v_pitch], w
        row[5:9] = q[q_legs]
        mujoco.mj_step(model, data)
        row[3], row[4] = xipos[torso, 0], xipos[torso, 2]
        row[9], row[10] = sensors[lay.s_foot_l], sensors[lay.s_foot_r]
        if not math.isfinite(row[0]) or not math.isfinite(q[lay.q_pitch]):
            out[i:] = np.nan
            break
    return Trajectory(start, log.time[start:stop].copy(), {name: out[:, j] for j, name in enumerate(SIMULATED)})


def contact(force_l: np.ndarray, force_r: np.ndarray) -> np.ndarray:
    """Either foot on the ground, sample by sample."""
    return (force_l > 0.0) | (force_r > 0.0)


def flights(log: Log) -> list[tuple[int, int]]:
    """The log's flights as (liftoff row, touchdown row): both feet off for MIN_FLIGHT_S or more."""
    on = contact(log.signals["foot_L_force"], log.signals["foot_R_force"])
    edges = np.flatnonzero(np.diff(on.astype(np.int8))) + 1  # rows where contact changes
    bounds = np.concatenate([[0], edges, [len(on)]])
    spans = []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        if not on[a] and a > 0 and b < len(on) and (log.time[b] - log.time[a]) >= MIN_FLIGHT_S:
            spans.append((int(a), int(b)))
    return spans


def hops(log: Log) -> list[tuple[int, int]]:
    """Each hop of the log as rows (liftoff, next liftoff); the last one ends at the log's end."""
    lifts = [a for a, _ in flights(log)]
    if not lifts:
        return []
    return [(a, b) for a, b in zip(lifts, [*lifts[1:], len(log.time)], strict=True)]


def phases(log: Log) -> list[tuple[int, int]]:
    """Each flight (liftoff to touchdown) and each stance after one (touchdown to the next liftoff, or
    the log's end), in time order: a replay from the log's state at every contact change."""
    spans = flights(log)
    stances = [(b, a) for (_, b), (a, _) in zip(spans, [*spans[1:], (len(log.time), 0)], strict=True)]
    return sorted(spans + [(a, b) for a, b in stances if b - a >= 2])


@dataclasses.dataclass(frozen=True)
class Errors:
    """Simulated minus logged over one replay (or several, concatenated)."""

    time: np.ndarray  # s, (n,)
    pitch: np.ndarray  # rad, (n,)
    wheel_speed: np.ndarray  # rad/s, (n,)
    touchdown: np.ndarray  # s, simulated minus logged, one per logged touchdown the replay saw (NaN: missed)
    liftoff: np.ndarray  # s, likewise for liftoffs

    def rms(self, name: str) -> float:
        """RMS of `pitch` or `wheel_speed`; a diverged (NaN) replay counts as its own failure: inf."""
        e = getattr(self, name)
        return float(np.sqrt(np.mean(e * e))) if e.size and np.isfinite(e).all() else math.inf

    def timing(self) -> str:
        """The touchdowns' timing in words: "12 ms mean |touchdown error| over 5 (1 missed)"."""
        td = self.touchdown[np.isfinite(self.touchdown)]
        missed = self.touchdown.size - td.size
        if not td.size:
            return f"no touchdown simulated of {missed} logged" if missed else "no touchdown"
        return f"{1e3 * np.abs(td).mean():.0f} ms mean |touchdown error| over {td.size}" + (
            f" ({missed} missed)" if missed else ""
        )

    @staticmethod
    def concat(parts: list[Errors]) -> Errors:
        return Errors(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in dataclasses.fields(Errors)))


def _switches(on: np.ndarray, time: np.ndarray, rising: bool) -> np.ndarray:
    d = np.diff(on.astype(np.int8))
    return time[1:][d == (1 if rising else -1)]


def _timing(logged_on: np.ndarray, sim_on: np.ndarray, time: np.ndarray, rising: bool) -> np.ndarray:
    """Simulated minus logged time (s) of each logged switch of one kind (rising: a touchdown), by the
    simulated one nearest it between the logged switches of the other kind around it (a touchdown
    within the flight before it or the stance after it); NaN where the simulation made none there. The
    nearest anywhere matched a touchdown the replay missed with one a hop away: over a second."""
    logged, simulated = _switches(logged_on, time, rising), _switches(sim_on, time, rising)
    others = _switches(logged_on, time, not rising)
    out = np.full(logged.size, np.nan)
    for i, t in enumerate(logged):
        start, end = others[others < t].max(initial=-np.inf), others[others > t].min(initial=np.inf)
        near = simulated[(simulated > start) & (simulated < end)]
        if near.size:
            out[i] = near[np.argmin(np.abs(near - t))] - t
    return out


def errors(log: Log, sim: Trajectory) -> Errors:
    """Compare a replay with its log: pitch and wheel speed sample by sample; each logged touchdown
    and liftoff (contact changes of the feet) against the simulated one nearest it in its phases."""
    k = slice(sim.first, sim.first + len(sim.time))
    s = log.signals
    logged_on = contact(s["foot_L_force"][k], s["foot_R_force"][k])
    sim_on = contact(sim.signals["foot_L_force"], sim.signals["foot_R_force"])
    timing = [_timing(logged_on, sim_on, sim.time, rising) for rising in (True, False)]
    return Errors(
        sim.time,
        sim.signals["pitch"] - s["pitch"][k],
        sim.signals["wheel_speed"] - s["wheel_speed"][k],
        timing[0],
        timing[1],
    )


def replay_spans(
    model: mujoco.MjModel,
    log: Log,
    spans: list[tuple[int, int]],
    *,
    delay_ticks: int = DEFAULT_DELAY_TICKS,
    window=None,  # noqa: ANN001 (a terrain.Window)
    servo: bool = False,
    drive: Robot = PACKAGED,
) -> list[tuple[Trajectory, Errors]]:
    """Replay each (start, stop) span of rows from the log's state at its start (`servo`, `drive`: simulate's)."""
    if not spans:
        raise ReplayError(f"{log.source}: nothing to replay (no hop: no flight of {MIN_FLIGHT_S:g} s or more)")
    data = mujoco.MjData(model)
    out = []
    for a, b in spans:
        traj = simulate(model, log, a, b, delay_ticks=delay_ticks, data=data, window=window, servo=servo, drive=drive)
        out.append((traj, errors(log, traj)))
    return out


def windows(log: Log, span: tuple[int, int], window_s: float) -> list[tuple[int, int]]:
    """Rows span[0]..span[1] cut into consecutive windows of about window_s (s), and at each gap: the
    window after a gap starts at its far side (hopper.logs.gaps)."""
    step = max(int(round(window_s / log.period)), 2)
    out = []
    for a, b in gaps.pieces(log, span):
        out += [(c, min(c + step, b)) for c in range(a, b, step) if min(c + step, b) - c >= 2]
    return out


def replay_hops(
    model: mujoco.MjModel,
    log: Log,
    count: int | None = None,
    *,
    first: int = 0,
    delay_ticks: int = DEFAULT_DELAY_TICKS,
    window=None,  # noqa: ANN001 (a terrain.Window)
    every: float | None = None,
    servo: bool = False,
    drive: Robot = PACKAGED,
) -> list[tuple[Trajectory, Errors]]:
    """Replay hops first..first+count-1 of the log (all from `first` by default), each from its liftoff
    to the next; with `every` (s), each hop in windows of that length, each from the log's state at its
    start (multiple shooting). Whole, an open-loop stance is an inverted pendulum without feedback on
    slipping feet: it drifts off unless the model is the robot to the last digit (REANCHOR_S), or
    the legs are held to the log's angles (`servo`: simulate's; `drive` too). A hop that holds a gap
    is left out whole, and re-anchored at the gap's far side with `every` (hopper.logs.gaps.note)."""
    if every is not None and not every > 0.0:
        raise ReplayError(f"a replay re-anchors every positive number of seconds, got {every}")
    spans = hops(log)[first:]
    spans = spans if count is None else spans[:count]
    if every is not None:
        spans = [w for hop in spans for w in windows(log, hop, every)]
    elif spans:
        spans = [hop for hop in spans if not gaps.crossed(log, hop)]
        if not spans:
            raise ReplayError(f"{log.source}: each hop asked holds a gap: a whole hop is not scored across one")
    return replay_spans(model, log, spans, delay_ticks=delay_ticks, window=window, servo=servo, drive=drive)
