"""The Python face of the control kernel: its parameters, phase and memory."""

from __future__ import annotations

import math
from collections.abc import Callable

import mujoco
import numpy as np

from hopper.config import (
    LEG_MOTOR_GEAR,
    LEG_TORQUE_LIMIT,
    MOTOR_RESISTANCE,
    MOTOR_TORQUE_CONSTANT,
    REGENERATIVE_DRIVES,
    SATURATION_FRACTION,
    STANDARD_GRAVITY,
    WHEEL_GEAR,
    WHEEL_TORQUE_LIMIT,
    SimConfig,
)
from hopper.control import gait as gaits
from hopper.control import landing
from hopper.control.memory import new_memory
from hopper.control.phases import FallCause, Phase
from hopper.layout import ModelLayout
from hopper.robot import PACKAGED, Robot


class HopController:
    """Owns the kernel's MEMORY record; `configure()` writes a config's gains, gravity, wheel
    and gait into it (between ticks). The settings themselves live in Simulation.config; the
    robot's constants (`robot`, read from the model flown) are written once."""

    def __init__(self, layout: ModelLayout, config: SimConfig, robot: Robot = PACKAGED) -> None:
        self.layout, self.robot = layout, robot
        self.mem = new_memory(layout)  # passed to control_tick; everything in it has a name
        self.start_over(config)

    def start_over(self, config: SimConfig) -> None:
        """The memory as construction leaves it for `config`, in place (the kernel keeps its view):
        nothing of an earlier episode survives."""
        self.mem[0] = new_memory(self.layout)[0]
        (self.mem["x0"], self.mem["z0"]), self.mem["dt"] = self.layout.torso_origin, config.timestep
        self._write_robot()
        self.mem["leg_kt"] = MOTOR_TORQUE_CONSTANT
        self.mem["leg_motor_gear"], self.mem["regenerate"] = LEG_MOTOR_GEAR, REGENERATIVE_DRIVES
        self.configure(config)
        self.reset()

    def _write_robot(self) -> None:
        m, r = self.mem, self.robot
        m["mass"], m["leg_limit"], m["hip_z"] = r.mass, r.leg_torque_limit, r.hip_z
        m["thigh"], m["shank"] = r.thigh, r.shank
        m["wheel_limit"], m["wheel_damping"] = r.wheel_torque_limit, r.wheel_damping
        m["wheel_top"] = r.wheel_no_load_speed
        m["saturation_torque"] = SATURATION_FRACTION * r.wheel_torque_limit
        # A model's motor n times as strong as the datasheet's (hopper.similarity sizes them so) is n
        # of them in parallel: the same k_t and no-load speed, n times the current through R / n.
        wheel_motors = (r.wheel_torque_limit / r.wheel_gear) / (WHEEL_TORQUE_LIMIT / WHEEL_GEAR)
        m["wheel_resistance"] = MOTOR_RESISTANCE / wheel_motors
        m["leg_resistance"] = MOTOR_RESISTANCE / (r.leg_torque_limit / LEG_TORQUE_LIMIT)

    def configure(self, config: SimConfig) -> None:
        """Take `config`; a gravity the legs cannot hold the robot at raises ValueError and changes nothing."""
        m, g, gait = self.mem, config.gains, config.gait
        self.gait = derived = gaits.derive(config.gravity, gait, self.robot)  # first: it may refuse
        m["kp"], m["ki"], m["kd"] = g.kp, g.ki, g.kd
        m["gravity"], m["wheel_on"] = config.gravity, config.wheel
        # The energy is the simulated robot's: a motor_torque mismatch is its wheel motor's k_t (hopper.mismatch),
        # though the control law keeps the nominal one.
        m["wheel_kt"] = MOTOR_TORQUE_CONSTANT * dict(config.mismatch).get("motor_torque", 1.0)
        for name, value in derived.record().items():
            m[name] = value
        m["stand"], m["crouch"] = gait.stand_height, gait.crouch_height
        m["push"], m["flight_length"], m["spread"] = gait.push_length, gait.flight_length, gait.foot_spread
        m["tuck_length"] = gait.tuck_length
        m["land_l"] = m["land_r"] = gait.flight_length
        m["lean"] = gait.crouch_lean
        m["friction"] = gait.friction
        m["sweep_angle"], m["sweep_time"] = math.radians(gait.sweep_angle), gait.sweep_time
        m["sweep_return"], m["sweep_scale"] = gait.sweep_return_time, gait.sweep_stiffness
        self._configure_sensing(config)

    def _configure_sensing(self, config: SimConfig) -> None:
        """SensingParams in the kernel's per-sample SI units. Switching to "realistic" powers the
        IMU on at the next tick; a new delay empties the delay line."""
        m, s, dt = self.mem, config.sensor, config.timestep
        realistic = config.sensing == "realistic"
        if realistic and not m["realistic"][0]:
            m["sense_ready"] = False
        if s.motor_delay_ticks != m["motor_delay"][0]:
            m["delay_line"], m["delay_head"] = 0.0, 0
        m["realistic"], m["sensor_seed"] = realistic, config.seed
        m["gyro_noise"] = math.radians(s.gyro_noise_density) / math.sqrt(dt)  # white noise: density / sqrt(dt)
        m["gyro_walk"] = math.radians(s.gyro_bias_walk) * math.sqrt(dt)  # random walk: density * sqrt(dt)
        m["gyro_turn_on"] = math.radians(s.gyro_turn_on_bias)
        m["accel_noise"] = s.accel_noise_density * 1e-6 * STANDARD_GRAVITY / math.sqrt(dt)
        m["accel_offset"] = s.accel_bias * 1e-3 * STANDARD_GRAVITY
        m["gyro_fixed"] = math.radians(s.gyro_bias_fixed)
        m["accel_fixed_x"] = s.accel_bias_fixed_x * 1e-3 * STANDARD_GRAVITY
        m["accel_fixed_z"] = s.accel_bias_fixed_z * 1e-3 * STANDARD_GRAVITY
        m["calibration_ticks"] = max(round(s.calibration_time / dt), 1)
        m["tilt_kp"], m["tilt_ki"] = 2.0 * s.tilt_zeta * s.tilt_wn, s.tilt_wn**2
        m["motor_delay"] = s.motor_delay_ticks

    def reset(self, time: float = 0.0, standing: bool = True) -> None:
        """Start in stance (feet believed on the ground when `standing`).

        A reset is a power cycle for the realistic IMU: at the next tick it is drawn again from the
        seed (so a reset replays the run) and calibrated standing still (hopper.control.sensing.
        power_on). The bias estimate is not kept: a MEMS gyro's turn-on bias changes from one
        power-on to the next, and the still calibration measures the new one to ~0.01 deg/s.
        """
        m = self.mem
        for name in (
            "phase_start", "push_done", "integral", "saturated", "wheel_command", "prev_vz",
            "last_contact", "last_both", "push_skip_l", "push_skip_r", "fall_cause", "fall_height",
            "failed_pushes", "boost", "progress_x", "stalled", "slope_l", "slope_r",
        ):  # fmt: skip
            m[name] = 0
        m["phase"], m["phase_start"], m["clock"] = int(Phase.STANCE), time, time
        m["contact_l"] = m["contact_r"] = standing
        m["pending_l"] = m["pending_r"] = -1.0
        m["sense_ready"] = False
        m["delay_line"], m["delay_head"] = 0.0, 0

    def plan_landing(self, data: mujoco.MjData, layout: ModelLayout, ground: Callable[[float, int], float]) -> None:
        """At the apex: each leg's landing length so that both feet meet the terrain together.

        ground(x, foot) is the terrain height (m) under foot 0 (left) or 1 (right) at world x.
        """
        m, s = self.mem, data.sensordata
        hip, ahead = self._hip_and_feet_ahead(data, layout)
        vx, vz = float(s[layout.s_com_vel]), float(s[layout.s_com_vel + 2])
        lengths = landing.plan_reach(
            hip, (vx, vz), float(m["gravity"][0]), ahead, float(m["flight_length"][0]), float(m["push"][0]), ground,
            self.robot.foot_radius,
        )  # fmt: skip
        m["land_l"], m["land_r"] = lengths

    def feel_ground(self, data: mujoco.MjData, ground: Callable[[float, int], float]) -> None:
        """At touchdown: the ground's slope under each foot (rad, rising along +x), for the stance's
        friction cones. Taken across the foot's own width, the ground its sphere rests on."""
        m, r = self.mem, self.robot.foot_radius
        for foot, name in ((0, "L"), (1, "R")):
            x = float(data.geom(f"foot_{name}").xpos[0])
            m[f"slope_{name.lower()}"] = math.atan((ground(x + r, foot) - ground(x - r, foot)) / (2.0 * r))

    def _hip_and_feet_ahead(
        self, data: mujoco.MjData, layout: ModelLayout
    ) -> tuple[tuple[float, float], tuple[float, float]]:
        """The hip's world (x, z) now and where the kernel's swing puts each foot ahead of it (m)."""
        q = data.qpos
        torso = (float(q[layout.q_x]) + layout.torso_origin[0], float(q[layout.q_z]) + layout.torso_origin[1])
        hip = landing.hip_position(torso, float(q[layout.q_pitch]), self.robot)
        mid, half = float(self.mem["feet_mid"][0]), 0.5 * float(self.mem["spread"][0])
        return hip, (mid + half, mid - half)

    def landing_feet(self, data: mujoco.MjData, layout: ModelLayout) -> list[tuple[float, float]]:
        """World (x, z) of the left and right foot centres now, were the legs in their landing pose.

        Ahead of the hip by the kernel's swing target, below it by the landing reach: the nominal
        flight length while rising, each leg's planned length once the apex has set them.
        """
        m = self.mem
        (hip_x, hip_z), ahead = self._hip_and_feet_ahead(data, layout)
        rising = float(data.sensordata[layout.s_com_vel + 2]) > 0.0
        reach = (m["flight_length"][0],) * 2 if rising else (m["land_l"][0], m["land_r"][0])
        return [(hip_x + a, hip_z - float(r)) for a, r in zip(ahead, reach, strict=True)]

    def field(self, name: str) -> np.ndarray:
        """A live view (shape (1,)) of one field of the kernel's memory, e.g. for a recorder."""
        return self.mem[name]

    @property
    def phase(self) -> Phase:
        return Phase(int(self.mem["phase"][0]))

    @property
    def fall_cause(self) -> FallCause:
        return FallCause(int(self.mem["fall_cause"][0]))

    @property
    def fall_height(self) -> float:
        """Hip above the supporting feet when the fall was called, m (0 in flight)."""
        return float(self.mem["fall_height"][0])

    @property
    def wheel_command(self) -> float:
        """Wheel torque asked this tick, N m."""
        return float(self.mem["wheel_command"][0])
