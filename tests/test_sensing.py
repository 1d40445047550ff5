"""Realistic sensing: the IMU's noise, the attitude estimator on synthetic traces, the motor delay, closed loop."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from hopper.config import STANDARD_GRAVITY, InvalidConfig, SensingParams, SimConfig
from hopper.control import HopController, Phase
from hopper.control.sensing import Attitude, delayed, draw_imu, imu_sample, update
from hopper.layout import ModelLayout
from hopper.model import build_model
from hopper.sim import Simulation

DT, MOON = 0.001, 1.625
FLIGHT = int(Phase.FLIGHT)


def _memory(sensor: SensingParams | None = None, sensing: str = "realistic", seed: int = 0) -> np.ndarray:
    config = SimConfig(terrain="flat", seed=seed, sensing=sensing, sensor=sensor or SensingParams())
    return HopController(ModelLayout.of(build_model(config)), config).mem


@njit
def _estimate(gyro, accel_x, accel_z, ground, gravity, kp, ki, pitch0, bias0):  # noqa: ANN001, ANN202
    """The estimator over a whole trace (shape (n,) each): its pitch and bias after every sample."""
    pitch, bias = np.empty(gyro.size), np.empty(gyro.size)
    att = Attitude(float(pitch0), float(bias0))
    for i in range(gyro.size):
        att = update(att, gyro[i], accel_x[i], accel_z[i], DT, ground[i], gravity, kp, ki)
        pitch[i], bias[i] = att.pitch, att.bias
    return pitch, bias


def _gains(sensor: SensingParams) -> tuple[float, float]:
    return 2 * sensor.tilt_zeta * sensor.tilt_wn, sensor.tilt_wn**2


# -- config ------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "bad",
    [{"gyro_noise_density": -0.1}, {"tilt_wn": float("nan")}, {"motor_delay_ticks": 17}, {"motor_delay_ticks": 2.0}],
)
def test_invalid_sensing_params_raise(bad: dict) -> None:
    with pytest.raises(InvalidConfig, match="must be"):
        SensingParams(**bad)
    with pytest.raises(InvalidConfig, match="sensing must be"):
        SimConfig(sensing="perfect")  # type: ignore[arg-type]


# -- the IMU model -----------------------------------------------------------------------------
def test_imu_noise_has_the_datasheet_density_and_a_bounded_turn_on_bias() -> None:
    sensor = SensingParams()
    mem = _memory(sensor)
    m = mem[0]
    draw_imu(m)
    n = 20_000
    gyro, ax, az, bias = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    for i in range(n):
        gyro[i], ax[i], az[i] = imu_sample(m, 0.0, 0.0, MOON)
        bias[i] = mem["gyro_bias"][0]
    gyro_sigma = math.radians(sensor.gyro_noise_density) * math.sqrt(1 / DT)  # 0.44 deg/s
    accel_sigma = sensor.accel_noise_density * 1e-6 * STANDARD_GRAVITY * math.sqrt(1 / DT)  # 0.054 m/s^2
    walk_sigma = math.radians(sensor.gyro_bias_walk) * math.sqrt(DT)
    for samples, offset, sigma in (
        (gyro, bias, gyro_sigma),
        (ax, mem["accel_bias_x"][0], accel_sigma),
        (az, MOON + mem["accel_bias_z"][0], accel_sigma),
    ):
        noise = samples - offset
        assert abs(noise.mean()) < 4 * sigma / math.sqrt(n)
        assert noise.std() == pytest.approx(sigma, rel=0.03)  # the std of a std estimate is 0.5 %
        assert abs(np.corrcoef(noise[:-1], noise[1:])[0, 1]) < 4 / math.sqrt(n)  # white
    assert np.diff(bias).std() == pytest.approx(walk_sigma, rel=0.03)
    # The turn-on biases: gyro within +-[0.5, 1] x its scale, both signs over seeds; accel within its scale.
    gyro_biases = []
    for seed in range(20):
        mem = _memory(sensor, seed=seed)
        draw_imu(mem[0])
        gyro_biases.append(math.degrees(mem["gyro_bias"][0]))
        for axis in ("accel_bias_x", "accel_bias_z"):
            assert abs(mem[axis][0]) <= sensor.accel_bias * 1e-3 * STANDARD_GRAVITY
    magnitudes = np.abs(gyro_biases)
    assert ((0.5 * sensor.gyro_turn_on_bias <= magnitudes) & (magnitudes <= sensor.gyro_turn_on_bias)).all()
    assert min(gyro_biases) < 0 < max(gyro_biases)
    assert len(set(gyro_biases)) == 20


# -- the estimator on a synthetic IMU trace ---------------------------------------------------
def _synthetic_trace(rng: np.random.Generator, sensor: SensingParams, ground_s: float, flight_s: float):  # noqa: ANN202
    """A robot at rest on the ground at 2 deg, then a ballistic flight rotating +10 deg and back,
    seen by a gyro with a 0.4 deg/s bias and the datasheet's noise. In flight the accelerometer
    reads no gravity, only the legs' swing reaction and noise."""
    n_ground, n_flight = round(ground_s / DT), round(flight_s / DT)
    t = np.arange(n_flight) * DT
    pitch0, swing = math.radians(2.0), math.radians(10.0)
    pitch = np.concatenate([np.full(n_ground, pitch0), pitch0 + swing * np.sin(math.pi * t / flight_s) ** 2])
    rate = np.concatenate([np.zeros(n_ground), swing * math.pi / flight_s * np.sin(2 * math.pi * t / flight_s)])
    bias = math.radians(0.4)
    n = n_ground + n_flight
    gyro = rate + bias + math.radians(sensor.gyro_noise_density) / math.sqrt(DT) * rng.standard_normal(n)
    accel_sigma = sensor.accel_noise_density * 1e-6 * STANDARD_GRAVITY / math.sqrt(DT)
    accel_x = -MOON * np.sin(pitch) + accel_sigma * rng.standard_normal(n)
    accel_z = MOON * np.cos(pitch) + accel_sigma * rng.standard_normal(n)
    ground = np.arange(n) < n_ground
    accel_x[~ground] = 0.3 * np.sin(20 * t) + accel_sigma * rng.standard_normal(n_flight)
    accel_z[~ground] = 0.2 * np.cos(20 * t) + accel_sigma * rng.standard_normal(n_flight)
    return pitch, bias, gyro, accel_x, accel_z, ground, n_ground


def test_estimator_learns_the_bias_at_rest_and_integrates_the_gyro_in_flight() -> None:
    sensor = SensingParams()
    kp, ki = _gains(sensor)
    ground_s, flight_s = 12.0 / sensor.tilt_wn, 1.2  # 600 s at rest: the loop is slow on purpose
    pitch, bias, gyro, accel_x, accel_z, ground, n_ground = _synthetic_trace(
        np.random.default_rng(3), sensor, ground_s, flight_s
    )
    est_pitch, est_bias = _estimate(gyro, accel_x, accel_z, ground, MOON, kp, ki, 0.0, 0.0)  # no calibration

    # On the ground the bias converges from 0.4 deg/s: the error envelope of the critically damped
    # loop, (1 + wn t) exp(-wn t), is 7e-5 after 12/wn; what is left is the accelerometer's noise.
    bias_error = math.degrees(est_bias[n_ground - 1] - bias)
    assert abs(bias_error) < 0.01  # deg/s
    # The pitch wanders with the gyro's angle random walk, which the slow loop corrects only over
    # ~1/kp: sigma ~ N / sqrt(2 kp) = 0.014 deg/s/sqrt(Hz) / sqrt(0.08/s) = 0.05 deg.
    assert abs(math.degrees(est_pitch[n_ground - 1] - pitch[n_ground - 1])) < 0.2  # deg

    # In flight only the gyro counts: the drift is the bias error times the time, plus the angle
    # random walk (0.014 deg/s/sqrt(Hz) * sqrt(1.2 s) = 0.015 deg, 1 sigma).
    error = np.degrees(est_pitch - pitch)[n_ground - 1 :]
    drift = error - error[0]
    t = np.arange(drift.size) * DT
    random_walk = sensor.gyro_noise_density * math.sqrt(flight_s)
    assert np.abs(drift - bias_error * t).max() < 4 * random_walk
    assert np.abs(drift).max() < abs(bias_error) * flight_s + 4 * random_walk
    # ... the accelerometer's reading in flight changes nothing, bit for bit.
    quiet_x, quiet_z = accel_x.copy(), accel_z.copy()
    quiet_x[~ground], quiet_z[~ground] = 0.0, 0.0
    quiet_pitch, quiet_bias = _estimate(gyro, quiet_x, quiet_z, ground, MOON, kp, ki, 0.0, 0.0)
    assert np.array_equal(quiet_pitch, est_pitch) and np.array_equal(quiet_bias, est_bias)
    # ... while the estimate follows the 10 deg swing.
    assert np.degrees(est_pitch[n_ground:]).max() > 11.0


def test_a_body_acceleration_on_the_ground_shifts_the_estimate_by_kp_dv_over_g() -> None:
    """The loop's one weakness, by its linear model: a velocity change dv on the ground looks like
    a tilt for a while, shifting the estimate by about kp dv / g (0.56 deg for 0.4 m/s on the Moon)."""
    sensor = SensingParams()
    kp, ki = _gains(sensor)
    n = 3000
    t = np.arange(n) * DT
    accel_x = np.where((t >= 0.5) & (t < 1.0), 0.8, 0.0)  # 0.8 m/s^2 for 0.5 s: dv = 0.4 m/s, level body
    accel_z = np.full(n, MOON)
    for gravity in (MOON, 3.72):
        est_pitch, _ = _estimate(
            np.zeros(n), accel_x, accel_z * gravity / MOON, np.ones(n, bool), gravity, kp, ki, 0, 0
        )
        end = round(1.0 / DT) - 1  # the end of the push (the loop has barely started to pull back)
        assert est_pitch[end] == pytest.approx(-kp * 0.4 / gravity, rel=0.02)
        assert 0.9 < est_pitch[-1] / est_pitch[end] < 1.0  # ... and takes ~1/wn = 50 s to forget it


# -- the delay line ----------------------------------------------------------------------------
@pytest.mark.parametrize("ticks", [0, 1, 3, 16])
def test_the_wheel_command_arrives_exactly_n_ticks_later(ticks: int) -> None:
    mem = _memory(SensingParams(motor_delay_ticks=ticks))
    m = mem[0]
    commands = np.arange(1.0, 41.0)
    out = [delayed(m, c) for c in commands]
    assert out == [0.0] * ticks + commands[: commands.size - ticks].tolist()
    ideal = _memory(SensingParams(motor_delay_ticks=ticks), sensing="ideal")[0]
    assert [delayed(ideal, c) for c in commands] == commands.tolist()


# -- in the simulation -------------------------------------------------------------------------
def test_ideal_sensing_hands_the_controller_the_truth_undelayed() -> None:
    """Ideal mode is the paper's: the controller reads the true pitch and the noise-free gyro,
    and the wheel command reaches the motor in the same tick."""
    from hopper.control.wheel import wheel_ctrl

    sim = Simulation(SimConfig())
    mem, lay = sim.controller.mem, sim.layout
    for _ in range(4000):
        pitch, gyro = float(sim.data.qpos[lay.q_pitch]), float(sim.data.sensordata[lay.s_gyro_pitch])
        wheel_speed = float(sim.data.qvel[lay.v_wheel])
        sim.step()
        assert (mem["pitch_est"][0], mem["rate_est"][0]) == (pitch, gyro)
        assert (mem["pitch_true"][0], mem["rate_true"][0]) == (pitch, gyro)
        assert sim.data.ctrl[lay.a_wheel] == wheel_ctrl(mem[0], float(mem["wheel_command"][0]), wheel_speed)
    assert len(sim.hops) >= 1


def test_realistic_sensing_is_deterministic_per_seed_and_a_reset_replays_it() -> None:
    config = SimConfig(seed=2, sensing="realistic")
    a, b = Simulation(config), Simulation(config)
    first = []
    for _ in range(3000):
        a.step()
        b.step()
        assert np.array_equal(a.data.qpos, b.data.qpos)
        assert a.controller.mem["pitch_est"][0] == b.controller.mem["pitch_est"][0]
        first.append(a.data.qpos.copy())
    a.reset()  # a power cycle: the same IMU draws, the same run
    for qpos in first:
        a.step()
        assert np.array_equal(a.data.qpos, qpos)
    c = Simulation(SimConfig(seed=3, terrain="flat", sensing="realistic"))
    d = Simulation(SimConfig(seed=2, terrain="flat", sensing="realistic"))
    assert c.controller.mem["rng"][0] == d.controller.mem["rng"][0] == 0  # drawn at the first tick
    c.step()
    d.step()
    assert c.controller.mem["gyro_bias"][0] != d.controller.mem["gyro_bias"][0]


def test_power_on_calibration_standing_still() -> None:
    sensor = SensingParams()
    for seed in range(5):
        sim = Simulation(SimConfig(seed=seed, sensing="realistic", sensor=sensor))
        sim.step()
        mem = sim.controller.mem
        # Initial pitch from the averaged accelerometer: off by its offset (<= 1 mg: 0.35 deg on
        # the Moon) and its noise averaged over 1 s (0.06 deg), not by the ~2 deg of one sample.
        offset = math.degrees(sensor.accel_bias * 1e-3 * STANDARD_GRAVITY / MOON)
        assert abs(math.degrees(mem["pitch_est"][0] - mem["pitch_true"][0])) < offset + 0.25
        # Bias from the averaged gyro: 0.44 deg/s / sqrt(1000 samples) = 0.014 deg/s, 1 sigma.
        assert abs(math.degrees(mem["bias_est"][0] - mem["gyro_bias"][0])) < 0.06
        assert abs(math.degrees(mem["gyro_bias"][0])) >= 0.25  # the bias it calibrated away was real


class _EstimateError:
    """Listener: the worst |estimate - truth| of the pitch during flight ticks."""

    def __init__(self) -> None:
        self.worst = 0.0

    def tick(self, sim: Simulation) -> None:
        mem = sim.controller.mem
        if mem["phase"][0] == FLIGHT:
            self.worst = max(self.worst, abs(mem["pitch_est"][0] - mem["pitch_true"][0]))

    def event(self, sim: Simulation, event: object) -> None:
        pass


@pytest.mark.parametrize("terrain", ["flat", "crater"])
@pytest.mark.parametrize("seed", range(5))
def test_hops_on_the_moon_with_realistic_sensing(terrain: str, seed: int) -> None:
    sim = Simulation(SimConfig(terrain=terrain, seed=seed, sensing="realistic"))
    error = _EstimateError()
    sim.listeners.append(error)
    hops = sim.run(7)
    assert len(hops) == 7 and not sim.fallen
    assert max(hop.landing_pitch_deg for hop in hops) <= 3.5
    assert math.degrees(error.worst) < 1.5
