"""The FlightAttitude Gymnasium environment: registered, check_env, seeded, vectorised."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from hopper.controllers.features import NAMES, SCALES, SIZE
from hopper.gym_env import ENV_ID, FALL_PENALTY, FlightAttitudeEnv, make_vector

PD = np.array([450.0 * 0.1, 30.0]) / 29.5  # the paper's PD on the normalised pitch and rate


def pd(obs: np.ndarray) -> np.ndarray:
    return np.array([np.clip(PD @ obs[:2], -1, 1)], np.float32)


def test_gymnasium_make_finds_it_and_check_env_passes() -> None:
    env = gym.make(ENV_ID)
    assert env.observation_space.shape == (SIZE,) and env.action_space.shape == (1,)
    check_env(env.unwrapped)
    env.close()


def test_one_seed_gives_identical_observations_with_every_randomisation_on() -> None:
    options = {"sensing": "realistic", "randomise": True, "kick_probability": 1.0, "gravity": (0.3, 5.0), "flights": 2}
    runs = []
    for _ in range(2):
        env = FlightAttitudeEnv(**options)
        obs, _ = env.reset(seed=7)
        trace = [obs]
        for i in range(400):
            obs, reward, terminated, truncated, info = env.step(np.array([0.3 * np.sin(i / 30.0)], np.float32))
            trace.append(np.append(obs, reward))
            if terminated or truncated:
                break
        runs.append(np.concatenate(trace))
    assert np.array_equal(runs[0], runs[1])
    other = FlightAttitudeEnv(**options)
    assert not np.array_equal(other.reset(seed=8)[0], runs[0][:SIZE])


def test_a_kicked_pd_flight_ends_at_the_touchdown_level_and_a_wheel_left_off_costs_more() -> None:
    returns = {}
    for name, policy in (("pd", pd), ("off", lambda obs: np.zeros(1, np.float32))):
        env = FlightAttitudeEnv(terrain="flat", kick_probability=1.0)
        obs, _ = env.reset(seed=3)
        total, done = 0.0, False
        while not done:
            obs, reward, terminated, truncated, info = env.step(policy(obs))
            total, done = total + reward, terminated or truncated
        assert terminated and info["flights"] == 1
        returns[name] = (total, info)
    assert abs(returns["pd"][1]["landing_error_deg"]) < 1.0
    assert returns["off"][0] < returns["pd"][0] - 1.0  # kicked with the wheel off: it lands badly, or falls
    assert returns["pd"][0] > FALL_PENALTY / 10


def test_the_vector_env_steps() -> None:
    envs = make_vector(2, terrain="flat")
    obs, _ = envs.reset(seed=0)
    assert obs.shape == (2, SIZE) and obs.dtype == np.float32
    for _ in range(20):
        obs, rewards, terminated, truncated, _ = envs.step(np.zeros((2, 1), np.float32))
    assert obs.shape == (2, SIZE) and rewards.shape == (2,)
    envs.close()


def test_bad_options_are_refused() -> None:
    with pytest.raises(ValueError, match="flights"):
        FlightAttitudeEnv(flights=0)


def test_every_kick_drawn_lands_inside_its_flight() -> None:
    # The kick's moment is a fraction of the flight the observation predicts: a crater flight that
    # ends early still gets its kick, never one in its last milliseconds or after its touchdown.
    env = FlightAttitudeEnv(kick_probability=1.0, flights=3, gravity=(0.5, 5.0))
    for seed in range(6):  # seed 4 lost its last kick when the moment was the nominal flight's
        obs, _ = env.reset(seed=seed)
        done = False
        while not done:
            obs, reward, terminated, truncated, info = env.step(pd(obs))
            done = terminated or truncated
        assert info["kicks"] == info["flights"] == 3 and not info["fell"]


def test_the_last_feature_is_the_pitch_integral_since_liftoff() -> None:
    env = FlightAttitudeEnv(flights=2, sensing="realistic")
    obs, _ = env.reset(seed=4)
    integral, last_since, done, liftoffs = 0.0, -1.0, False, 0
    while not done:
        raw = env.law.obs
        if raw.time_since_liftoff < last_since:  # a new flight: the integral starts again
            integral, liftoffs = 0.0, liftoffs + 1
        last_since = raw.time_since_liftoff
        assert obs[NAMES.index("pitch_integral")] == pytest.approx(integral / SCALES[-1], abs=1e-4)
        obs, reward, terminated, truncated, info = env.step(pd(obs))  # PD's torque: far from saturation
        integral += raw.pitch * raw.dt
        done = terminated or truncated
    assert liftoffs == 1 and integral != 0.0
