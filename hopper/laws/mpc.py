"""Model-predictive flight wheel law: plan the rest of the flight to land level and still, with OSQP."""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
import time
from collections import deque

import control as ct
import numpy as np
import osqp
import scipy.sparse as sp

from hopper.config import WHEEL_TORQUE_LIMIT, SimConfig
from hopper.controllers.api import ControllerContext, ControllerError, Observation, Param
from hopper.laws.plant import AttitudeModel, attitude_model
from hopper.layout import ModelLayout
from hopper.robot import PACKAGED, Robot

INF = math.inf
SLACK_PRICE = 100.0  # cost per rad/s of wheel speed over its limit (exact penalty: zero whenever feasible)
SLACK_WEIGHT = 1.0  # quadratic on the same slack, so that P has no zero on it


def state_scale(robot: Robot) -> tuple[float, float, float]:
    """The states' natural sizes: 1 deg, 10 deg/s and the wheel's top speed (rad, rad/s, rad/s)."""
    return (math.radians(1.0), math.radians(10.0), robot.wheel_no_load_speed)


def jump(robot: Robot) -> tuple[float, float, float]:
    """Off the plan by this much (pitch rad, rate rad/s, wheel speed rad/s), the state was kicked: the
    plan is dropped and the gain flies alone for recover_ms, until the legs have caught up with the
    torso (the model's premise)."""
    return (math.radians(2.0), math.radians(30.0), 0.2 * robot.wheel_no_load_speed)


NO_TIME_LIMIT = 1e10  # s: OSQP's own default, i.e. none
MAX_BACKOFF = 8  # replan periods at most between failed solves
STATS_KEPT = 2000  # solves whose time and iterations stats() sums up
REG = 1e-6  # (scaled) on what the cost leaves free (rate, wheel speed): P stays positive definite
# The fast loop's gain: the built-in LQR's (Bryson tolerances on hopper.laws.plant's 1 ms model, which
# is right at the loop's frequencies: there the legs' servos do not follow and the torso is light).
# (The wheel speed's and the torque's tolerances are the plant's wheel's top speed and stall torque.)
ANCILLARY_TOL = (math.radians(2.0), math.radians(40.0))
RHO = 3e-3  # ADMM's step at the start of each solve (tuned on recorded flights: 15 iterations a replan)
OSQP_SETTINGS = dict(  # noqa: C408 (the solver's names)
    verbose=False,
    warm_starting=True,
    polishing=False,
    eps_abs=1e-3,  # in each row's natural units (1 deg, 10 deg/s, top speed, stall torque)
    eps_rel=1e-3,
    # A replan takes 15 iterations (~0.3 ms); with the wheel at its top speed for long, ADMM crawls
    # (hundreds): past this the replan fails and falls back, and the next ones back off (MAX_BACKOFF).
    max_iter=400,
    alpha=1.4,
    rho=RHO,
    # Adaptive on a count of iterations (OSQP 1.x's mode 1; not its time-based mode, which differs
    # from run to run), and set back to RHO before a solve when the last one moved it: a solve is
    # then a function of its data and its warm start alone, so runs and re-flies from snapshots
    # repeat exactly. A fixed step took 2000 iterations after a kick; this, under 300.
    adaptive_rho=1,
    adaptive_rho_interval=25,
    check_termination=5,
)


@dataclasses.dataclass(frozen=True)
class PredictionModel:
    """x[k+1] = a x[k] + b tau[k] at dt, x = (pitch rad, rate rad/s, wheel speed rad/s), tau in N m."""

    a: np.ndarray  # (3, 3)
    b: np.ndarray  # (3,)
    dt: float  # s
    robot: Robot = PACKAGED  # whose wheel: its top speed, stall torque and back-EMF slope

    def held(self, ticks: int) -> tuple[np.ndarray, np.ndarray]:
        """The model over `ticks` steps with the input held: (a^m, sum_i a^i b)."""
        a, b = np.eye(3), np.zeros(3)
        for _ in range(ticks):
            a, b = self.a @ a, self.a @ b + self.b
        return a, b


def prediction_model(config: SimConfig, layout: ModelLayout) -> PredictionModel:
    """The flight's attitude plant with the legs' servos at their quasi-steady state (residualised).

    hopper.laws.plant's model keeps the rows of pitch, rate and wheel speed and drops the legs' states,
    which holds the leg joints still: the hip servos then look like a spring that returns the torso
    by itself. That is right for the first tens of ms (the LQR's loop lives there) but not over a
    flight: under a 3 N m step it predicts a third of the pitch the simulation shows after 0.2 s. Here
    the legs' joint states are solved for the steady state their servos reach from the torso's state
    and the torque, x_f = (I - A_ff)^-1 (A_fs x + B_f tau), and put back in the attitude rows: the
    torso then turns with the inertia it has in flight (about 0.55 kg m^2), as the full plant and the
    simulation do. The free states (x, z, their speeds, the wheel's angle) are held at zero.
    """
    key = SimConfig(
        gravity=config.gravity, gait=config.gait, timestep=config.timestep, terrain="flat", model=config.model
    )
    return _prediction_model(key, layout.v_legs)


@functools.lru_cache(maxsize=16)
def _prediction_model(config: SimConfig, legs: tuple[int, ...]) -> PredictionModel:
    model = attitude_model(config)
    full = model.full
    nv = model.states[1] - model.states[0]  # states = (v_pitch, nv + v_pitch, nv + v_wheel)
    slow = list(model.states)
    fast = [*legs, *(nv + i for i in legs)]
    a, b = full.a, full.b[:, 0]
    a_ff = a[np.ix_(fast, fast)]
    steady = np.linalg.solve(np.eye(len(fast)) - a_ff, np.c_[a[np.ix_(fast, slow)], b[fast]])
    a_r = a[np.ix_(slow, slow)] + a[np.ix_(slow, fast)] @ steady[:, :3]
    b_r = b[slow] + a[np.ix_(slow, fast)] @ steady[:, 3]
    return PredictionModel(a_r, b_r, model.dt, model.full.robot)


def step_grid(step_ticks: int, growth: float, horizon_ticks: int) -> np.ndarray:
    """Ticks of each coarse step, the first furthest from the touchdown: the last is `step_ticks`
    long and each one before it `growth` times its successor (rounded), until `horizon_ticks`."""
    ticks: list[int] = []
    length = float(step_ticks)
    while sum(ticks) < horizon_ticks:
        ticks.append(max(1, round(length)))
        length *= growth
    return np.array(ticks[::-1], dtype=int)


@dataclasses.dataclass
class Plan:
    """A solved plan from the replan on: each coarse step's held torque and length."""

    torques: list[float]  # N m
    ticks: list[int]  # control ticks of each step


@dataclasses.dataclass(frozen=True)
class Solution:
    """A plan as the QP found it (SI): n steps from the replan to the touchdown."""

    states: np.ndarray  # (n + 1, 3) pitch rad, rate rad/s, wheel speed rad/s at each step's start, then touchdown
    torques: np.ndarray  # (n,) N m, held over each step
    slacks: np.ndarray  # (n + 1,) rad/s of wheel speed over its limit
    ticks: np.ndarray  # (n,) control ticks of each step


class QP:
    """The fixed-size QP, built once per structure (grid, weights); a replan changes vectors only.

    Variables z = (x_0 .. x_N, u_0 .. u_{N-1}, s_0 .. s_N): the states (3 each) at the steps' starts,
    the torques held over them, the wheel-speed slacks; each scaled by its natural size. x_N is at
    the touchdown (or at the horizon's end while the touchdown is further). Steps are fine near the
    touchdown, where the landing is decided, and longer further back (`step_grid`).

    A replan that leaves n steps to the touchdown pins x_{N-n} to the measured state and relaxes
    every row of the steps before it: those variables are then decoupled, free and at zero cost. So
    the horizon shrinks on a fixed P and A (OSQP's factorisation keeps its pattern, only l and u
    change), and the previous solution, indexed from the touchdown, is a warm start as it stands.
    """

    def __init__(
        self, model: PredictionModel, ticks: np.ndarray, weights: tuple[float, ...], deadline_s: float = NO_TIME_LIMIT
    ) -> None:
        n = self.steps = int(ticks.size)
        self.ticks = ticks
        robot = model.robot
        top, stall, damping, scale = (
            robot.wheel_no_load_speed,
            robot.wheel_torque_limit,
            robot.wheel_damping,
            state_scale(robot),
        )
        self.dt = model.dt
        self.remaining = np.cumsum(ticks[::-1])[::-1] * model.dt  # s from each step's start to touchdown
        held = {int(m): model.held(int(m)) for m in set(ticks.tolist())}
        self.a = [held[int(m)][0] for m in ticks]
        self.b = [held[int(m)][1] for m in ticks]
        h = ticks * model.dt
        pitch_w, torque_w, land_pitch_w, land_rate_w = weights
        nx = 3 * (n + 1)
        self.iu = nx
        nz = self.nz = nx + n + (n + 1)
        # Each variable in units of its natural size (1 deg, 10 deg/s, top speed, stall torque): the
        # weights span ten decades in SI units, and ADMM converges slowly on a badly scaled problem.
        self.scale = np.concatenate([np.tile(scale, n + 1), np.full(n, stall), np.full(n + 1, top)])
        self.var_step = np.concatenate([np.repeat(np.arange(n + 1), 3), np.arange(n), np.arange(n + 1)])
        p = np.zeros(nz)
        p[0 : 3 * n : 3] = h * pitch_w  # the pitch integrated over each step, from its start
        p[3 * n] = land_pitch_w
        p[3 * n + 1] = land_rate_w
        p[nx : nx + n] = h * torque_w
        p[nx + n :] = SLACK_WEIGHT
        self.p = np.maximum(p * self.scale**2, REG)  # P's diagonal, scaled
        self.P = sp.diags(self.p, format="csc")
        self.q = np.zeros(nz)
        self.q[nx + n :] = SLACK_PRICE * top

        blocks: list[sp.spmatrix] = []
        step_of: list[np.ndarray] = []  # the step whose rows they are: relaxed before the pin; -1 never
        lo: list[np.ndarray] = []
        hi: list[np.ndarray] = []
        sizes: list[np.ndarray] = []  # each row's natural size (SI): rows are divided by it

        def add(block: sp.spmatrix, steps_of: np.ndarray, low: np.ndarray, high: np.ndarray, size: object) -> int:
            first_row = sum(r.shape[0] for r in blocks)
            blocks.append(sp.csr_matrix(block))
            step_of.append(steps_of)
            lo.append(low)
            hi.append(high)
            sizes.append(np.resize(np.asarray(size, dtype=float), block.shape[0]))
            return first_row

        # Dynamics: a_k x_k + b_k u_k - x_{k+1} = 0.
        dyn = sp.lil_matrix((3 * n, nz))
        for k in range(n):
            dyn[3 * k : 3 * k + 3, 3 * k : 3 * k + 3] = self.a[k]
            dyn[3 * k : 3 * k + 3, nx + k] = self.b[k].reshape(3, 1)
            dyn[3 * k : 3 * k + 3, 3 * k + 3 : 3 * k + 6] = -np.eye(3)
        self.row_dyn = add(dyn, np.repeat(np.arange(n), 3), np.zeros(3 * n), np.zeros(3 * n), scale)
        # The states themselves: free, but the pinned step's are the measurement.
        self.row_pin = add(sp.eye(nx, nz), np.full(nx, -1), np.full(nx, -INF), np.full(nx, INF), scale)
        # Wheel speed within its limit, softened: w_k - s_k <= w_max and w_k + s_k >= -w_max.
        spd = sp.lil_matrix((2 * (n + 1), nz))
        for k in range(n + 1):
            spd[2 * k, 3 * k + 2], spd[2 * k, nx + n + k] = 1.0, -1.0
            spd[2 * k + 1, 3 * k + 2], spd[2 * k + 1, nx + n + k] = 1.0, 1.0
        limits = np.tile([-INF, -top, top, INF], n + 1).reshape(-1, 4)
        self.row_speed = add(spd, np.repeat(np.arange(n + 1), 2), limits[:, :2].ravel(), limits[:, 2:].ravel(), top)
        # Slacks are never negative.
        self.row_slack = add(
            sp.hstack([sp.csr_matrix((n + 1, nx + n)), sp.eye(n + 1)]),
            np.full(n + 1, n + 1),  # always active
            np.zeros(n + 1),
            np.full(n + 1, INF),
            top,
        )
        # The motor's envelope, -T <= u + D w <= T at both ends of each step (w moves within it), |u| <= T.
        env = sp.lil_matrix((3 * n, nz))
        for k in range(n):
            env[3 * k, nx + k], env[3 * k, 3 * k + 2] = 1.0, damping
            env[3 * k + 1, nx + k], env[3 * k + 1, 3 * k + 5] = 1.0, damping
            env[3 * k + 2, nx + k] = 1.0
        limit = np.full(3 * n, stall)
        self.row_env = add(env, np.repeat(np.arange(n), 3), -limit, limit, stall)

        # Rows in natural units too: OSQP's tolerances then mean the same thing in every row.
        self.row_scale = 1.0 / np.concatenate(sizes)
        self.A = (sp.diags(self.row_scale) @ sp.vstack(blocks, format="csc") @ sp.diags(self.scale)).tocsc()
        self.step_of = np.concatenate(step_of)
        self.l_active = np.concatenate(lo)
        self.u_active = np.concatenate(hi)
        self.speed_rows = slice(self.row_speed, self.row_speed + 2 * (n + 1))
        self._riccati()
        self.solver = osqp.OSQP()
        self.solver.setup(self.P, self.q, self.A, *self._relaxed(0), **OSQP_SETTINGS, time_limit=deadline_s)

    # -- the replan's data --------------------------------------------------------------------
    def first_step(self, time_to_touchdown: float) -> int | None:
        """The step to pin for this much time left: the one whose start is nearest to now, 0 if
        the touchdown is beyond the horizon, None in the last half step (no plan is left to make)."""
        if time_to_touchdown < 0.5 * self.ticks[-1] * self.dt:
            return None
        return int(np.argmin(np.abs(self.remaining - time_to_touchdown)))

    def _relaxed(self, first: int) -> tuple[np.ndarray, np.ndarray]:
        active = self.step_of >= first
        return np.where(active, self.l_active, -INF), np.where(active, self.u_active, INF)

    def bounds(self, first: int, x0: np.ndarray, speed_limit: float) -> tuple[np.ndarray, np.ndarray]:
        """l and u for a plan whose step `first` starts at the measured state x0 (SI)."""
        self.l_active[self.speed_rows][1::2] = -speed_limit
        self.u_active[self.speed_rows][0::2] = speed_limit
        lo, hi = self._relaxed(first)
        pin = slice(self.row_pin + 3 * first, self.row_pin + 3 * first + 3)
        lo[pin] = x0
        hi[pin] = x0
        return lo * self.row_scale, hi * self.row_scale

    # -- warm starts --------------------------------------------------------------------------
    def warm(self, x: np.ndarray, y: np.ndarray, was: int, first: int) -> tuple[np.ndarray, np.ndarray]:
        """The previous solution (pinned at step `was`) as a warm start for one pinned at `first`.

        The steps before `first` are decoupled and free at zero cost: their optimum is zero, and
        so are their rows' multipliers; ADMM would take a hundred iterations to find that. The new
        pin takes the multiplier of the dynamics row it replaces (the costate of x_first).
        """
        x, y = x.copy(), y.copy()
        if first > was:
            x[self.var_step < first] = 0.0
            costate = -y[self.row_dyn + 3 * (first - 1) : self.row_dyn + 3 * first]
            y[(self.step_of >= 0) & (self.step_of < first)] = 0.0
            y[self.row_pin : self.row_pin + 3 * (self.steps + 1)] = 0.0
            y[self.row_pin + 3 * first : self.row_pin + 3 * first + 3] = costate
        return x, y

    def _riccati(self) -> None:
        """The QP's own cost without its inequalities: a time-varying LQR, for cold starts."""
        n, s = self.steps, self.scale
        q = (self.p / s**2)[: 3 * (n + 1)].reshape(n + 1, 3)  # SI state weights per step
        r = (self.p / s**2)[self.iu : self.iu + n]
        cost = np.diag(q[n])
        gains = [np.zeros(3)] * n
        for k in range(n - 1, -1, -1):
            a, b = self.a[k], self.b[k]
            pb = cost @ b
            gains[k] = -(pb @ a) / (r[k] + b @ pb)
            closed = a + np.outer(b, gains[k])
            cost = np.diag(q[k]) + gains[k][:, None] * r[k] * gains[k][None, :] + closed.T @ cost @ closed
        self.lqr_gains, self.state_weights = gains, q

    def guess(self, first: int, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A cold start: the unconstrained optimum from x0 (the time-varying LQR rolled out) and its
        multipliers (the costates, from the stationarity of the Lagrangian, P z + q + A' y = 0)."""
        n = self.steps
        xs, us = np.zeros((n + 1, 3)), np.zeros(n)
        xs[first] = x0
        for k in range(first, n):
            us[k] = self.lqr_gains[k] @ xs[k]
            xs[k + 1] = self.a[k] @ xs[k] + self.b[k] * us[k]
        z = np.zeros(self.nz)
        z[first * 3 : 3 * (n + 1)] = xs[first:].ravel()
        z[self.iu + first : self.iu + n] = us[first:]
        y_si = np.zeros(self.A.shape[0])
        q = self.state_weights
        costate = q[n] * xs[n]  # the multiplier of the dynamics row into x_{k+1}
        for k in range(n - 1, first - 1, -1):
            y_si[self.row_dyn + 3 * k : self.row_dyn + 3 * k + 3] = costate
            costate = q[k] * xs[k] + self.a[k].T @ costate
        y_si[self.row_pin + 3 * first : self.row_pin + 3 * first + 3] = -costate
        y_si[self.row_slack : self.row_slack + n + 1] = -SLACK_PRICE  # the slacks rest on their bound
        return z / self.scale, y_si / self.row_scale


class MPC:
    """A predictive wheel law over the rest of the flight: land level and still at the predicted
    touchdown, spending little torque, within the motor's envelope and the wheel's top speed.

    The plan. Every `replan_ms` a QP is solved from the measured state to the touchdown
    (obs.time_to_touchdown, rounded to the nearest step) on a coarse grid: `step_ms` steps at the
    touchdown, each step before it `step_growth` times longer, over `horizon` nominal flights (while
    the touchdown is further, the plan aims to be level at the horizon's end, and the horizon
    recedes). Each step is the 1 ms model raised to its length with the torque held.
      cost: at touchdown (pitch / landing_pitch_tol)^2 + (rate / landing_rate_tol)^2, heavy; over
        the flight, integrated, (pitch / pitch_tol)^2 + (torque / torque_scale)^2 (the torque's
        square is the motor's copper loss, most of its energy in flight);
      constraints: the dynamics; -T <= tau + D w <= T at both ends of each step and |tau| <= T (the
        motor's torque-speed envelope, T the stall torque, D its back-EMF slope); |w| <= w_max with
        a slack priced far above any landing error, so the QP is feasible from any state.
    The model is the flight plant with the legs' servos residualised (prediction_model: the
    truncated one hopper.laws.plant gives the LQR mispredicts a flight's pitch threefold).

    Between replans, the plan's move plus a fast correction: tau = u_plan + K (x - x_plan), with
    x_plan the plan's state propagated at 1 ms and K the built-in LQR's gain. Why: the QP cannot be
    solved every 1 ms within budget, and an open-loop move held for 10 ms or more leaves a kick, a
    torque pulse, the legs' swing after apex or sensing noise uncorrected until the next replan.
    The gain closes the 1 kHz loop around the plan (the ancillary law of tube MPC): on the plan it
    adds nothing, off it it pulls back at the LQR's bandwidth, and the next replan starts from the
    measured state. K is designed on hopper.laws.plant's truncated model, which is the right one at
    the loop's frequencies (there the legs' servos do not follow and the torso is light: a gain
    designed on the residualised model rang at 20 deg/s RMS with realistic sensing's delay). In the
    last half step, when no replan is left, after a kick (`recover_ms`) and when every fallback is
    spent, the gain flies alone, without its wheel-speed term: tau = K_pitch pitch + K_rate rate.
    Pulling the wheel back toward rest is the plan's business (its speed enters through the
    envelope); alone, that term fights the pitch correction just when the wheel is spun up (a kick
    at 80 % of the flight landed at 2.0 deg with it, 1.2 deg without; the PID, 1.1 deg).

    Failures. The solver is OSQP 1.x, warm-started with the previous solution (a new flight, or a
    kick: with the unconstrained optimum and its multipliers, from a time-varying LQR), its ADMM
    step set back to RHO before each solve, so that a solve is a function of its data and its warm
    start alone. A solve that does not end `solved` (OSQP's max_iter is the deterministic "too
    slow": about 8 ms) falls back to the previous plan's next moves, or if none is left, to the
    gain alone, and the next replans back off (MAX_BACKOFF); `fallbacks` counts each,
    `stats()` sums the solves up (wall times, iterations, statuses). `solve_deadline_ms` adds
    OSQP's wall-clock time limit, for a deployment where a late plan is a wrong one; it is off by
    default (0) because it makes a run depend on the machine's load: a descheduled solve would
    fall back in one run and not in the next.

    State: numbers and arrays; a snapshot's deep copy leaves the solver behind and the copy builds
    its own at its next call, warm-started from the copied solution: a re-fly repeats the flight.
    """

    params = (
        Param("landing_pitch_tol", 0.1, (0.005, 10.0), "deg"),
        Param("landing_rate_tol", 2.0, (0.05, 200.0), "deg/s"),
        Param("pitch_tol", 5.0, (0.05, 90.0), "deg"),
        Param("torque_scale", WHEEL_TORQUE_LIMIT, (0.5, 300.0), "N m"),
        Param("replan_ms", 10.0, (1.0, 100.0), "ms"),
        Param("step_ms", 20.0, (2.0, 100.0), "ms"),
        Param("step_growth", 1.03, (1.0, 1.3), "x"),
        Param("horizon", 1.25, (0.1, 3.0), "x nominal flight"),
        Param("recover_ms", 30.0, (0.0, 200.0), "ms"),
        Param("solve_deadline_ms", 0.0, (0.0, 100.0), "ms (0: none)"),
    )

    def __init__(self) -> None:
        self.model: PredictionModel | None = None
        self.fallbacks = {"previous_plan": 0, "gain": 0}  # replans that failed, by what flew instead
        self.solves = 0
        self.kicks = 0  # times the state left the plan by more than jump() (the plan dropped, see recover_ms)
        self.solve_times_us: deque[float] = deque(maxlen=STATS_KEPT)  # the last solves' wall times, us
        self.iterations: deque[int] = deque(maxlen=STATS_KEPT)  # and their ADMM iterations
        self.statuses: dict[str, int] = {}
        self._flight_s = 1.0  # s, the nominal flight at this gravity and gait
        self._fast: AttitudeModel | None = None
        self._qp: QP | None = None
        self._built: tuple[float, ...] | None = None
        self._gain = (0.0, 0.0, 0.0)
        self._warm: tuple[np.ndarray, np.ndarray, int] | None = None  # last solution (scaled), its pinned step
        self._plan: Plan | None = None
        self._rho_moved = False  # the last solve adapted ADMM's step
        self._backoff = 1  # replan periods to the next replan: doubled after each failed solve
        self._ticks = 0  # calls since reset
        self._next_replan = 0  # the call at which to replan
        self._nominal = [0.0, 0.0, 0.0]  # the plan's state now
        self._jump = jump(PACKAGED)  # the configured plant's wheel's (configure)
        self._a: list[float] = []  # the 1 ms model as floats, row-major: the tick's arithmetic in plain Python
        self._b: list[float] = []
        self._step = 0  # the plan's step now
        self._step_left = 0  # ticks left in it

    # -- set-up -----------------------------------------------------------------------------
    def configure(self, context: ControllerContext) -> None:
        config = context.config
        self.model = prediction_model(config, ModelLayout.of(context.model))
        self._fast = attitude_model(config)
        self._a, self._b = self.model.a.ravel().tolist(), self.model.b.tolist()
        self._jump = jump(self.model.robot)
        self._flight_s = 2.0 * math.sqrt(2.0 * config.gravity * config.gait.apex_height) / config.gravity
        self._built = None

    def _structure(self) -> tuple[float, ...]:
        return (
            self.landing_pitch_tol,
            self.landing_rate_tol,
            self.pitch_tol,
            self.torque_scale,
            self.step_ms,
            self.step_growth,
            self.horizon,
            self.solve_deadline_ms,
            self._flight_s,
        )

    def build(self) -> None:
        """The QP and the fast gain for the present params and plant; a new plan at the next call.
        ControllerError if it was never configured."""
        if self.model is None or self._fast is None:
            raise ControllerError("MPC needs its plant: it is configured when attached to a simulation")
        robot = self.model.robot
        q = np.diag([1.0 / s**2 for s in (*ANCILLARY_TOL, robot.wheel_no_load_speed)])
        r = np.array([[1.0 / robot.wheel_torque_limit**2]])
        k, _, _ = ct.dlqr(self._fast.a, self._fast.b.reshape(3, 1), q, r)
        self._gain = tuple(float(v) for v in -np.asarray(k).ravel())
        self._qp = self._make_qp()
        self._warm = self._plan = None
        self._built = self._structure()

    def _make_qp(self) -> QP:
        dt = self.model.dt
        ticks = step_grid(
            max(1, round(self.step_ms * 1e-3 / dt)), self.step_growth, round(self.horizon * self._flight_s / dt)
        )
        weights = (
            1.0 / math.radians(self.pitch_tol) ** 2,
            1.0 / self.torque_scale**2,
            1.0 / math.radians(self.landing_pitch_tol) ** 2,
            1.0 / math.radians(self.landing_rate_tol) ** 2,
        )
        deadline = self.solve_deadline_ms * 1e-3 if self.solve_deadline_ms > 0 else NO_TIME_LIMIT
        return QP(self.model, ticks, weights, deadline_s=deadline)

    def __deepcopy__(self, memo: dict) -> MPC:
        """Everything but the solver (a C object): the copy sets up its own at its first call."""
        clone = type(self).__new__(type(self))
        state = {k: v for k, v in self.__dict__.items() if k != "_qp"}
        clone.__dict__.update(copy.deepcopy(state, memo))
        clone._qp = None
        return clone

    # -- the law ----------------------------------------------------------------------------
    def reset(self, obs: Observation) -> None:
        """At liftoff: a new flight, a new plan at the first call."""
        self._plan = None
        self._ticks = 0
        self._next_replan = 0

    def __call__(self, obs: Observation) -> float:
        if self._built != self._structure():
            self.build()
        elif self._qp is None:
            self._qp = self._make_qp()  # a snapshot's copy: the same QP, the copied warm start
        x0, x1, x2 = obs.pitch, obs.rate, obs.wheel_speed
        if self._ticks >= self._next_replan:
            self._next_replan = self._ticks + self._backoff * max(1, round(self.replan_ms * 1e-3 / obs.dt))
            self._replan(obs)
        self._ticks += 1
        k0, k1, k2 = self._gain
        plan = self._plan
        if plan is not None and self._step_left == 0:  # the plan's next step
            self._step += 1
            if self._step < len(plan.ticks):
                self._step_left = plan.ticks[self._step]
            else:
                self._plan = plan = None
        if plan is None:
            return k0 * x0 + k1 * x1
        u = plan.torques[self._step]
        nominal = self._nominal  # updated in place: no allocation on a tick (a GC pass inside a call costs 0.1 s)
        n0, n1, n2 = nominal
        j0, j1, j2 = self._jump
        if abs(x0 - n0) > j0 or abs(x1 - n1) > j1 or abs(x2 - n2) > j2:  # kicked: see the class's docstring
            self.kicks += 1
            self._plan = None
            self._next_replan = self._ticks + max(0, round(self.recover_ms * 1e-3 / obs.dt) - 1)
            return k0 * x0 + k1 * x1
        a, b = self._a, self._b
        nominal[0] = a[0] * n0 + a[1] * n1 + a[2] * n2 + b[0] * u
        nominal[1] = a[3] * n0 + a[4] * n1 + a[5] * n2 + b[1] * u
        nominal[2] = a[6] * n0 + a[7] * n1 + a[8] * n2 + b[2] * u
        self._step_left -= 1
        return u + k0 * (x0 - n0) + k1 * (x1 - n1) + k2 * (x2 - n2)

    def _replan(self, obs: Observation) -> None:
        qp = self._qp
        first = qp.first_step(obs.time_to_touchdown)
        if first is None:
            return  # the last half step: what is left of the plan, then the gain
        x0 = np.array((obs.pitch, obs.rate, obs.wheel_speed))
        solver = qp.solver
        lo, hi = qp.bounds(first, x0, obs.wheel_speed_limit)
        solver.update(l=lo, u=hi)
        if self._plan is not None and self._warm is not None:
            solver.warm_start(*qp.warm(*self._warm, first))
        else:  # a new flight, a kick, a plan run out after failures: the unconstrained optimum from here
            solver.warm_start(*qp.guess(first, x0))
        start = time.perf_counter_ns()
        if self._rho_moved:
            solver.update_settings(rho=RHO)
        result = solver.solve(raise_error=False)
        self.solve_times_us.append((time.perf_counter_ns() - start) / 1e3)
        self.iterations.append(int(result.info.iter))
        self._rho_moved = result.info.rho_updates > 0
        self.solves += 1
        status = result.info.status
        self.statuses[status] = self.statuses.get(status, 0) + 1
        if result.info.status_val != osqp.SolverStatus.OSQP_SOLVED:
            if self._plan is not None:
                self.fallbacks["previous_plan"] += 1
            else:
                self.fallbacks["gain"] += 1
            # The next solve starts again from the last good solution, after a longer wait: a run of
            # failed solves (each up to max_iter) would otherwise eat the control period's budget.
            self._backoff = min(2 * self._backoff, MAX_BACKOFF)
            return
        self._warm = (result.x.copy(), result.y.copy(), first)
        self._backoff = 1
        z = result.x * qp.scale
        self._plan = Plan(z[qp.iu + first : qp.iu + qp.steps].tolist(), qp.ticks[first:].tolist())
        self._nominal[:] = x0.tolist()
        self._step, self._step_left = 0, self._plan.ticks[0]

    # -- what it did ------------------------------------------------------------------------
    def solution(self) -> Solution | None:
        """The last good plan in SI units (None before the first): from its pinned step to the touchdown."""
        if self._warm is None or self._qp is None:
            return None
        qp, (z, _, first) = self._qp, self._warm
        z = z * qp.scale
        n = qp.steps
        return Solution(
            states=z[3 * first : 3 * (n + 1)].reshape(-1, 3),
            torques=z[qp.iu + first : qp.iu + n],
            slacks=z[qp.iu + n + first :],
            ticks=qp.ticks[first:].copy(),
        )

    def stats(self) -> dict[str, object]:
        """Solves, their wall times (us: mean, p99, max) and iterations over the last STATS_KEPT,
        statuses and fallbacks."""
        times = np.array(self.solve_times_us) if self.solve_times_us else np.zeros(1)
        return {
            "solves": self.solves,
            "solve_us_mean": float(times.mean()),
            "solve_us_p99": float(np.percentile(times, 99)),
            "solve_us_max": float(times.max()),
            "iterations_mean": float(np.mean(self.iterations)) if self.iterations else 0.0,
            "statuses": dict(self.statuses),
            "fallbacks": dict(self.fallbacks),
            "kicks": self.kicks,
        }
