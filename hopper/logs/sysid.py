"""Identify the robot from a log: a least-squares fit of the simulation, replayed open loop, to the log.

The log's span is cut into short windows, each replayed from the log's state at its start
(multiple shooting: an open-loop stance drifts off within a second, and a window's error then
says how wrong the model is, not how far a fall took it). The residuals are the simulated minus
logged pitch, wheel speed, torso CoM and leg angles, and the logged gyro minus the logged (true)
pitch rate and the gyro's bias, each over its scale (CHANNELS). The bias is measured against the
log's own state, not the replay's rate: against the replay, whatever the model still gets wrong in
stance (a friction 13 % off) leaked into it (-17 % on the round trip's second case). scipy's least_squares (trust region
reflective) fits the parameters (PARAMS) with a Jacobian of forward differences (the gyro bias's
column is exact: it changes no simulation). Each estimate carries the sigma of the linearised
fit, s^2 (J^T J)^-1 with s^2 the residual's variance: the residuals of model error are
correlated in time, so these sigmas are lower bounds. Pairs whose estimates correlate beyond
NOT_SEPARABLE are reported as such: only a combination of them is identified.

mujoco.sysid (MuJoCo 4) rolls out open-loop controls; our wheel's drive closes a loop on the
wheel speed it measures and delays its command (hopper.logs.replay), and mujoco.sysid needs absl,
which the product does not install: the fit here is scipy's, on hopper.logs.replay.simulate.
"""

from __future__ import annotations

import dataclasses
import math
import time as clock
from collections.abc import Callable, Sequence

import mujoco
import numpy as np

from hopper import robot as robots
from hopper.errors import HopperError
from hopper.layout import LEG_JOINTS
from hopper.logs.replay import Errors, ReplayError, flights, hops, replay_hops, simulate, windows
from hopper.logs.schema import Log
from hopper.logs.world import DEFAULT_DELAY_TICKS
from hopper.mismatch import Nominal, pitch_inertia

NOT_SEPARABLE = 0.999  # |correlation| of two estimates beyond which only their combination is identified
# Residual scales (SI): a residual of 1 is this much error. The gyro's is its white noise per sample
# at 1 kHz (hopper.config.SensingParams: 0.014 deg/s/sqrt(Hz)).
CHANNELS = {
    "pitch": 1e-3,  # rad
    "wheel_speed": 0.1,  # rad/s
    "x": 1e-3,  # m
    "z": 1e-3,  # m
    **dict.fromkeys(LEG_JOINTS, 1e-3),  # rad
    "gyro_pitch": math.radians(0.014) / math.sqrt(0.001),  # rad/s
}
DIVERGED = 100.0  # the residual of a sample after a window's replay diverged (non-finite)
STAGES = (0.05, 0.1, 0.3)  # s, the windows of the fit's stages
FLIGHT_WINDOW_S = 0.3  # s, the windows of the flights' fit before the stages (no contact: no chaos)


class IdentifyError(HopperError, ValueError):
    """Identification asked of what it cannot do (an unknown parameter, a log too short, ...)."""


@dataclasses.dataclass(frozen=True)
class Param:
    """One identifiable quantity: its unit, what it is, its scale (the fit's step and prior size) and bounds
    as factors of its nominal value (or, for a nominal of 0, in its unit)."""

    unit: str
    what: str
    scale: Callable[[float], float]  # nominal -> a typical size of the quantity
    bounds: Callable[[float], tuple[float, float]]


def _factor(nominal: float) -> tuple[float, float]:
    return 0.2 * nominal, 5.0 * nominal


PARAMS: dict[str, Param] = {
    "torso_mass": Param("kg", "the torso's mass", abs, _factor),
    "torso_inertia": Param("kg m^2", "the torso's pitch inertia (every principal moment alike)", abs, _factor),
    "torso_com_x": Param("m", "the torso's CoM forward of its frame", lambda _: 0.01, lambda _: (-0.18, 0.18)),
    "torso_com_z": Param("m", "the torso's CoM above its frame", lambda _: 0.01, lambda _: (-0.18, 0.18)),
    "wheel_inertia": Param(
        "kg m^2", "the spin inertia the motor turns: the wheel's and the rotor's (armature), scaled alike", abs, _factor
    ),
    "wheel_armature": Param("kg m^2", "the rotor's share of wheel_inertia (the joint's armature)", abs, _factor),
    "motor_torque": Param("x nominal", "the wheel motor's k_t: stall torque x k, back-EMF damping x k^2", abs, _factor),
    "motor_damping": Param("x nominal", "the wheel motor's damping beyond k_t's (winding, gear)", abs, _factor),
    "friction": Param("", "the sliding friction of the ground and the feet", abs, lambda n: (0.05, 3.0)),
    "gyro_bias": Param("deg/s", "the IMU gyro's bias (pitch axis)", lambda _: 1.0, lambda _: (-10.0, 10.0)),
}
# What `hopper-sim identify` fits by default. The armature's share of the spin inertia and the
# motor's damping beyond k_t^2 are left out: with k_t they make a triple that the wheel's response
# cannot tell apart (their correlations exceed 0.99999 on the round trip); --params adds them,
# and the fit then says they are not separable.
DEFAULT_FIT = ("torso_mass", "torso_inertia", "torso_com_x", "torso_com_z", "wheel_inertia", "motor_torque",
               "friction", "gyro_bias")  # fmt: skip


def nominal(model: mujoco.MjModel) -> dict[str, float]:
    """Every parameter's value in `model` (SI, PARAMS' units; the motor factors 1, no gyro bias)."""
    torso, wheel = model.body("torso").id, model.body("wheel").id
    armature = float(model.dof_armature[model.jnt_dofadr[model.joint("wheel").id]])
    return {
        "torso_mass": float(model.body_mass[torso]),
        "torso_inertia": pitch_inertia(model, torso),
        "torso_com_x": float(model.body_ipos[torso, 0]),
        "torso_com_z": float(model.body_ipos[torso, 2]),
        "wheel_inertia": pitch_inertia(model, wheel) + armature,
        "wheel_armature": armature,
        "motor_torque": 1.0,
        "motor_damping": 1.0,
        "friction": float(model.geom_friction[model.geom("foot_L").id, 0]),
        "gyro_bias": 0.0,
    }


def wheel_split(nominal: dict[str, float], values: dict[str, float]) -> tuple[float, float]:
    """(armature, the wheel body's spin inertia), kg m^2: wheel_inertia is their sum; without a
    wheel_armature of its own the armature keeps its nominal share of it."""
    total = values.get("wheel_inertia", nominal["wheel_inertia"])
    share = nominal["wheel_armature"] / nominal["wheel_inertia"]
    armature = values.get("wheel_armature", share * total)
    return armature, max(total - armature, 1e-9)


class Robot:
    """A compiled model whose identifiable parameters are set from its nominal ones (in place)."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.base = Nominal.of(model)
        self.nominal = nominal(model)
        self._torso, self._wheel = model.body("torso").id, model.body("wheel").id
        self._dof = int(model.jnt_dofadr[model.joint("wheel").id])
        self._motor = model.actuator("wheel").id

    def set(self, values: dict[str, float]) -> None:
        """Back to nominal, then these values (any subset of PARAMS)."""
        m, b, n = self.model, self.base, self.nominal
        v = n | values
        for f in dataclasses.fields(b):
            getattr(m, f.name)[:] = getattr(b, f.name)
        t, w, a = self._torso, self._wheel, self._motor
        m.body_mass[t] = v["torso_mass"]
        m.body_inertia[t] = b.body_inertia[t] * (v["torso_inertia"] / n["torso_inertia"])
        m.body_ipos[t, 0], m.body_ipos[t, 2] = v["torso_com_x"], v["torso_com_z"]
        arm, spin = wheel_split(n, values)
        m.body_inertia[w] = b.body_inertia[w] * (spin / (n["wheel_inertia"] - n["wheel_armature"]))
        m.dof_armature[self._dof] = arm
        k, d = v["motor_torque"], v["motor_damping"]
        m.actuator_gainprm[a, 0] = b.actuator_gainprm[a, 0] * k
        m.actuator_forcerange[a] = b.actuator_forcerange[a] * k
        m.actuator_biasprm[a, 2] = b.actuator_biasprm[a, 2] * k * k * d
        m.geom_friction[:, 0] = b.geom_friction[:, 0] * (v["friction"] / n["friction"])
        mujoco.mj_setConst(m, mujoco.MjData(m))  # masses changed: subtree masses and the like follow


TRIANGLE_MARGIN = 1e-5  # share of the largest moment by which the other two exceed it, at least


def _triangle(moments: np.ndarray) -> np.ndarray:
    """Principal moments that keep A + B >= C once MJCF's 6 digits have rounded them: a thin disc (the
    wheel: A = B = C / 2) sits on that bound, and a rounding below it is refused by the compiler.
    The two smaller moments (about the axes out of the robot's plane) grow by what it takes."""
    d = np.array(moments, dtype=float)
    k = int(np.argmax(d))
    short = d[k] * (1.0 + TRIANGLE_MARGIN) - (d.sum() - d[k])
    if short > 0.0:
        d[[i for i in range(3) if i != k]] += short / 2.0
    return d


def to_spec(spec: mujoco.MjSpec, model: mujoco.MjModel, values: dict[str, float]) -> mujoco.MjSpec:
    """Write `values` into `spec` (the MJCF `model` was compiled from), as Robot.set does to the model;
    the gyro's bias goes in a <numeric name="gyro_bias"> (rad/s): MuJoCo's sensors have no bias."""
    n = nominal(model)
    v = n | values
    torso, wheel = spec.body("torso"), spec.body("wheel")
    torso.mass = v["torso_mass"]
    torso.inertia = _triangle(np.asarray(torso.inertia) * (v["torso_inertia"] / n["torso_inertia"]))
    torso.ipos = [v["torso_com_x"], torso.ipos[1], v["torso_com_z"]]
    arm, spin = wheel_split(n, values)
    wheel.inertia = _triangle(np.asarray(wheel.inertia) * (spin / (n["wheel_inertia"] - n["wheel_armature"])))
    spec.joint("wheel").armature = arm
    motor = spec.actuator("wheel")
    k, d = v["motor_torque"], v["motor_damping"]
    gain, bias = np.array(motor.gainprm), np.array(motor.biasprm)
    gain[0] *= k
    bias[2] *= k * k * d
    motor.gainprm, motor.biasprm = gain, bias
    motor.forcerange = np.asarray(motor.forcerange) * k
    ratio = v["friction"] / n["friction"]
    for geom in spec.geoms:
        friction = np.array(geom.friction)
        friction[0] *= ratio
        geom.friction = friction
    existing = [x for x in spec.numerics if x.name == "gyro_bias"]
    numeric = existing[0] if existing else spec.add_numeric(name="gyro_bias")
    numeric.data = [math.radians(v["gyro_bias"])]
    return spec


@dataclasses.dataclass(frozen=True)
class Estimate:
    name: str
    unit: str
    nominal: float
    value: float
    sigma: float  # 1 sigma of the linearised fit (a lower bound: see the module's docstring)


@dataclasses.dataclass(frozen=True)
class Fit:
    """What identify found: the estimates, their correlations, and the fit's residuals (RMS, in CHANNELS'
    units) before (the model it started from) and after, both over the last stage's windows."""

    estimates: tuple[Estimate, ...]
    correlation: np.ndarray  # (p, p)
    residual_before: dict[str, float]
    residual_after: dict[str, float]
    evaluations: int  # simulations of the whole span
    seconds: float
    windows: int
    message: str  # the optimiser's
    # A line-searched parameter's profile range (hopper.logs.sysid.line_search), its own units: the
    # measure of its uncertainty where the Jacobian's sigma is blind (friction).
    profile: dict[str, tuple[float, float]] = dataclasses.field(default_factory=dict)

    @property
    def values(self) -> dict[str, float]:
        return {e.name: e.value for e in self.estimates}

    def not_separable(self) -> list[tuple[str, str, float]]:
        """Pairs whose estimates correlate beyond NOT_SEPARABLE, with the correlation."""
        names, c = [e.name for e in self.estimates], self.correlation
        return [
            (names[i], names[j], float(c[i, j]))
            for i in range(len(names))
            for j in range(i + 1, len(names))
            if abs(c[i, j]) >= NOT_SEPARABLE
        ]

    def combined(self, names: Sequence[str]) -> tuple[float, float]:
        """The sum of these estimates (same unit) and its sigma, correlations included."""
        idx = [i for i, e in enumerate(self.estimates) if e.name in names]
        sig = np.array([self.estimates[i].sigma for i in idx])
        cov = self.correlation[np.ix_(idx, idx)] * np.outer(sig, sig)
        return float(sum(self.estimates[i].value for i in idx)), float(math.sqrt(max(cov.sum(), 0.0)))


def hop_span(log: Log, first: int, count: int) -> tuple[int, int]:
    """Rows from the liftoff of hop `first` (0-based) to the liftoff after hop first+count-1."""
    spans = hops(log)
    if len(spans) < first + count:
        asked = f"hops {first + 1}..{first + count}"
        raise IdentifyError(f"{log.source}: has {len(spans)} hop(s), the fit asks for {asked}")
    return spans[first][0], spans[first + count - 1][1]


class Problem:
    """The residuals of a model against a log over windows, as a function of the fitted parameters."""

    def __init__(
        self,
        robot: Robot,
        log: Log,
        spans: list[tuple[int, int]],
        names: Sequence[str],
        delay_ticks: int,
        drive: robots.Robot = robots.PACKAGED,  # the motor the log's commands were made for (replay.simulate)
    ):
        unknown = [n for n in names if n not in PARAMS]
        if unknown:
            raise IdentifyError(f"unknown parameter(s) {', '.join(unknown)}; choose from {', '.join(PARAMS)}")
        if not names:
            raise IdentifyError("no parameter to fit")
        twice = sorted({n for n in names if list(names).count(n) > 1})
        if twice:  # Problem.values keeps the last column: the first has no effect (a zero Jacobian column)
            raise IdentifyError(f"parameter(s) {', '.join(twice)} given more than once")
        self.robot, self.log, self.spans, self.names, self.delay = robot, log, spans, tuple(names), delay_ticks
        self.drive = drive
        self.data = mujoco.MjData(robot.model)
        n = robot.nominal
        self.nominal = np.array([n[k] for k in self.names])
        self.scale = np.array([PARAMS[k].scale(n[k]) or 1.0 for k in self.names])
        lo, hi = zip(*(PARAMS[k].bounds(n[k]) for k in self.names), strict=True)
        self.lower, self.upper = (np.array(lo) - self.nominal) / self.scale, (np.array(hi) - self.nominal) / self.scale
        self.physical = [k != "gyro_bias" for k in self.names]
        rows = np.concatenate([np.arange(a, b) for a, b in spans])
        s = log.signals
        self.measured = {c: s[c][rows] for c in CHANNELS}
        self.true_rate = s["pitch_rate"][rows]  # the state's: what the gyro measures, bias aside
        self.evaluations = 0
        self._cache: tuple[bytes, np.ndarray] | None = None

    def values(self, z: np.ndarray) -> dict[str, float]:
        return dict(zip(self.names, (self.nominal + z * self.scale).tolist(), strict=True))

    def simulated(self, values: dict[str, float]) -> dict[str, np.ndarray]:
        self.robot.set({k: v for k, v in values.items() if k != "gyro_bias"})
        self.evaluations += 1
        parts = [
            simulate(self.robot.model, self.log, a, b, delay_ticks=self.delay, data=self.data, drive=self.drive).signals
            for a, b in self.spans
        ]
        return {c: np.concatenate([p[c] for p in parts]) for c in CHANNELS if c != "gyro_pitch"}

    def residuals(self, z: np.ndarray) -> np.ndarray:
        key = z.tobytes()
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        values = self.values(z)
        sim = self.simulated(values)
        parts = []
        for c, scale in CHANNELS.items():
            if c == "gyro_pitch":
                predicted = self.true_rate + math.radians(values.get("gyro_bias", 0.0))
                parts.append((self.measured[c] - predicted) / scale)
            else:
                parts.append((sim[c] - self.measured[c]) / scale)
        r = np.nan_to_num(np.concatenate(parts), nan=DIVERGED, posinf=DIVERGED, neginf=-DIVERGED)
        self._cache = (key, r)
        return r

    def jacobian(self, z: np.ndarray, step: float = 1e-3) -> np.ndarray:
        r0 = self.residuals(z)
        jac = np.zeros((r0.size, z.size))
        for i, physical in enumerate(self.physical):
            if physical:
                dz = step if z[i] + step <= self.upper[i] else -step
                moved = z.copy()
                moved[i] += dz
                jac[:, i] = (self.residuals(moved) - r0) / dz
            else:  # the gyro bias: d(measured - rate - bias)/d bias, on the gyro's rows only
                n = r0.size // len(CHANNELS)
                gyro = list(CHANNELS).index("gyro_pitch")
                jac[gyro * n : (gyro + 1) * n, i] = -math.radians(self.scale[i]) / CHANNELS["gyro_pitch"]
        self._cache = (z.tobytes(), r0)
        return jac

    def channel_rms(self, r: np.ndarray) -> dict[str, float]:
        per = r.reshape(len(CHANNELS), -1)
        return {c: float(np.sqrt(np.mean(per[i] ** 2)) * scale) for i, (c, scale) in enumerate(CHANNELS.items())}


def _least_squares(problem: Problem, z: np.ndarray, max_evaluations: int):  # noqa: ANN202 (scipy's result)
    from scipy.optimize import least_squares  # here: scipy.optimize took a third of every hopper-sim start

    return least_squares(
        problem.residuals,
        np.clip(z, problem.lower, problem.upper),
        jac=problem.jacobian,
        bounds=(problem.lower, problem.upper),
        method="trf",
        x_scale=1.0,
        max_nfev=max_evaluations,
    )


GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0
SCAN = 2.0 ** np.linspace(-1.5, 1.0, 11)  # the scan's factors of the value found so far
REFINE = 16  # golden-section steps after the scan: the bracket shrinks to 0.05 % of its width
# The line search's windows, s: so short that a foot's slip or stick changes little within one, the
# friction's cost is unimodal there (on the round trip: it is at 0.03 s, it is not at 0.1 s).
SCAN_WINDOW_S = 0.03
PROFILE_SIGMAS = 2.0  # the line search's profile range: a cost within 2^2 residual variances of its least


def line_search(problem: Problem, z: np.ndarray, i: int) -> tuple[np.ndarray, tuple[float, float]]:
    """(z with its i-th parameter moved to the least cost along its axis, the profile range): a scan
    over factors 0.35 to 2 of its value, then golden-section steps between the best point's
    neighbours. For a parameter whose effect is piecewise (friction: a foot slips or sticks), where
    least squares' local model is blind between a window's slip and its stick, and its Jacobian's
    sigma says nothing. The profile range spans the values tried whose cost is within PROFILE_SIGMAS^2
    residual variances of the least (the others held): where the feet never slip it is wide."""
    tried: list[tuple[float, float]] = []

    def at(value: float) -> np.ndarray:
        moved = z.copy()
        moved[i] = (value - problem.nominal[i]) / problem.scale[i]
        return np.clip(moved, problem.lower, problem.upper)

    def cost(value: float) -> float:
        r = problem.residuals(at(value))
        tried.append((float(r @ r), value))
        return tried[-1][0]

    value = float(problem.nominal[i] + z[i] * problem.scale[i])
    grid = value * SCAN
    costs = [cost(v) for v in grid]
    k = int(np.argmin(costs))
    a, b = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    c, d = b - GOLDEN * (b - a), a + GOLDEN * (b - a)
    fc, fd = cost(c), cost(d)
    for _ in range(REFINE):
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - GOLDEN * (b - a)
            fc = cost(c)
        else:
            a, c, fc = c, d, fd
            d = a + GOLDEN * (b - a)
            fd = cost(d)
    least, best = min(tried)
    variance = least / max(problem.residuals(at(best)).size - len(z), 1)
    inside = [v for f, v in tried if f <= least + PROFILE_SIGMAS**2 * variance]
    return at(best), (min(inside), max(inside))


def identify(
    model: mujoco.MjModel,
    log: Log,
    span: tuple[int, int],
    names: Sequence[str] = DEFAULT_FIT,
    *,
    stages: Sequence[float] = STAGES,
    delay_ticks: int = DEFAULT_DELAY_TICKS,
    max_evaluations: int = 60,
    progress: Callable[[str], None] | None = None,
    drive: robots.Robot = robots.PACKAGED,
) -> Fit:
    """Fit `names` (PARAMS) of `model` (compiled in the log's world; left at the estimates) to rows
    span[0]..span[1] of `log`: one least-squares fit per window length of `stages` (s), each from
    the last one's estimate (short windows first: their cost is smooth where a contact's slip or
    stick makes a long window's rugged; long ones last, for their sensitivity). `progress`, if
    given, is told as each stage starts (a fit takes minutes). The replays' drive inverts `drive`, the
    motor the log's commands were made for (hopper.logs.world.World.drive), whatever motor the
    candidate model has: the candidate's motor is then what turns the commands into torque, and
    motor_torque is its k_t against `model`'s."""
    started = clock.perf_counter()

    def announce(what: str) -> None:
        if progress is not None:
            progress(f"{what} ({clock.perf_counter() - started:.0f} s in)")

    if not log.has_state():
        raise ReplayError(f"{log.source}: identification replays from the log's state, and it has none")
    if not stages or any(w <= 0 for w in stages):
        raise IdentifyError(f"window lengths must be positive seconds, got {list(stages)}")
    if max_evaluations < 1:  # scipy's least_squares takes no max_nfev below 1
        raise IdentifyError(f"max_evaluations must be at least 1, got {max_evaluations}")
    robot = Robot(model)
    profile: dict[str, tuple[float, float]] = {}
    evaluations = 0  # of the stages before the last
    start = {}  # the flights' estimates, where the stages begin
    aloft = [(a, min(b, span[1])) for a, b in flights(log) if span[0] <= a < span[1]]
    airborne = [w for flight in aloft for w in windows(log, flight, FLIGHT_WINDOW_S)]
    free = [n for n in names if n != "friction"]
    if "friction" in names and free and airborne:
        # Without a contact nothing is piecewise: the torso and the wheel are fitted on the flights
        # first, so that friction, on the stances, does not soak up their errors (a torso mass 2 %
        # and a CoM 20 % off once made friction +15 %).
        announce(f"fitting {', '.join(free)} on {len(airborne)} windows in flight first")
        flying = Problem(robot, log, airborne, free, delay_ticks, drive)
        start = flying.values(_least_squares(flying, np.zeros(len(free)), max_evaluations).x)
        evaluations += flying.evaluations
    for i, window_s in enumerate(stages):
        spans = windows(log, span, window_s)
        if not spans:
            raise IdentifyError(f"{log.source}: rows {span[0]}..{span[1]} hold no window of {window_s:g} s")
        announce(f"stage {i + 1} of {len(stages)}: {len(spans)} windows of {window_s:g} s")
        problem = Problem(robot, log, spans, names, delay_ticks, drive)
        if i == 0:
            pairs = zip(problem.names, problem.nominal, problem.scale, strict=True)
            z = np.array([(start.get(k, n) - n) / c for k, n, c in pairs])
        result = _least_squares(problem, z, max_evaluations)
        if "friction" in problem.names:  # its cost is rugged (slip or stick): a line search, then LM again
            short = Problem(robot, log, windows(log, span, SCAN_WINDOW_S), names, delay_ticks, drive)
            z, profile["friction"] = line_search(short, result.x, problem.names.index("friction"))
            evaluations += short.evaluations
            result = _least_squares(problem, z, max_evaluations)
        z = result.x
        if i < len(stages) - 1:
            evaluations += problem.evaluations
    # Before and after on the same windows, the last stage's: the first stage's short windows hold
    # less error than its long ones, and a ratio across the two said nothing.
    before = problem.channel_rms(problem.residuals(np.zeros(len(problem.names))))
    r = problem.residuals(z)
    jac = problem.jacobian(z)
    evaluations += problem.evaluations
    dof = max(r.size - z.size, 1)
    s2 = float(r @ r) / dof
    cov = np.linalg.pinv(jac.T @ jac) * s2
    sigma_z = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = np.nan_to_num(cov / np.outer(sigma_z, sigma_z))
    values = problem.values(z)
    robot.set({k: v for k, v in values.items() if k != "gyro_bias"})
    estimates = tuple(
        Estimate(k, PARAMS[k].unit, float(problem.nominal[i]), values[k], float(sigma_z[i] * problem.scale[i]))
        for i, k in enumerate(problem.names)
    )
    return Fit(
        estimates,
        corr,
        before,
        problem.channel_rms(r),
        evaluations,
        clock.perf_counter() - started,
        len(spans),
        str(result.message),
        profile,
    )


def replay_error(
    model: mujoco.MjModel,
    log: Log,
    first: int,
    count: int,
    delay_ticks: int = DEFAULT_DELAY_TICKS,
    every: float | None = None,
    servo: bool = False,
    drive: robots.Robot = robots.PACKAGED,
) -> Errors:
    """The replay error of hops first..first+count-1, each from its liftoff: whole, or re-anchored on
    the log's state every `every` s, the legs held to the log's angles with `servo`
    (hopper.logs.replay.replay_hops), the commands through `drive`'s motor."""
    parts = replay_hops(
        model, log, count, first=first, delay_ticks=delay_ticks, every=every, servo=servo, drive=drive
    )  # fmt: skip
    return Errors.concat([e for _, e in parts])
