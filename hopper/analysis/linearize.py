"""The flight plant: the whole MuJoCo model linearized in flight, with the leg servos closed.

The legs' servos (hopper.control.legs) hold each leg's angle in the world, so a wheel torque turns
the torso against the hip servos' springs, not against a rigid robot. Linearizing the simulation
itself captures that: MuJoCo's finite-differenced transition (mjd_transitionFD) for the physics,
and central differences of the controller's kernel for the legs' torques. The wheel's torque is
left as the plant's input; hopper.analysis.loop closes the flight PID around it.
"""

from __future__ import annotations

from collections.abc import Callable

import mujoco
import numpy as np

from hopper.analysis.loop import Plant, pitch_inertia
from hopper.config import SimConfig
from hopper.control.kernel import EV_APEX, control_tick
from hopper.sim import Simulation

EPS = 1e-6  # finite-difference step (rad, m, rad/s, m/s)
SETTLED_AFTER_APEX_S = 0.1  # s: by then the legs hold their landing pose (the tuck ends at apex)
PHYSICS = mujoco.mjtState.mjSTATE_FULLPHYSICS
CHECK_TICKS = 100  # settled_flight polls its cancel flag this often: 0.1 s of simulation, ~1 ms of work


def flight_plant(sim: Simulation, lagged_gyro: bool = False) -> Plant:
    """The plant at the simulation's present state (which should be in flight).

    `lagged_gyro`: the leg servos' use of the gyro (which the kernel reads a tick late) is left out
    of `a` and given as `gyro`, for a loop that models the lag (hopper.analysis.predict)."""
    model, data, lay = sim.model, sim.data, sim.layout
    nv = model.nv
    n = 2 * nv + model.na
    a, b = np.zeros((n, n)), np.zeros((n, model.nu))
    mujoco.mjd_transitionFD(model, data, EPS, True, a, b, None, None)
    legs, gyro, estimate = _kernel_jacobian(sim, lagged_gyro)
    # Close everything the kernel does but the wheel's PID: the leg servos, and the wheel driver's
    # back-EMF feedforward (wheel_ctrl adds damping * speed so that the torque is what was asked).
    legs[lay.a_wheel, :] = 0.0
    robot = sim.robot
    legs[lay.a_wheel, nv + lay.v_wheel] = robot.wheel_damping / robot.wheel_torque_limit
    full = np.zeros((nv, nv))
    mujoco.mj_fullM(model, data, full)
    kick = np.zeros(n)
    kick[nv : 2 * nv] = np.linalg.solve(full, np.eye(nv)[lay.v_pitch])  # as Simulation.disturb does
    return Plant(
        a=a + b @ legs,
        b=b[:, lay.a_wheel : lay.a_wheel + 1] / robot.wheel_torque_limit,
        pitch=lay.v_pitch,
        rate=nv + lay.v_pitch,
        kick=kick,
        dt=model.opt.timestep,
        inertia=pitch_inertia(model, data),
        gyro=None if gyro is None else b @ gyro,
        estimate=None if estimate is None else b @ estimate,
        robot=robot,
    )


def _kernel_jacobian(
    sim: Simulation, lagged_gyro: bool = False
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """d ctrl / d x of one controller tick, x in MuJoCo's tangent space [dq, dv], by central
    differences; with `lagged_gyro` also d ctrl / d gyro (the gyro's reading held in the first)
    and, in realistic sensing, d ctrl / d the attitude estimate the tick starts from (the leg
    servos read the estimate then, not the state: perturbing the state alone leaves it out).

    The kernel runs on scratch copies (MjData and its memory record), so the run is untouched.
    """
    model, data = sim.model, sim.data
    nv = model.nv
    state = np.empty(mujoco.mj_stateSize(model, PHYSICS))
    mujoco.mj_getState(model, data, state, PHYSICS)
    scratch = mujoco.MjData(model)

    gyro = sim.layout.s_gyro_pitch
    held = float(data.sensordata[gyro])

    def ctrl_at(dq: np.ndarray, dv: np.ndarray, dgyro: float = 0.0, destimate: float = 0.0) -> np.ndarray:
        mujoco.mj_setState(model, scratch, state, PHYSICS)
        mujoco.mj_integratePos(model, scratch.qpos, dq, 1.0)
        scratch.qvel[:] += dv
        mujoco.mj_forward(model, scratch)
        if lagged_gyro:  # the reading is last tick's, not the perturbed state's
            scratch.sensordata[gyro] = held + dgyro
        ctrl = np.zeros(model.nu)
        mem = sim.controller.mem.copy()
        mem["pitch_est"] += destimate
        control_tick(scratch.qpos, scratch.qvel, scratch.sensordata, ctrl, mem)
        return ctrl

    jacobian = np.zeros((model.nu, 2 * nv + model.na))
    for i in range(2 * nv):
        step = np.zeros(2 * nv)
        step[i] = EPS
        jacobian[:, i] = (ctrl_at(step[:nv], step[nv:]) - ctrl_at(-step[:nv], -step[nv:])) / (2.0 * EPS)
    if not lagged_gyro:
        return jacobian, None, None
    zero = np.zeros(nv)
    by_gyro = (ctrl_at(zero, zero, EPS) - ctrl_at(zero, zero, -EPS)) / (2.0 * EPS)
    by_gyro[sim.layout.a_wheel] = 0.0  # the wheel's law is closed by the loop, with its own lag
    by_estimate = None
    if sim.controller.mem["realistic"][0]:
        by_estimate = (ctrl_at(zero, zero, 0.0, EPS) - ctrl_at(zero, zero, 0.0, -EPS)) / (2.0 * EPS)
        by_estimate[sim.layout.a_wheel] = 0.0
    return jacobian, by_gyro, by_estimate


class Cancelled(Exception):
    """settled_flight was asked to stop (its caller is shutting down)."""


def settled_flight(config: SimConfig, cancelled: Callable[[], bool] = lambda: False) -> Simulation:
    """A simulation of `config` stepped to its first flight, once the legs hold their landing pose.

    `cancelled` is polled every CHECK_TICKS ticks; when it says so, Cancelled is raised.
    """
    sim = Simulation(config)
    limit = 30.0  # s: the first apex comes within a few seconds at any gravity the config accepts
    settle = round(SETTLED_AFTER_APEX_S / config.timestep)
    ticks = apex = 0
    while apex == 0 or ticks < apex + settle:
        if ticks % CHECK_TICKS == 0 and cancelled():
            raise Cancelled
        if sim.step() & EV_APEX and apex == 0:
            apex = ticks
        ticks += 1
        if apex == 0 and (sim.time > limit or sim.fallen):
            raise RuntimeError(f"no flight within {limit:g} s of simulation")
    return sim
