"""A Gymnasium environment for the flight attitude task: `gymnasium.make("hopper/FlightAttitude-v0")`
after `import hopper.gym_env` (README, "Learned control").

The agent flies the wheel in flight through the controller API, as any controller does: the
simulation's flight law is an EnvLaw whose `__call__` returns the agent's pending action. One
env step runs the simulation tick by tick up to the next flight tick that asks for a command;
the ground phases (landing, stance, push) are flown by our gait in between. The torque chosen on
an observation acts at the next control tick (1 ms later: the API's call returns before the agent
is asked); the first tick of each flight gets 0 N m.

Observation: hopper.controllers.features (9 float32, normalised; FIELDS documents each), the last
the integral of pitch since liftoff that the paper's PID keeps, integrated on the agent's actions.
Action: (1,) float32 in [-1, 1], the wheel torque / 29.5 N m (the motor's envelope clamps it). A
finite action outside [-1, 1] is clipped to it, as gymnasium's continuous-control envs (Pendulum,
LunarLander, MountainCarContinuous) do and as the motor would saturate; one that is not a single
finite number (NaN, inf, another shape) raises InvalidAction before anything is simulated.
Reward, per step: -(pitch / 2 deg)^2 * dt * W_PITCH - a^2 * dt * W_TORQUE - W_ENERGY * (electrical
J); at each touchdown -min((pitch / 1 deg)^2 + (rate / 20 deg/s)^2, 25) (true pitch and rate);
a fall ends the episode with FALL_PENALTY.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Literal

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from hopper.config import (
    GRAVITY_LIMITS,
    GRAVITY_PRESETS,
    MOTOR_RESISTANCE,
    MOTOR_TORQUE_CONSTANT,
    WHEEL_GEAR,
    WHEEL_TORQUE_LIMIT,
    GaitParams,
    InvalidConfig,
    SensingParams,
    SimConfig,
)
from hopper.control import EV_FALL, EV_LIFTOFF, EV_TOUCHDOWN
from hopper.control.gait import held_gravity, legs_cap, momentum_capacity
from hopper.controllers.api import Observation
from hopper.controllers.features import HIGH, LOW, SIZE, PitchIntegral, features
from hopper.disturbances import DISTURBANCE_LIMITS
from hopper.errors import HopperError
from hopper.robot import PACKAGED
from hopper.sim import Simulation

ENV_ID = "hopper/FlightAttitude-v0"
W_PITCH, W_TORQUE, W_ENERGY = 1.0, 0.1, 0.01  # per s of (pitch / 2 deg)^2, per s of a^2, per J
LAND_PITCH_DEG, LAND_RATE_DEG_S, LAND_CAP = 1.0, 20.0, 25.0
FALL_PENALTY = -100.0
SPEC = "hopper.gym_env:EnvLaw"
# Model randomisation (hopper.mismatch factors, x nominal), drawn uniformly when `randomise`.
MISMATCH_RANGES = {
    "torso_mass": (0.8, 1.25),
    "wheel_inertia": (0.8, 1.2),
    "motor_torque": (0.85, 1.15),
    "leg_mass": (0.8, 1.3),
    "friction": (0.6, 1.2),
}
GYRO_BIAS_RANGE = (0.0, 1.0)  # deg/s turn-on bias, drawn when `randomise` (realistic sensing)
SEED_DRAW_LIMIT = 2**63  # terrain seeds are drawn as numpy int64: the largest `high` it takes


class InvalidAction(HopperError, ValueError):
    """An action that is not one finite number; nothing was simulated."""


class NoFlight(HopperError, RuntimeError):
    """reset() saw the robot fall before its first flight: the gait could not fly it there."""


def legs_cap_note(gravity: float) -> str:
    """Why the packaged robot may fall before it flies at `gravity` (m/s^2): its legs cap the hop below
    the gait's apex there (hopper.control.gait.legs_cap); "" when they do not."""
    cap = legs_cap(gravity, GaitParams())
    if cap is None:
        return ""
    return (
        f"at {gravity:g} m/s^2 the robot's {PACKAGED.leg_torque_limit:g} N m legs cap the hop at {cap[0]:.2f} m of "
        f"the {cap[1]:g} m asked: expect falls on the ground, some before the first flight"
    )


def max_kick_fraction() -> float:
    """The largest kick_fraction whose kicks the simulation takes: its pitch_kick limit (N m s) over
    the wheel's momentum capacity (N m s)."""
    return DISTURBANCE_LIMITS["pitch_kick"][0] / momentum_capacity()


class EnvLaw:
    """The env's flight law: returns the agent's pending torque (N m), keeps the observation it was
    called with and the agent's pitch integral (reset at each liftoff, as a controller's)."""

    def __init__(self) -> None:
        self.torque = 0.0
        self.obs: Observation | None = None
        self.calls = 0
        self.integral = PitchIntegral()

    def reset(self, obs: Observation) -> None:
        self.integral.reset()

    def __call__(self, obs: Observation) -> float:
        self.obs, self.calls = obs, self.calls + 1
        return self.torque


@dataclasses.dataclass(frozen=True, kw_only=True)
class EnvOptions:
    """What an episode is made of; `reset(options=...)` may override any field for one episode."""

    gravity: float | tuple[float, float] = GRAVITY_PRESETS["moon"]  # m/s^2, or a (low, high) log-uniform range
    terrain: Literal["crater", "flat"] = "crater"
    terrain_seeds: tuple[int, int] = (10_000, 20_000)  # drawn in [low, high); the league's seeds are below
    sensing: Literal["ideal", "realistic"] = "ideal"
    flights: int = 1  # flights an episode lasts
    kick_probability: float = 0.0  # per flight: a pitch kick at a random moment, 0.1-0.8 of the predicted flight
    kick_fraction: float = 0.5  # the largest kick, x the wheel's momentum capacity (1.60 N m s)
    randomise: bool = False  # mismatch factors (MISMATCH_RANGES) and the gyro's turn-on bias

    def __post_init__(self) -> None:
        # Every option is checked here, not when an episode first meets it (a kick mid-episode, a
        # gravity drawn at reset): one line naming the option, its value and what is accepted.
        object.__setattr__(self, "gravity", _gravity(self.gravity))
        SimConfig(terrain=self.terrain, sensing=self.sensing)  # the simulation's own words for these
        object.__setattr__(self, "terrain_seeds", _seeds(self.terrain_seeds))
        if not _integer(self.flights) or self.flights < 1:
            raise InvalidConfig(f"flights must be an integer >= 1, got {self.flights!r}")
        _number("kick_probability", self.kick_probability, 0.0, 1.0, "")
        _number("kick_fraction", self.kick_fraction, 0.0, max_kick_fraction(),
                f" x the wheel's momentum capacity (its kicks stay within the simulation's "
                f"{DISTURBANCE_LIMITS['pitch_kick'][0]:g} {DISTURBANCE_LIMITS['pitch_kick'][1]})")  # fmt: skip
        if not isinstance(self.randomise, (bool, np.bool_)):
            raise InvalidConfig(f"randomise must be True or False, got {self.randomise!r}")

    @classmethod
    def of(cls, base: EnvOptions | None, overrides: dict[str, Any]) -> EnvOptions:
        """`base` (None: the defaults) with `overrides`; InvalidConfig names an unknown option."""
        names = [f.name for f in dataclasses.fields(cls)]
        unknown = sorted(str(k) for k in overrides if k not in names)
        if unknown:
            raise InvalidConfig(f"unknown option {', '.join(unknown)}; the options: {', '.join(names)}")
        return dataclasses.replace(base, **overrides) if base is not None else cls(**overrides)


def _integer(value: object) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def _within(value: object, low: float, high: float) -> bool:
    """A finite number (not a bool) in [low, high]."""
    number = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
    return number and math.isfinite(value) and low <= value <= high  # type: ignore[operator, arg-type]


def _number(name: str, value: object, low: float, high: float, unit: str) -> float:
    if not _within(value, low, high):
        raise InvalidConfig(f"{name} must be a finite number in [{low:g}, {high:g}]{unit}, got {value!r}")
    return float(value)  # type: ignore[arg-type]


def gravity_limits() -> tuple[float, float, str]:
    """(low, high, why) m/s^2: the gravities a Simulation of the packaged robot accepts: the config's
    GRAVITY_LIMITS, and below the one its legs cannot hold it at (hopper.control.gait.derive refuses)."""
    low, high = GRAVITY_LIMITS
    held = math.nextafter(held_gravity(GaitParams()), 0.0)
    return (low, held, " (above, the legs cannot hold the robot)") if held < high else (low, high, "")


def _gravity(value: object) -> float | tuple[float, float]:
    """A gravity (m/s^2) or a (low, high) range of them, inside gravity_limits()."""
    low, high, why = gravity_limits()
    if not isinstance(value, (tuple, list)):
        return _number("gravity", value, low, high, " m/s^2" + why)
    if not (len(value) == 2 and all(_within(v, low, high) for v in value)):
        raise InvalidConfig(
            f"gravity range must be (low, high), each a finite number in [{low:g}, {high:g}] m/s^2{why}, got {value!r}"
        )
    if value[0] > value[1]:
        raise InvalidConfig(f"gravity range must be (low, high) with low <= high, got {value!r}")
    return float(value[0]), float(value[1])


def _seeds(value: object) -> tuple[int, int]:
    """A [low, high) range of terrain seeds the simulation takes and numpy can draw."""
    if not (isinstance(value, (tuple, list)) and len(value) == 2 and all(_integer(v) for v in value)):
        raise InvalidConfig(f"terrain_seeds must be a (low, high) pair of integers, got {value!r}")
    low, high = int(value[0]), int(value[1])
    if not 0 <= low < high <= SEED_DRAW_LIMIT:
        raise InvalidConfig(
            f"terrain_seeds must be (low, high) with 0 <= low < high <= 2^63 (drawn in [low, high)), got {value!r}"
        )
    for seed in (low, high - 1):
        SimConfig(seed=seed)  # the simulation's own bound on a seed
    return low, high


class FlightAttitudeEnv(gym.Env):
    """The wheel in flight, on hopper.sim.Simulation; see the module docstring for spaces and reward."""

    metadata = {"render_modes": []}

    def __init__(self, **options: Any) -> None:
        self.options = EnvOptions.of(None, options)
        self.observation_space = spaces.Box(LOW, HIGH, (SIZE,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)
        self.sim: Simulation | None = None
        self._kick_at, self._kick_size = math.inf, 0.0

    # -- gymnasium ------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        o = EnvOptions.of(self.options, options or {})
        self._episode = o
        config = self._draw_config(o)
        if self.sim is None:
            self.sim = Simulation(config)
        else:
            self.sim.start_over(config)
        self.law: EnvLaw = self.sim.law.controller
        self.flights, self.kicks = 0, 0
        self._kick_at = math.inf
        obs, _, terminated, truncated, info = self._advance()
        if terminated or truncated:  # no flight to act in: the gait could not fly the robot there
            what = "fell" if info.get("fell") else "reached the time limit"
            cap = legs_cap_note(config.gravity)
            where = f"(terrain seed {config.seed}, {info['time']:.2f} s)"
            why = f": {cap}" if cap else f" at {config.gravity:g} m/s^2"
            raise NoFlight(f"the robot {what} before its first flight {where}{why}")
        return obs, info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        if self.sim is None:
            raise gym.error.ResetNeeded("call reset() before step()")
        a = _action(action)
        low, high = self.law.obs.torque_bounds
        tau = min(max(a * WHEEL_TORQUE_LIMIT, low), high)
        self.law.torque = a * WHEEL_TORQUE_LIMIT
        self.law.integral.update(self.law.obs, self.law.torque)  # as a Policy does on its own command
        obs, reward, terminated, truncated, info = self._advance()
        dt = self.sim.config.timestep
        current = tau / (WHEEL_GEAR * MOTOR_TORQUE_CONSTANT)  # A
        watts = max(current * current * MOTOR_RESISTANCE + tau * self.law.obs.wheel_speed, 0.0)  # no regeneration
        pitch = self.law.obs.pitch / math.radians(2.0)
        reward -= (W_PITCH * pitch * pitch + W_TORQUE * a * a) * dt + W_ENERGY * watts * dt
        return obs, reward, terminated, truncated, info

    # -- inside ---------------------------------------------------------------------------
    def _draw_config(self, o: EnvOptions) -> SimConfig:
        rng = self.np_random
        g = o.gravity
        if isinstance(g, tuple):  # clipped: exp(log(low)) may fall an ulp outside the range
            g = min(max(float(math.exp(rng.uniform(math.log(g[0]), math.log(g[1])))), g[0]), g[1])
        mismatch, sensor = (), SensingParams()
        if o.randomise:
            mismatch = tuple((k, float(rng.uniform(*r))) for k, r in MISMATCH_RANGES.items())
            sensor = SensingParams(gyro_turn_on_bias=float(rng.uniform(*GYRO_BIAS_RANGE)))
        seed = int(rng.integers(*o.terrain_seeds))
        return SimConfig(seed=seed, terrain=o.terrain, gravity=float(g), sensing=o.sensing, sensor=sensor,
                         controller=SPEC, mismatch=mismatch)  # fmt: skip

    def _advance(self) -> tuple[np.ndarray, float, bool, bool, dict]:
        """Step ticks until the law's next call (an observation), a touchdown of the last flight, a
        fall or the time limit. Returns (obs, reward of landings and falls, terminated, truncated, info)."""
        sim, law, o = self.sim, self.law, self._episode
        if law.obs is not None and law.obs.time_since_liftoff >= self._kick_at * (
            law.obs.time_since_liftoff + law.obs.time_to_touchdown
        ):
            self._kick_at = math.inf
            self.kicks += 1
            sim.disturb("pitch_kick", self._kick_size)
        calls, reward, limit = law.calls, 0.0, sim.time_limit(o.flights)
        while True:
            events = sim.step()
            if events & EV_FALL or sim.fallen:
                return self._obs(), reward + FALL_PENALTY, True, False, self._info(fell=True)
            if events & EV_TOUCHDOWN:
                self.flights += 1
                law.torque = 0.0
                reward += self._landing()
                if self.flights >= o.flights:
                    return self._obs(), reward, True, False, self._info()
            if events & EV_LIFTOFF:
                self._flight_started()
            if law.calls != calls:
                return self._obs(), reward, False, False, self._info()
            if sim.time >= limit:
                return self._obs(), reward, False, True, self._info()

    def _flight_started(self) -> None:
        # Every draw happens here, whatever the policy does next, so candidates compared on one
        # seed meet the same kicks (common random numbers). The moment is a fraction of the flight
        # the observation predicts, not of the nominal one: on a crater a flight may end early,
        # and a kick 1 ms before touchdown (or after it) makes the return a lottery on timing.
        o, rng = self._episode, self.np_random
        kick, at, size = rng.uniform() < o.kick_probability, rng.uniform(0.1, 0.8), rng.uniform(-1.0, 1.0)
        self._kick_at = float(at) if kick else math.inf  # fraction of the predicted flight
        limit = DISTURBANCE_LIMITS["pitch_kick"][0]  # kick_fraction <= limit / capacity, but for rounding
        self._kick_size = min(max(float(size) * o.kick_fraction * momentum_capacity(), -limit), limit)  # N m s

    def _landing(self) -> float:
        s = self.sim.state()
        p = math.degrees(s.pitch) / LAND_PITCH_DEG
        r = math.degrees(s.pitch_rate) / LAND_RATE_DEG_S
        return -min(p * p + r * r, LAND_CAP)

    def _obs(self) -> np.ndarray:
        obs = self.law.obs if self.law.obs is not None else self.sim.observation()
        return features(obs, self.law.integral.value).astype(np.float32)

    def _info(self, fell: bool = False) -> dict:
        info = {"flights": self.flights, "fell": fell, "time": self.sim.time, "kicks": self.kicks}
        hops = self.sim.hops
        if hops and hops[-1].completed:
            info["landing_error_deg"] = hops[-1].landing_error_deg  # signed, deg, the last touchdown's
        return info


def _action(action: object) -> float:
    """The action as a float in [-1, 1]; InvalidAction if it is not one finite number."""
    try:
        if action is None:  # numpy reads it as NaN
            raise TypeError
        a = np.asarray(action, dtype=float)
    except (TypeError, ValueError):
        raise InvalidAction(f"action must be one finite number in [-1, 1], got {action!r:.60}") from None
    if a.size != 1:
        raise InvalidAction(f"action must be one number in [-1, 1] (shape (1,)), got shape {a.shape}")
    value = float(a.reshape(-1)[0])
    if not math.isfinite(value):
        raise InvalidAction(f"action must be a finite number in [-1, 1], got {value}")
    return min(max(value, -1.0), 1.0)  # outside: clipped, as the motor saturates


def make_vector(n: int, **options: Any) -> gym.vector.SyncVectorEnv:
    """n environments stepped together in this process (gymnasium.vector.SyncVectorEnv)."""
    return gym.vector.SyncVectorEnv([lambda: FlightAttitudeEnv(**options) for _ in range(n)])


if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point="hopper.gym_env:FlightAttitudeEnv", max_episode_steps=None)
