"""The built-in MPC: its QP's constraints and landing, its model against the simulation, fallbacks, determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hopper.config import WHEEL_NO_LOAD_SPEED, WHEEL_TORQUE_LIMIT, SimConfig
from hopper.control.wheel import WHEEL_DAMPING
from hopper.controllers import ControllerContext, Observation, with_controller
from hopper.laws.mpc import MPC, prediction_model, step_grid
from hopper.laws.plant import attitude_model
from hopper.layout import ModelLayout
from hopper.sim import Simulation

MOON = SimConfig(terrain="flat")


@pytest.fixture(scope="module")
def moon() -> Simulation:
    return Simulation(MOON)


def configured(sim: Simulation, **params: float) -> MPC:
    mpc = MPC()
    for p in MPC.params:
        setattr(mpc, p.name, params.get(p.name, p.default))
    mpc.configure(ControllerContext(sim.config, sim.model))
    return mpc


def flight_obs(sim: Simulation, pitch: float, rate: float, wheel: float, left: float = 0.6) -> Observation:
    w = wheel
    return sim.observation()._replace(
        pitch=pitch,
        rate=rate,
        wheel_speed=w,
        time=0.0,
        time_since_liftoff=0.0,
        time_to_touchdown=left,
        torque_bounds=(max(-WHEEL_TORQUE_LIMIT, -WHEEL_TORQUE_LIMIT - WHEEL_DAMPING * w),
                       min(WHEEL_TORQUE_LIMIT, WHEEL_TORQUE_LIMIT - WHEEL_DAMPING * w)),
    )  # fmt: skip


def held(model, x: np.ndarray, torques: np.ndarray, ticks: np.ndarray) -> np.ndarray:  # noqa: ANN001
    """The 1 ms model stepped through a plan's held torques: (pitch, rate, wheel speed) at its end."""
    for u, m in zip(torques, ticks, strict=True):
        for _ in range(int(m)):
            x = model.a @ x + model.b * u
    return x


def test_grid_is_fine_at_the_touchdown_and_covers_the_horizon():
    ticks = step_grid(20, 1.03, 1250)
    assert ticks[-1] == 20 and ticks.sum() >= 1250
    assert np.all(np.diff(ticks) <= 0)  # longer further from the touchdown
    assert np.array_equal(step_grid(20, 1.0, 100), [20] * 5)


def test_qp_respects_the_envelope_and_the_speed_limit_near_them(moon: Simulation):
    # Near the top speed, a pitch error that asks for torque in the direction that speeds the wheel up.
    mpc = configured(moon)
    w0 = 0.8 * WHEEL_NO_LOAD_SPEED
    obs = flight_obs(moon, pitch=math.radians(2.0), rate=math.radians(20.0), wheel=w0)  # wants tau > 0
    mpc.reset(obs)
    mpc(obs)
    sol = mpc.solution()
    assert sol is not None and mpc.statuses == {"solved": 1}
    u, w = sol.torques, sol.states[:, 2]
    tol = 3e-3 * WHEEL_TORQUE_LIMIT  # OSQP's eps_abs + eps_rel |row| in the envelope's rows (stall-torque units)
    for ends in (w[:-1], w[1:]):  # the envelope holds at both ends of every step
        assert np.all(u + WHEEL_DAMPING * ends <= WHEEL_TORQUE_LIMIT + tol)
        assert np.all(u + WHEEL_DAMPING * ends >= -WHEEL_TORQUE_LIMIT - tol)
    assert np.all(np.abs(u) <= WHEEL_TORQUE_LIMIT + tol)
    assert np.all(np.abs(w) <= WHEEL_NO_LOAD_SPEED + sol.slacks + 1e-2 * WHEEL_NO_LOAD_SPEED)
    assert u.max() > 0.3 * (WHEEL_TORQUE_LIMIT - WHEEL_DAMPING * w0)  # it does push toward the limit
    # And what the plan does on its own model stays inside: the slack is not spent.
    assert sol.slacks.max() < 0.05


def test_the_plan_lands_level_and_still_on_its_linear_model(moon: Simulation):
    mpc = configured(moon)
    x0 = np.array([math.radians(3.0), math.radians(30.0), 5.0])
    obs = flight_obs(moon, *x0, left=0.8)
    mpc.reset(obs)
    mpc(obs)
    sol = mpc.solution()
    dt = moon.config.timestep
    assert abs(sol.ticks.sum() * dt - 0.8) <= 0.5 * sol.ticks[0] * dt  # to the touchdown, to the nearest step
    end = held(mpc.model, x0, sol.torques, sol.ticks)
    assert abs(math.degrees(end[0])) < 0.05
    assert abs(math.degrees(end[1])) < 0.5
    np.testing.assert_allclose(end, sol.states[-1], atol=2e-3)  # the QP's dynamics are the model's


def test_its_model_predicts_the_flight_better_than_the_truncated_one(moon: Simulation):
    """The residualised plant against MuJoCo: a 3 N m step for 0.2 s in flight, from level and still."""
    sim = Simulation(with_controller(MOON, f"{__file__}:StepThenHold"))
    sim.run(1)
    law = sim.law.controller
    assert law.log, "the step never ran"
    start, measured = law.log[0], law.log[-1]
    truncated = attitude_model(MOON)
    resid = prediction_model(MOON, ModelLayout.of(sim.model))
    ticks = len(law.log) - 1
    x_res = held(resid, np.array(start), np.array([StepThenHold.TORQUE]), np.array([ticks]))
    x_tr = held(truncated, np.array(start), np.array([StepThenHold.TORQUE]), np.array([ticks]))
    assert abs(x_res[0] - measured[0]) < 0.5 * abs(x_tr[0] - measured[0])
    assert abs(x_res[0] - measured[0]) < 0.5 * abs(measured[0] - start[0])


class StepThenHold:
    """Level the torso with a PD until 0.25 s after liftoff, then 3 N m for 0.2 s, logging the state."""

    TORQUE = 3.0  # N m

    def __init__(self) -> None:
        self.log: list[tuple[float, float, float]] = []

    def __call__(self, obs: Observation) -> float:
        t = obs.time_since_liftoff
        if t < 0.25:
            return 450.0 * obs.pitch + 30.0 * obs.rate
        if t <= 0.45:
            self.log.append((obs.pitch, obs.rate, obs.wheel_speed))
            return self.TORQUE if t < 0.45 else 0.0
        return 450.0 * obs.pitch + 30.0 * obs.rate


def test_three_hops_at_the_moon_without_a_fall():
    sim = Simulation(with_controller(SimConfig(seed=3), "mpc"))
    sim.run(3)
    assert not sim.fallen and sim.controller_fault is None
    assert len(sim.hops) == 3
    assert max(h.landing_pitch_deg for h in sim.hops) < 1.0
    mpc = sim.law.controller
    assert mpc.solves > 100 and mpc.fallbacks == {"previous_plan": 0, "gain": 0}


def near_the_limit(sim: Simulation) -> Observation:
    """A state whose plan leans on the envelope: the unconstrained optimum is not the answer there."""
    return flight_obs(sim, math.radians(2.0), math.radians(20.0), 0.7 * WHEEL_NO_LOAD_SPEED)


def test_a_failed_solve_falls_back_to_the_last_plan_then_to_the_gain(moon: Simulation):
    mpc = configured(moon, replan_ms=1.0)
    obs = near_the_limit(moon)
    mpc.reset(obs)
    first = mpc(obs)
    plan = mpc.solution().torques[0]
    mpc._qp.solver.update_settings(max_iter=1)  # every solve from now on stops unsolved
    nxt = obs._replace(time=obs.time + obs.dt, time_to_touchdown=obs.time_to_touchdown - obs.dt, rate=obs.rate + 0.05)
    second = mpc(nxt)
    assert mpc.fallbacks == {"previous_plan": 1, "gain": 0}
    assert mpc._backoff == 2  # the next replan waits twice as long
    assert mpc.statuses == {"solved": 1, "maximum iterations reached": 1}
    assert math.isfinite(first) and math.isfinite(second)
    # It flew the old plan's move with the correction toward the old plan's nominal state.
    k = np.array(mpc._gain)
    state = np.array((nxt.pitch, nxt.rate, nxt.wheel_speed))
    nominal = mpc.model.a @ np.array((obs.pitch, obs.rate, obs.wheel_speed)) + mpc.model.b * plan
    assert second == pytest.approx(plan + k @ (state - nominal), rel=1e-9)
    # A new flight has no plan to fall back on: the gain alone, without its wheel-speed term.
    mpc.reset(obs)
    assert mpc(obs) == pytest.approx(k[0] * obs.pitch + k[1] * obs.rate, rel=1e-12)
    assert mpc.fallbacks == {"previous_plan": 1, "gain": 1}


def test_too_slow_a_solve_is_a_failure(moon: Simulation):
    mpc = configured(moon, solve_deadline_ms=0.01)
    obs = near_the_limit(moon)
    mpc.reset(obs)
    mpc(obs)
    assert mpc.statuses == {"run time limit reached": 1} and mpc.fallbacks["gain"] == 1


def test_two_runs_are_identical_and_a_refly_from_a_snapshot_repeats_the_flight():
    config = with_controller(SimConfig(seed=1), "mpc")
    a, b = Simulation(config), Simulation(config)
    a.run(2)
    b.run(2)
    assert [h.as_dict() for h in a.hops] == [h.as_dict() for h in b.hops]
    assert np.array_equal(a.data.qpos, b.data.qpos) and np.array_equal(a.data.qvel, b.data.qvel)
    # Mid-flight: snapshot, fly on, restore, fly the same again (the solver is rebuilt on the copy).
    while a.phase.label != "flight" or a.time - a.hops[-1].touchdown_time_s < 0.5:
        a.step()
    snap = a.snapshot()
    trace = []
    for _ in range(300):
        a.step()
        trace.append(a.data.qpos.copy())
    a.restore(snap)
    for expected in trace:
        a.step()
        assert np.array_equal(a.data.qpos, expected)
