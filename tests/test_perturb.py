"""The mouse's spring (hopper.perturb): it pulls, it is capped, it composes with other pushes, and its
release is recorded as a disturbance with what the pull added up to."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hopper.commands import Grab, PullTo, Release
from hopper.config import SimConfig
from hopper.events import CommandFailed, Dragged, EventKind
from hopper.perturb import PULL_MAX_ACCEL
from hopper.sim import Simulation


@pytest.fixture
def sim() -> Simulation:
    s = Simulation(SimConfig(terrain="flat"))
    for _ in range(200):
        s.step()
    return s


def _torso(sim: Simulation) -> tuple[float, float]:
    p = sim.data.xpos[sim.layout.torso]
    return float(p[0]), float(p[2])


def test_a_pull_forward_moves_the_robot_and_its_release_is_a_disturbance_event(sim: Simulation) -> None:
    x, z = _torso(sim)
    sim.submit(Grab((x, z)))
    sim.step()
    assert abs(sim.pull.peak_force) < 5.0  # grabbed where it is: no stretch, only damping
    sim.submit(PullTo((x + 0.3, z)))
    for _ in range(600):
        sim.step()
    assert _torso(sim)[0] > x + 0.1
    impulse = sim.pull.impulse.copy()
    sim.submit(Release())
    sim.step()
    (event,) = [e for e in sim.events if isinstance(e.payload, Dragged)]
    drag = event.payload
    assert event.kind == EventKind.DISTURBANCE and drag.disturbance == "drag"
    # What acted: the sum so far, less the force set for the step the release cancelled (one tick's).
    assert abs(drag.impulse_x - impulse[0]) <= PULL_MAX_ACCEL * 8.2 * 1e-3 and drag.impulse_x > 1.0
    assert drag.duration_s == pytest.approx(0.601, abs=2e-3)
    assert "drag +" in event.describe() and "N s forward" in event.describe()
    assert np.allclose(sim.data.xfrc_applied[sim.layout.torso], 0.0, atol=1e-9)  # the force is gone
    assert sim.pull is None


def test_the_pull_is_capped_by_the_robots_mass(sim: Simulation) -> None:
    x, z = _torso(sim)
    sim.submit(Grab((x, z)))
    sim.submit(PullTo((x + 50.0, z)))  # a wild drag far off screen
    for _ in range(20):
        sim.step()
    mass = float(sim.model.body_subtreemass[sim.layout.torso])
    assert sim.pull.peak_force == pytest.approx(PULL_MAX_ACCEL * mass, rel=1e-9)
    force = sim.data.xfrc_applied[sim.layout.torso, :3]
    assert float(np.linalg.norm(force)) <= PULL_MAX_ACCEL * mass * (1 + 1e-9)


def test_a_pull_composes_with_a_torque_pulse_on_the_same_body(sim: Simulation) -> None:
    torso = sim.layout.torso
    sim.data.xfrc_applied[torso, 4] = 3.0  # someone else's pitch torque, e.g. a torque pulse
    x, z = _torso(sim)
    sim.submit(Grab((x + 0.1, z + 0.1)))  # off the CoM: the pull adds a moment
    sim.submit(PullTo((x + 0.3, z + 0.1)))
    for _ in range(10):
        sim.step()
    sim.submit(Release())
    sim.step()
    assert sim.data.xfrc_applied[torso, 4] == pytest.approx(3.0, abs=1e-9)
    assert np.allclose(np.delete(sim.data.xfrc_applied[torso], 4), 0.0, atol=1e-9)


def test_a_reset_ends_a_pull_unrecorded_and_bad_points_are_refused(sim: Simulation) -> None:
    x, z = _torso(sim)
    sim.submit(Grab((x, z)))
    sim.submit(PullTo((x + 0.3, z)))
    for _ in range(10):
        sim.step()
    sim.reset(reason="user")
    assert sim.pull is None and not any(isinstance(e.payload, Dragged) for e in sim.events)
    sim.submit(PullTo((x + 0.3, z)))  # the drag's next update, after the reset: ignored
    sim.submit(Grab((math.nan, z)))
    sim.step()
    assert sim.pull is None
    failed = [e.payload for e in sim.events if isinstance(e.payload, CommandFailed)]
    assert len(failed) == 1 and "grab x" in failed[0].describe()
