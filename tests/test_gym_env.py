"""The FlightAttitude Gymnasium environment: registered, check_env, seeded, vectorised."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from hopper.config import GRAVITY_LIMITS, GRAVITY_PRESETS, GaitParams, InvalidConfig
from hopper.control.gait import derive, momentum_capacity
from hopper.controllers.features import NAMES, SCALES, SIZE
from hopper.disturbances import DISTURBANCE_LIMITS
from hopper.gym_env import (
    ENV_ID,
    FALL_PENALTY,
    FlightAttitudeEnv,
    InvalidAction,
    NoFlight,
    gravity_limits,
    legs_cap_note,
    make_vector,
    max_kick_fraction,
)

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


KICK_MAX = DISTURBANCE_LIMITS["pitch_kick"][0] / momentum_capacity()  # the simulation's limit, x capacity
HELD = gravity_limits()[1]  # checked against the gait's own refusal below


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"flights": 0}, "flights must be an integer >= 1, got 0"),
        ({"flights": 1.5}, "flights must be an integer >= 1, got 1.5"),
        # Accepted, then a crash mid-episode: "pitch_kick magnitude must be ... in [-5, 5] N m s, got 7.19".
        ({"kick_fraction": 5, "kick_probability": 1.0}, f"kick_fraction must be a finite number in [0, {KICK_MAX:g}]"),
        ({"kick_fraction": -0.1}, "kick_fraction must be a finite number in [0, "),
        ({"kick_probability": float("nan")}, "kick_probability must be a finite number in [0, 1], got nan"),
        ({"kick_probability": 1.5}, "kick_probability must be a finite number in [0, 1], got 1.5"),
        # numpy's bare "high - low < 0" at reset:
        ({"gravity": (5, 1)}, "gravity range must be (low, high) with low <= high, got (5, 1)"),
        ({"gravity": (0.0, 1)}, f"gravity range must be (low, high), each a finite number in [{GRAVITY_LIMITS[0]:g}, "),
        ({"gravity": (1, float("inf"))}, "gravity range must be (low, high), each a finite number in ["),
        ({"gravity": (1, 2, 3)}, "gravity range must be (low, high), each a finite number in ["),
        ({"gravity": float("nan")}, "gravity must be a finite number in ["),
        ({"gravity": -1.6}, "gravity must be a finite number in ["),
        # A ValueError at reset:
        ({"gravity": 25.0}, f"gravity must be a finite number in [0.05, {HELD:g}] m/s^2 (above, the legs cannot hold"),
        ({"terrain": "moon"}, "terrain must be 'crater' or 'flat', got 'moon'"),
        ({"sensing": "noisy"}, "sensing must be 'ideal' or 'realistic', got 'noisy'"),
        ({"terrain_seeds": (5, 5)}, "terrain_seeds must be (low, high) with 0 <= low < high <= 2^63"),
        ({"terrain_seeds": (-1, 5)}, "terrain_seeds must be (low, high) with 0 <= low < high <= 2^63"),
        ({"terrain_seeds": (0, 1.5)}, "terrain_seeds must be a (low, high) pair of integers, got (0, 1.5)"),
        ({"randomise": "yes"}, "randomise must be True or False, got 'yes'"),
        ({"kicks": 1}, "unknown option kicks; the options: gravity, terrain, terrain_seeds, sensing, flights, "),
    ],
)
def test_every_bad_option_is_refused_at_construction_in_one_line_naming_it(options: dict, message: str) -> None:
    for make in (lambda: gym.make(ENV_ID, **options), lambda: FlightAttitudeEnv().reset(seed=0, options=options)):
        with pytest.raises(InvalidConfig) as info:
            make()
        assert str(info.value).startswith(message) and "\n" not in str(info.value), str(info.value)


def test_the_limits_are_the_simulations_own() -> None:
    low, high, _ = gravity_limits()
    assert low == GRAVITY_LIMITS[0] and high < GRAVITY_LIMITS[1]  # the packaged robot's legs bind first
    derive(high, GaitParams())  # the gait the simulation derives takes the highest accepted gravity
    with pytest.raises(ValueError, match="the legs cannot hold the robot"):
        derive(float(np.nextafter(high, np.inf)), GaitParams())  # and refuses the next one up
    assert max_kick_fraction() == KICK_MAX


def test_the_largest_kicks_accepted_fly_through_their_episodes() -> None:
    env = FlightAttitudeEnv(kick_fraction=max_kick_fraction(), kick_probability=1.0, flights=2)
    for seed in range(3):
        obs, _ = env.reset(seed=seed)
        done = False
        while not done:
            obs, reward, terminated, truncated, info = env.step(pd(obs))
            done = terminated or truncated
        assert info["kicks"] >= 1 and np.isfinite(reward)


def test_a_gravity_range_whose_end_exp_log_rounds_outside_is_drawn_inside_it() -> None:
    """exp(log(0.05)) is 0.05 + 7e-18: a draw at the range's end was refused by the SimConfig at reset."""
    low = GRAVITY_LIMITS[0]
    env = FlightAttitudeEnv(gravity=(low, low), terrain="flat")
    assert env._draw_config(env.options).gravity == low


def trace(env: FlightAttitudeEnv, actions: list) -> list:
    """(obs, reward, terminated) of each step of actions, after reset(seed=5)."""
    out = [env.reset(seed=5)[0]]
    for a in actions:
        obs, reward, terminated, truncated, _ = env.step(a)
        out.append((obs, reward, terminated, truncated))
    return out


@pytest.mark.parametrize(
    ("action", "message"),
    [
        (np.array([np.nan], np.float32), "action must be a finite number in [-1, 1], got nan"),
        (np.array([np.inf], np.float32), "action must be a finite number in [-1, 1], got inf"),
        (np.zeros(2, np.float32), "action must be one number in [-1, 1] (shape (1,)), got shape (2,)"),
        (None, "action must be one finite number in [-1, 1], got None"),
        ("up", "action must be one finite number in [-1, 1], got 'up'"),
    ],
)
def test_an_action_that_is_no_finite_number_is_refused_at_once_and_changes_nothing(
    action: object, message: str | None, capsys: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    """A NaN gave 'EnvLaw returned nan N m' in the log, a NaN reward and terminated=False; the next
    step then ended the episode (the PID had taken over)."""
    good = [np.array([0.2 * np.sin(i / 5.0)], np.float32) for i in range(30)]
    env = gym.make(ENV_ID)  # with gymnasium's own wrappers (the passive checker, order enforcing)
    expected = trace(env, good)
    env.reset(seed=5)
    for a in good[:10]:
        env.step(a)
    with pytest.raises(InvalidAction) as info:
        env.step(action)
    assert str(info.value) == message
    got = [env.step(a) for a in good[10:]]  # the episode goes on as if the bad action had never come
    for (obs, reward, terminated, truncated), step in zip(expected[11:], got, strict=True):
        assert np.array_equal(obs, step[0]) and reward == step[1] and (terminated, truncated) == step[2:4]
    assert capsys.readouterr().out == "" and not [r for r in caplog.records if r.levelno >= 30], caplog.text


def test_a_finite_action_outside_the_box_is_clipped_as_the_motor_saturates() -> None:
    """The gymnasium habit for continuous actions (Pendulum, LunarLander): clipped, not refused."""
    runs = [trace(FlightAttitudeEnv(), [np.array([a], np.float32)] * 40) for a in (1.0, 7.5)]
    for one, other in zip(runs[0][1:], runs[1][1:], strict=True):
        assert np.array_equal(one[0], other[0]) and one[1:] == other[1:]


def test_a_step_before_reset_says_so() -> None:
    with pytest.raises(gym.error.ResetNeeded, match="call reset"):
        FlightAttitudeEnv().step(np.zeros(1, np.float32))


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


def test_a_reset_without_a_flight_says_why_in_one_line() -> None:
    """At 16.5 m/s^2 the paper's 30 N m legs lift the robot 0.02 m and it falls in its first push:
    reset() raised RuntimeError("episode ended before a flight: {'flights': 0, ...}")."""
    env = FlightAttitudeEnv(gravity=16.5)
    said = (
        r"^the robot fell before its first flight \(terrain seed \d+, 1\.\d\d s\): at 16\.5 m/s\^2 the robot's 30 N m "
    )
    with pytest.raises(NoFlight, match=said + r"legs cap the hop at 0\.02 m of the 0\.25 m asked"):
        env.reset(seed=0)
    assert isinstance(NoFlight("x"), RuntimeError)  # as it was: `except RuntimeError` still catches it
    assert legs_cap_note(GRAVITY_PRESETS["mars"]) == ""  # the legs lift the gait's apex there
    assert derive(GRAVITY_PRESETS["mars"], GaitParams()).apex == GaitParams().apex_height
