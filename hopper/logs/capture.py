"""Capture a hopper log from the simulation: a robot with a known truth, logged as a real one would be.

Each row k is one 1 kHz tick, every column a sample of the robot at time t_k: the state (the
torso's CoM, pitch and their rates: the truth a motion-capture system gives), the sensors (the
gyro as the IMU read it, noise and bias included in realistic sensing; the wheel and leg
encoders; the feet's contact forces) and the commands computed at that tick (the wheel torque as
asked, before the motor's delay line, for the motor the controller knows, which the log's world
records; the leg torques as sent). The kernel reads the IMU one tick
late (MuJoCo's sensors are of the state before the step): the sample it reads at tick k+1 is
the one of t_k, and is logged in row k.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hopper.config import SimConfig
from hopper.layout import LEG_JOINTS
from hopper.logs.schema import Log
from hopper.logs.world import of_config
from hopper.sim import Simulation


@dataclasses.dataclass(frozen=True)
class Capture:
    """A captured log and how the run went."""

    log: Log
    hops: int  # completed
    fell: bool


def capture(config: SimConfig, hops: int, source: str = "capture") -> Capture:
    """Simulate `config` (its mismatch, sensing and seed) for `hops` hops (or until it falls or runs out
    of time, Simulation.time_limit) and log every tick."""
    if hops < 1:
        raise ValueError(f"hops must be at least 1, got {hops}")
    sim = Simulation(config)
    model, data, lay, mem = sim.model, sim.data, sim.layout, sim.controller.mem
    ticks = round(sim.time_limit(hops) / model.opt.timestep)
    names = (
        "time", "x", "z", "vx", "vz", "pitch", "pitch_rate", "wheel_speed", *LEG_JOINTS,
        "foot_L_force", "foot_R_force", "wheel_torque_cmd", *(f"{j}_torque_cmd" for j in LEG_JOINTS), "gyro_pitch",
    )  # fmt: skip
    rows = np.empty((ticks + 1, len(names)))
    col = {n: i for i, n in enumerate(names)}
    legs_q, legs_a = list(lay.q_legs), list(lay.a_legs)
    torso, realistic = lay.torso, config.sensing == "realistic"
    n = 0
    while n < ticks and len(sim.hops) < hops and not sim.fallen:
        q, v = data.qpos, data.qvel
        row = rows[n]
        row[col["time"]] = data.time
        pitch, rate = q[lay.q_pitch], v[lay.v_pitch]
        row[col["pitch"]], row[col["pitch_rate"]], row[col["wheel_speed"]] = pitch, rate, v[lay.v_wheel]
        row[col["hip_L"] : col["knee_R"] + 1] = q[legs_q]
        vx, vz = v[lay.v_x], v[lay.v_z]
        sim.step()
        # After mj_step the positions of bodies and the sensors are those of t_k (its forward pass).
        com, origin = data.xipos[torso], data.xpos[torso]
        rz, rx = com[2] - origin[2], com[0] - origin[0]
        row[col["x"]], row[col["z"]] = com[0], com[2]
        row[col["vx"]], row[col["vz"]] = vx + rate * rz, vz - rate * rx  # v + omega (about y) x r
        s = data.sensordata
        row[col["foot_L_force"]], row[col["foot_R_force"]] = s[lay.s_foot_l], s[lay.s_foot_r]
        row[col["wheel_torque_cmd"]] = mem["wheel_command"][0]
        row[col["hip_L_torque_cmd"] : col["knee_R_torque_cmd"] + 1] = data.ctrl[legs_a] * lay.leg_gear
        if n > 0:  # this tick's IMU sample is of the previous tick's state
            gyro = mem["rate_est"][0] + (mem["bias_est"][0] if realistic else 0.0)
            rows[n - 1, col["gyro_pitch"]] = gyro
        n += 1
    n -= 1  # the last row's gyro sample was never read
    if n < 2:
        raise ValueError("the run ended before it could be logged")
    signals = {name: rows[:n, i].copy() for i, name in enumerate(names) if name != "time"}
    log = Log(rows[:n, 0].copy(), signals, source, world=of_config(config, sim.robot))
    return Capture(log, len(sim.hops), sim.fallen)
