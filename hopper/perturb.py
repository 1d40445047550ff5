"""Mouse perturbation: a spring that pulls a grabbed point of the torso toward the pointer.

As in MuJoCo's `simulate`, the spring is scaled by the mass it moves: stiffness m w^2 and critical
damping 2 m w for the whole robot, so a drag feels the same on any body and at any gravity. The
force acts at the grabbed point (a force at the torso's CoM plus the moment of its offset), is
capped at PULL_MAX_ACCEL times the robot's mass, and is summed while it acts: the impulse and peak
force are what the disturbance event reports on release.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Protocol

import mujoco
import numpy as np

PULL_OMEGA = 8.0  # rad/s, natural frequency of the robot on the spring (about 1.3 Hz: a hand's pull)
PULL_MAX_ACCEL = 10.0  # m/s^2: the pull never exceeds this times the robot's mass


class Physics(Protocol):
    """What a pull needs of the simulation it listens to (a hopper.sim.Simulation): its model and data.

    A Protocol, not hopper.sim's class: hopper.sim imports this module, which must not import it back.
    """

    @property
    def model(self) -> mujoco.MjModel: ...

    @property
    def data(self) -> mujoco.MjData: ...


@dataclasses.dataclass
class Pull:
    """A spring from a point fixed in one body (`anchor`, body frame, m) to a world target (x, z, m)."""

    body: int
    anchor: np.ndarray  # (3,), m, in the body's frame
    target: np.ndarray  # (2,), world (x, z), m
    mass: float  # kg, what the spring is scaled for
    started: float  # s, simulation time of the grab
    impulse: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(2))  # N s, world (x, z)
    peak_force: float = 0.0  # N
    _applied: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(6))  # what it added to xfrc_applied
    _pending: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(2))  # impulse of the step to come

    @classmethod
    def grab(cls, model: mujoco.MjModel, data: mujoco.MjData, body: int, point: tuple[float, float]) -> Pull:
        """Grab `body` at world (x, z) `point` (on or near it); the target starts there: no force yet."""
        world = np.array([point[0], 0.0, point[1]])
        anchor = data.xmat[body].reshape(3, 3).T @ (world - data.xpos[body])
        mass = float(model.body_subtreemass[model.body_rootid[body]])
        return cls(body, anchor, np.array(point, dtype=float), mass, float(data.time))

    def anchor_world(self, data: mujoco.MjData) -> np.ndarray:
        """The grabbed point now, world (x, y, z), m."""
        return data.xpos[self.body] + data.xmat[self.body].reshape(3, 3) @ self.anchor

    def force(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        """The spring's world force now (x, y, z), N: stiffness on the stretch, damping on the point's velocity."""
        point = self.anchor_world(data)
        velocity = np.zeros(6)  # [angular, linear] at the body's origin, world axes
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, self.body, velocity, 0)
        v = velocity[3:] + np.cross(velocity[:3], point - data.xpos[self.body])
        stretch = np.array([self.target[0] - point[0], 0.0, self.target[1] - point[2]])
        f = self.mass * (PULL_OMEGA**2 * stretch - 2.0 * PULL_OMEGA * v * np.array([1.0, 0.0, 1.0]))
        limit = PULL_MAX_ACCEL * self.mass
        norm = float(np.linalg.norm(f))
        return f * (limit / norm) if norm > limit else f

    def apply(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Replace last tick's contribution to xfrc_applied by this tick's (other pushes there stay)."""
        f = self.force(model, data)
        moment = np.cross(self.anchor_world(data) - data.xipos[self.body], f)  # xfrc acts at the CoM
        contribution = np.concatenate([f, moment])
        data.xfrc_applied[self.body] += contribution - self._applied
        self._applied = contribution
        self._pending = f[[0, 2]] * model.opt.timestep
        self.impulse += self._pending
        self.peak_force = max(self.peak_force, float(np.linalg.norm(f)))

    def remove(self, data: mujoco.MjData) -> None:
        """Take this pull's force off the body (the step it was set for will not come)."""
        data.xfrc_applied[self.body] -= self._applied
        self._applied = np.zeros(6)
        self.impulse -= self._pending
        self._pending = np.zeros(2)

    # -- a Simulation listener while it acts: after each step, the force for the next ------------
    def tick(self, sim: Physics) -> None:
        self.apply(sim.model, sim.data)

    def event(self, sim: Physics, event: Any) -> None:
        pass
