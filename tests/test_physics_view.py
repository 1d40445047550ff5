"""The physics overlays (app/dashboard/physics.py) on a real viser scene: the ground's push on the feet
in stance, the predicted arc and landing in flight, the mouse's pull, and the View panel's switch."""

from __future__ import annotations

import numpy as np
import pytest
import viser
from hopper.app.dashboard.physics import WEIGHT_M, PhysicsView
from net import free_port

from hopper.commands import Grab, PullTo
from hopper.config import SimConfig
from hopper.control import Phase
from hopper.sim import Simulation

pytestmark = pytest.mark.integration  # servers, processes or pools (conftest: the suite in parts)


@pytest.fixture
def scene():
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    yield server.scene
    server.stop()


def _arrow(view: PhysicsView, side: int) -> np.ndarray:
    return np.asarray(view.forces[side].points)[0]


def test_standing_the_arrows_carry_the_robots_weight(scene) -> None:
    sim = Simulation(SimConfig(terrain="flat"))
    view = PhysicsView(scene, sim)
    for _ in range(50):  # 50 ms standing still, before the crouch
        sim.step()
    view.update(sim, now=0.0)
    assert all(arrow.visible for arrow in view.forces)
    rise = sum(_arrow(view, side)[1, 2] - _arrow(view, side)[0, 2] for side in range(2))
    assert rise == pytest.approx(WEIGHT_M, rel=0.05)  # both feet together push up one weight
    assert all(abs(_arrow(view, side)[0, 2]) < 0.01 for side in range(2))  # from the contact, on the ground


def test_in_flight_the_arc_and_the_landing_marks_show_and_stance_hides_them(scene) -> None:
    sim = Simulation(SimConfig(terrain="flat"))
    view = PhysicsView(scene, sim)
    while not (sim.phase is Phase.FLIGHT and sim.data.sensordata[sim.layout.s_com_vel + 2] < 0.0):
        sim.step()
    view.update(sim, now=0.0)
    assert view.arc.visible and all(mark.visible for mark in view.marks)
    assert not any(arrow.visible for arrow in view.forces)
    points = np.asarray(view.arc.points)
    assert points[0, 0, 0] < sim.state().x < points[-1, 1, 0]  # drawn from the liftoff on, to the landing
    landing_x = [float(mark.position[0]) for mark in view.marks]
    while sim.phase is Phase.FLIGHT:
        sim.step()
    feet = [float(sim.data.geom_xpos[sim.model.geom(f"foot_{s}").id][0]) for s in "LR"]
    assert np.allclose(landing_x, feet, atol=0.015), (landing_x, feet)
    view.update(sim, now=1.0)
    assert not view.arc.visible and not any(mark.visible for mark in view.marks)


def test_the_pull_is_drawn_from_the_grabbed_point_to_the_pointer_and_the_switch_hides_all(scene) -> None:
    sim = Simulation(SimConfig(terrain="flat"))
    view = PhysicsView(scene, sim)
    x, z = sim.state().x, sim.state().z
    sim.submit(Grab((x, z)))
    sim.submit(PullTo((x + 0.4, z + 0.1)))
    sim.step()
    view.update(sim, now=0.0)
    start, end = np.asarray(view.pull.points)[0]
    assert view.pull.visible and end[0] == pytest.approx(x + 0.4) and end[2] == pytest.approx(z + 0.1)
    assert start[0] == pytest.approx(x, abs=0.01)
    view.visible = False
    view.update(sim, now=1.0)
    assert not view.pull.visible and not any(arrow.visible for arrow in view.forces)
