"""Realistic sensing inside the kernel: a seeded MEMS IMU, the attitude estimator, the wheel's command delay.

Everything lives in the kernel's MEMORY record (hopper.control.memory): the noise generator's
state, the IMU's true biases, the estimate and the delay line. A run is therefore deterministic
per SimConfig.seed, and "ideal" mode costs one branch. Angles in rad, pitch + = nose down; the
accelerometer reads specific force (acceleration minus gravity) in the torso frame, so at rest
it reads (-g sin(pitch), g cos(pitch)) on its (x, z) axes.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

# splitmix64 (Steele, Lea, Flood: "Fast splittable pseudorandom number generators", OOPSLA 2014):
# one 64-bit word of state, passes BigCrush, cheap enough for four Gaussians a tick.
GOLDEN = np.uint64(0x9E3779B97F4A7C15)
MIX_1 = np.uint64(0xBF58476D1CE4E5B9)
MIX_2 = np.uint64(0x94D049BB133111EB)
SHIFT_30, SHIFT_27, SHIFT_31, SHIFT_11 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(11)
# Mixed into SimConfig.seed so the IMU's stream is not the terrain generator's (same seed).
IMU_SALT = np.uint64(0x1B0D_5E75_0A1C_0DE5)
TWO_PI = 2.0 * math.pi


@njit(cache=True)
def splitmix64(state: np.uint64) -> tuple[np.uint64, np.uint64]:
    """(next state, 64 random bits)."""
    state = state + GOLDEN
    z = (state ^ (state >> SHIFT_30)) * MIX_1
    z = (z ^ (z >> SHIFT_27)) * MIX_2
    return state, z ^ (z >> SHIFT_31)


@njit(cache=True)
def uniform(state: np.uint64) -> tuple[np.uint64, float]:
    """(next state, a float uniform in [0, 1) with 53 random bits)."""
    state, bits = splitmix64(state)
    return state, (bits >> SHIFT_11) * (1.0 / 9007199254740992.0)


@njit(cache=True)
def gaussian_pair(state: np.uint64) -> tuple[np.uint64, float, float]:
    """(next state, two independent standard normal draws) by Box-Muller."""
    state, u1 = uniform(state)
    state, u2 = uniform(state)
    radius = math.sqrt(-2.0 * math.log(1.0 - u1))  # 1 - u1 in (0, 1]: no log(0)
    return state, radius * math.cos(TWO_PI * u2), radius * math.sin(TWO_PI * u2)


# -- the IMU ---------------------------------------------------------------------------------
@njit(cache=True)
def draw_imu(m) -> None:  # noqa: ANN001 (a MEMORY record)
    """Power the IMU on: restart its noise from the seed and draw its turn-on biases (plus their known parts)."""
    state = np.uint64(m.sensor_seed) ^ IMU_SALT
    state, u = uniform(state)
    v = 2.0 * u - 1.0  # in [-1, 1); the gyro's turn-on bias is +-[0.5, 1) x its scale
    m.gyro_bias = m.gyro_fixed + m.gyro_turn_on * 0.5 * (v + (1.0 if v >= 0.0 else -1.0))
    state, u = uniform(state)
    m.accel_bias_x = m.accel_fixed_x + m.accel_offset * (2.0 * u - 1.0)
    state, u = uniform(state)
    m.accel_bias_z = m.accel_fixed_z + m.accel_offset * (2.0 * u - 1.0)
    m.rng = state


@njit(cache=True)
def imu_sample(m, rate: float, force_x: float, force_z: float) -> tuple[float, float, float]:  # noqa: ANN001
    """One IMU sample (gyro rad/s, accelerometer x and z m/s^2) of the true pitch rate and specific
    force: white noise of the configured density, the gyro's bias taking one random-walk step."""
    m.rng, n_gyro, n_walk = gaussian_pair(m.rng)
    m.rng, n_x, n_z = gaussian_pair(m.rng)
    m.gyro_bias += m.gyro_walk * n_walk
    return (
        rate + m.gyro_bias + m.gyro_noise * n_gyro,
        force_x + m.accel_bias_x + m.accel_noise * n_x,
        force_z + m.accel_bias_z + m.accel_noise * n_z,
    )


# -- the estimator ---------------------------------------------------------------------------
class Attitude(NamedTuple):
    """The estimator's whole state."""

    pitch: float  # rad
    bias: float  # rad/s, of the gyro


@njit(cache=True)
def update(
    att: Attitude,
    gyro: float,
    accel_x: float,
    accel_z: float,
    dt: float,
    ground: bool,
    gravity: float,
    kp: float,
    ki: float,
) -> Attitude:
    """One step: integrate the bias-corrected gyro; on the ground, correct pitch and bias by the
    horizontal specific force in the estimated world frame (a 2-D Mahony filter, PI).

    With the estimate off by d, that horizontal force is a_x + d f_z (a_x the true horizontal
    acceleration): the correction acts on d f_z but also on a_x. Over any long stretch a_x
    integrates to a change of velocity, which stays bounded, while f_z integrates to g t: so the
    loop converges to the true vertical on average and an acceleration only shifts it by about
    kp dv / g. Gating on |f| ~ g would not help on the Moon (a 0.1 m/s^2 push tilts the apparent
    vertical by 3.5 deg but changes |f| by 0.2 %) and would drop the pushes and landings that
    cancel the stance's accelerations. In flight the torso's specific force carries no gravity
    (only the legs' swing reactions): the accelerometer is ignored and the gyro integrated.
    Error dynamics: d'' + kp d' + ki d = 0, so kp = 2 zeta wn, ki = wn^2 (hopper.config.SensingParams).
    """
    pitch = att.pitch + (gyro - att.bias) * dt
    bias = att.bias
    if ground:
        horizontal = (math.cos(pitch) * accel_x + math.sin(pitch) * accel_z) / gravity
        pitch -= kp * horizontal * dt
        bias += ki * horizontal * dt
    return Attitude(pitch, bias)


@njit(cache=True)
def power_on(m, pitch: float) -> None:  # noqa: ANN001 (a MEMORY record)
    """Start the realistic sensing as a robot does standing still at power-on: draw the IMU, then
    average `calibration_ticks` samples at rest (true rate 0, specific force = gravity's
    reaction at the true `pitch`): their mean gyro is the bias estimate, the mean accelerometer
    direction the initial pitch. Empties the wheel's delay line. Switched on mid-run (the
    "realistic" mode toggled live) this is a handover: the estimate starts at the true attitude
    as if the robot had stood still there."""
    draw_imu(m)
    n = max(m.calibration_ticks, 1)
    rest_x, rest_z = -m.gravity * math.sin(pitch), m.gravity * math.cos(pitch)
    sum_gyro = sum_x = sum_z = 0.0
    for _ in range(n):
        gyro, accel_x, accel_z = imu_sample(m, 0.0, rest_x, rest_z)
        sum_gyro += gyro
        sum_x += accel_x
        sum_z += accel_z
    m.bias_est = sum_gyro / n
    m.pitch_est = math.atan2(-sum_x, sum_z)
    m.delay_line[:] = 0.0
    m.delay_head = 0
    m.sense_ready = True


@njit(cache=True)
def sense(m, qpos: np.ndarray, sensors: np.ndarray) -> tuple[float, float]:  # noqa: ANN001
    """(pitch rad, pitch rate rad/s) for the controller: the truth in "ideal" mode, the estimate
    from the simulated IMU in "realistic" mode. Records both in the MEMORY record."""
    pitch, rate = qpos[m.q_pitch], sensors[m.s_gyro]
    m.pitch_true, m.rate_true = pitch, rate
    if not m.realistic:
        m.pitch_est, m.rate_est = pitch, rate
        return pitch, rate
    if not m.sense_ready:
        power_on(m, pitch)
    gyro, accel_x, accel_z = imu_sample(m, rate, sensors[m.s_accel], sensors[m.s_accel + 2])
    ground = m.contact_l or m.contact_r  # last tick's debounced foot contact
    att = update(
        Attitude(m.pitch_est, m.bias_est), gyro, accel_x, accel_z, m.dt, ground, m.gravity, m.tilt_kp, m.tilt_ki
    )
    m.pitch_est, m.bias_est = att.pitch, att.bias
    m.rate_est = gyro - att.bias
    return att.pitch, m.rate_est


@njit(cache=True)
def delayed(m, torque: float) -> float:  # noqa: ANN001 (a MEMORY record)
    """The wheel torque (N m) commanded `motor_delay` ticks ago; queues `torque`. Zero until the
    line has filled. In "ideal" mode, `torque` itself."""
    n = m.motor_delay
    if not m.realistic or n == 0:
        return torque
    head = m.delay_head
    out = m.delay_line[head]
    m.delay_line[head] = torque
    m.delay_head = head + 1 if head + 1 < n else 0
    return out
