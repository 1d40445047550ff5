"""The control kernel's memory: one numpy record with a named field per parameter, state and metric.

One record (a structured array of length 1) passes as a single argument (each array argument
costs the compiled kernel ~0.3 us of dispatch), and every reader names what it reads:
`mem["phase"][0]` in Python, `m.phase` inside the kernel.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hopper.config import MAX_MOTOR_DELAY_TICKS
from hopper.control.gait import Gait
from hopper.layout import ModelLayout

_PARAMS = [
    ("kp", "f8"),  # N m/rad, flight PID
    ("ki", "f8"),  # N m/(rad s)
    ("kd", "f8"),  # N m s/rad
    ("gravity", "f8"),  # m/s^2, magnitude
    ("wheel_on", "?"),  # False: zero wheel torque, wheel free to spin
    ("external", "?"),  # True: a Python controller flies the wheel (kernel.EV_WHEEL); False: wheel_pid
    ("on_stand", "?"),  # True: on the test stand (hopper.stand): the flight's attitude loop, no gait
    ("legs_locked", "?"),  # True: the stand holds the legs in the landing pose (no leg torques)
    ("stand", "f8"),  # m, hip height above the feet in stance
    ("crouch", "f8"),  # m, before the push
    ("push", "f8"),  # m, leg length where the push stops
    ("flight_length", "f8"),  # m, leg length reaching for the landing, after the apex
    ("tuck_length", "f8"),  # m, leg length while rising
    ("feet_mid", "f8"),  # m, the feet's midpoint ahead of the hip in the swing (the kernel writes it)
    ("land_l", "f8"),  # m, each leg's length reaching for the landing (hopper.control.landing)
    ("land_r", "f8"),
    ("spread", "f8"),  # m between the feet at landing
    ("lean", "f8"),  # m, torso CoM ahead of the feet midpoint before the push
    ("friction", "f8"),  # friction coefficient the stance forces assume
    ("sweep_angle", "f8"),  # rad, the legs' backward sweep from their liftoff angle (0: none; GaitParams)
    ("sweep_time", "f8"),  # s the sweep takes
    ("sweep_return", "f8"),  # s the forward swing to the landing pose takes after the sweep
    ("sweep_scale", "f8"),  # x the swing servo's natural frequency during the sweep
    # The robot flown (hopper.robot.Robot, read from its model; SI units there).
    ("mass", "f8"),  # kg
    ("wheel_limit", "f8"),  # N m, the wheel's stall torque
    ("wheel_damping", "f8"),  # N m s/rad, its back-EMF slope
    ("wheel_top", "f8"),  # rad/s, its no-load speed
    ("saturation_torque", "f8"),  # N m: SATURATION_FRACTION of the stall torque counts as saturated
    ("leg_limit", "f8"),  # N m, each leg motor's
    ("thigh", "f8"),  # m
    ("shank", "f8"),  # m
    ("hip_z", "f8"),  # m, the hips above the torso frame's origin (negative: below)
    ("x0", "f8"),  # m, torso x in the XML (root_x measures from it)
    ("z0", "f8"),  # m, torso z in the XML (root_z measures from it)
    # The gait at this gravity: every field of hopper.control.gait.Gait (units there).
    *((field.name, "f8") for field in dataclasses.fields(Gait)),
    ("dt", "f8"),  # s, control period = timestep
    # Sensing (hopper.control.sensing; SensingParams in per-sample SI units).
    ("realistic", "?"),  # False: true pitch and noise-free gyro, no motor delay (the "ideal" mode)
    ("sensor_seed", "u8"),  # SimConfig.seed: the IMU's draws restart from it at each power-on
    ("gyro_noise", "f8"),  # rad/s, standard deviation of one gyro sample
    ("gyro_walk", "f8"),  # rad/s, standard deviation of one tick's step of the bias random walk
    ("gyro_turn_on", "f8"),  # rad/s, turn-on bias scale
    ("accel_noise", "f8"),  # m/s^2, standard deviation of one accelerometer sample, per axis
    ("accel_offset", "f8"),  # m/s^2, residual zero-g offset scale
    ("gyro_fixed", "f8"),  # rad/s, known part of the gyro's turn-on bias (SensingParams.gyro_bias_fixed)
    ("accel_fixed_x", "f8"),  # m/s^2, known parts of the accelerometer's offsets
    ("accel_fixed_z", "f8"),
    ("calibration_ticks", "i8"),  # still samples averaged at power-on
    ("tilt_kp", "f8"),  # 1/s, attitude correction per unit of horizontal specific force / g
    ("tilt_ki", "f8"),  # 1/s^2, gyro bias correction per unit of horizontal specific force / g
    ("motor_delay", "i8"),  # ticks between a wheel command and the torque
    # The motors' energy (hopper.control.energy; figures in hopper.config).
    ("wheel_kt", "f8"),  # N m/A, the wheel motor's torque constant (the simulated robot's: SimConfig.mismatch)
    ("leg_kt", "f8"),  # N m/A, the leg motors'
    ("wheel_resistance", "f8"),  # ohm, the wheel motor's winding over its count in parallel (controller.py)
    ("leg_resistance", "f8"),  # ohm, each leg motor's
    ("leg_motor_gear", "f8"),  # joint torque / motor torque at each leg joint
    ("regenerate", "?"),  # True: braking energy is recovered (negative power counts); False: burnt
]
_LAYOUT = [  # hopper.layout.ModelLayout, flattened
    *((name, "i8") for name in ("q_x", "q_z", "q_pitch", "q_wheel", "q_hip_l", "q_knee_l", "q_hip_r", "q_knee_r")),
    *((name, "i8") for name in ("v_x", "v_z", "v_wheel", "v_hip_l", "v_knee_l", "v_hip_r", "v_knee_r")),
    *(
        (name, "i8")
        for name in ("s_gyro", "s_foot_l", "s_foot_r", "s_wheel_torque", "s_com", "s_com_vel", "s_angmom", "s_accel")
    ),
    *((name, "i8") for name in ("s_torque_hip_l", "s_torque_knee_l", "s_torque_hip_r", "s_torque_knee_r")),
    *((name, "i8") for name in ("a_wheel", "a_hip_l", "a_knee_l", "a_hip_r", "a_knee_r")),
    ("wheel_gear", "f8"),
    ("leg_gear", "f8"),
]
_STATE = [
    ("phase", "i8"),  # hopper.control.phases.Phase
    ("phase_start", "f8"),  # s
    ("push_done", "?"),  # the push reached its speed or length; the legs now swing
    ("recovering", "?"),  # this push is a recovery hop (the capture point left the feet)
    ("boost", "?"),  # this push is a stronger hop out of a place the robot keeps landing back in
    ("progress_x", "f8"),  # m, the furthest liftoff along the forward speed's direction so far
    ("stalled", "i8"),  # liftoffs since the last that beat progress_x by STALL_PROGRESS
    ("failed_pushes", "i8"),  # pushes since the last liftoff that ended with the feet still down
    ("last_both", "f8"),  # s, when both feet last touched the ground
    ("slope_l", "f8"),  # rad, the ground's slope under each foot, rising along +x (written at touchdown)
    ("slope_r", "f8"),
    ("push_skip_l", "?"),  # the leg began this push with no stroke left (hopper.control.kernel)
    ("push_skip_r", "?"),
    ("sweep_from_l", "f8"),  # rad, each virtual leg's world angle at liftoff (where a sweep starts)
    ("sweep_from_r", "f8"),
    ("sweep_len_l", "f8"),  # m, each virtual leg's length at liftoff (held through a sweep)
    ("sweep_len_r", "f8"),
    ("integral", "f8"),  # rad s, flight PID integral
    ("saturated", "?"),  # the wheel command was clamped this tick
    ("contact_l", "?"),  # debounced foot contact
    ("pending_l", "f8"),  # s since a contact change started, < 0: none pending
    ("contact_r", "?"),
    ("pending_r", "f8"),
    ("wheel_command", "f8"),  # N m asked of the wheel this tick
    # The flight's attitude loop as a bench drives it (hopper.stand, hopper.analysis.frequency).
    ("pitch_ref", "f8"),  # rad, the pitch the flight law holds (0: upright)
    ("inject_ref", "f8"),  # rad, added to pitch_ref this tick (an injected excitation)
    ("inject_torque", "f8"),  # N m, added to the law's wheel torque this tick: the plant input's injection
    ("law_pitch", "f8"),  # rad, the pitch error the flight law sees: pitch_est - pitch_ref - inject_ref
    ("law_command", "f8"),  # N m, the flight law's torque this tick, before the injection
    ("prev_vz", "f8"),  # m/s, the CoM's, for the apex
    ("last_contact", "f8"),  # s, last tick with a foot down
    ("clock", "f8"),  # s, the kernel's own copy of data.time
    ("fall_cause", "i8"),  # hopper.control.phases.FallCause
    ("fall_height", "f8"),  # m, hip above the supporting feet when the fall was called (0 in flight)
    # Sensing: truth and estimate side by side (in "ideal" mode the estimate is the truth).
    ("pitch_true", "f8"),  # rad, qpos pitch this tick
    ("rate_true", "f8"),  # rad/s, the noise-free gyro this tick
    ("pitch_est", "f8"),  # rad, what the controller uses as pitch
    ("rate_est", "f8"),  # rad/s, what the controller uses as pitch rate: gyro sample - bias_est
    ("bias_est", "f8"),  # rad/s, the estimator's gyro bias
    ("gyro_bias", "f8"),  # rad/s, the simulated IMU's true gyro bias now
    ("accel_bias_x", "f8"),  # m/s^2, the simulated IMU's true accelerometer offsets
    ("accel_bias_z", "f8"),
    ("rng", "u8"),  # splitmix64 state of the IMU's noise
    ("sense_ready", "?"),  # False: power on (draw the IMU, calibrate) at the next realistic tick
    ("delay_line", "f8", (MAX_MOTOR_DELAY_TICKS,)),  # N m, wheel commands in flight to the driver
    ("delay_head", "i8"),  # index of the oldest command in delay_line
]
# Metric accumulators of the hop in progress (hopper.metrics reads and clears them).
_ACC = [
    ("acc_saturation", "f8"),  # s with |wheel torque| >= 98 % of the limit, ground and flight
    ("acc_peak_wheel", "f8"),  # rad/s, max |wheel speed|
    ("acc_peak_pitch", "f8"),  # rad, max |pitch| in flight
    ("acc_rate_sq", "f8"),  # rad^2/s^2, sum of pitch rate squared over flight ticks
    ("acc_flight_ticks", "f8"),
    ("acc_apex_z", "f8"),  # m, highest torso z in flight
    ("acc_wheel_energy", "f8"),  # J, the wheel motor's electrical energy, ground and flight
    ("acc_leg_energy", "f8"),  # J, the four leg motors', ground and flight
    # The response since liftoff or the scheduled kick (hopper.metrics.ResponseMetrics defines them).
    ("acc_lobe", "f8"),  # +1 / -1: sign of the first excursion beyond RESPONSE_THRESHOLD, 0: none yet
    ("acc_crossed", "f8"),  # 1: the pitch has crossed zero after the first excursion
    ("acc_first_peak", "f8"),  # rad, largest |pitch| of the first excursion
    ("acc_overshoot", "f8"),  # rad, largest pitch beyond zero, opposite the first excursion, after the crossing
    ("acc_last_out", "f8"),  # s, time of the last tick with |pitch| beyond SETTLE_BAND (-inf: none)
    ("acc_peak_torque", "f8"),  # N m, max |wheel torque|
    ("acc_resp_wheel", "f8"),  # rad/s, max |wheel speed|
]
ACC = tuple(name for name, _ in _ACC)
RESPONSE_ACC = ACC[ACC.index("acc_lobe") :]  # cleared at liftoff and at a scheduled kick
FLIGHT_ACC = ("acc_peak_pitch", "acc_rate_sq", "acc_flight_ticks", "acc_apex_z", *RESPONSE_ACC)  # flight ticks only
MEMORY = np.dtype(_PARAMS + _LAYOUT + _STATE + _ACC, align=True)


def new_memory(layout: ModelLayout) -> np.ndarray:
    """A zeroed record (shape (1,), dtype MEMORY) holding the model layout's indices."""
    mem = np.zeros(1, dtype=MEMORY)
    names = {"q_x": layout.q_x, "q_z": layout.q_z, "q_pitch": layout.q_pitch, "q_wheel": layout.q_wheel}
    names |= {"v_x": layout.v_x, "v_z": layout.v_z, "v_wheel": layout.v_wheel}
    for side, (hip, knee) in (("l", (0, 1)), ("r", (2, 3))):
        names |= {f"q_hip_{side}": layout.q_legs[hip], f"q_knee_{side}": layout.q_legs[knee]}
        names |= {f"v_hip_{side}": layout.v_legs[hip], f"v_knee_{side}": layout.v_legs[knee]}
        names |= {f"a_hip_{side}": layout.a_legs[hip], f"a_knee_{side}": layout.a_legs[knee]}
        torques = layout.s_leg_torques
        names |= {f"s_torque_hip_{side}": torques[hip], f"s_torque_knee_{side}": torques[knee]}
    names |= {"s_gyro": layout.s_gyro_pitch, "s_foot_l": layout.s_foot_l, "s_foot_r": layout.s_foot_r}
    names |= {"s_wheel_torque": layout.s_wheel_torque, "a_wheel": layout.a_wheel, "wheel_gear": layout.wheel_gear}
    names |= {"s_com": layout.s_com, "s_com_vel": layout.s_com_vel, "s_angmom": layout.s_angmom}
    names |= {"s_accel": layout.s_accel, "leg_gear": layout.leg_gear}
    for name, value in names.items():
        mem[name] = value
    return mem
