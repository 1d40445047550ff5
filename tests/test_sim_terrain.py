"""The simulation on endless terrain: the window moves in flight, in place, with an unchanged overlap;
the ground the controller and MuJoCo see is the field's at world x; snapshots carry the window."""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest
from hopper.app.episode import shortfall
from hopper.terrain import to_hfield

from hopper import keyframes
from hopper.config import SimConfig
from hopper.control import Phase
from hopper.control.landing import FOOT_Y
from hopper.sim import Simulation


class MoveWatch:
    """A listener that keeps the model's hfield data and the phase each time the window moved."""

    def __init__(self, sim: Simulation) -> None:
        self.first, self.data = sim.terrain.first, sim.model.hfield_data.copy()
        self.moves: list[tuple[int, int, np.ndarray, np.ndarray, Phase]] = []

    def tick(self, sim: Simulation) -> None:
        if sim.terrain.first != self.first:
            data = sim.model.hfield_data.copy()
            self.moves.append((self.first, sim.terrain.first, self.data, data, sim.phase))
            self.first, self.data = sim.terrain.first, data

    def event(self, sim: Simulation, event: object) -> None:
        pass


def _hfield(data: np.ndarray, sim: Simulation) -> np.ndarray:
    return data.reshape(sim.model.hfield_nrow[0], sim.model.hfield_ncol[0])


def test_a_run_hops_on_past_the_start_window_moving_it_in_flight_with_the_overlap_unchanged() -> None:
    sim = Simulation(SimConfig(seed=0))
    watch = MoveWatch(sim)
    sim.listeners.append(watch)
    sim.run(45)
    assert len(sim.hops) == 45 and not sim.fallen and shortfall(sim, 45) is None
    assert sim.state().x > sim.config.craters.x0 + sim.config.craters.length  # past the old strip's end
    assert watch.moves, "the window never moved"
    for before, after, old, new, phase in watch.moves:
        assert phase is Phase.FLIGHT  # at an apex, feet off the ground
        shift = after - before
        old, new = _hfield(old, sim), _hfield(new, sim)
        assert 0 < shift <= old.shape[1] - 200  # at least 10 m shared
        assert np.array_equal(new[:, : old.shape[1] - shift], old[:, shift:])  # float32, bit for bit
    # The model holds the window where it says it is, at the field's fixed scale.
    window, model = sim.terrain, sim.model
    data, elevation, offset = to_hfield(window.heights, window.field.vertical_range)
    assert np.array_equal(model.hfield_data, data.ravel().astype(np.float32))
    assert model.geom("terrain").pos.tolist() == pytest.approx([window.x0 + 15.0, 0.0, offset])
    # World x is continuous: the hops' distances add up to the torso's travel.
    assert sum(h.distance_m for h in sim.hops) == pytest.approx(sim.metrics.progress.last_touchdown_x, abs=0.2)


def test_the_ground_under_the_feet_is_the_fields_at_world_x_what_mujoco_collides_with() -> None:
    sim = Simulation(SimConfig(seed=4))
    sim.terrain.place(sim.terrain.first + 1337)  # 66.85 m along, as a long run leaves it
    from hopper.model import set_terrain

    set_terrain(sim.model, sim.terrain)
    mujoco.mj_forward(sim.model, sim.data)
    field, cell = sim.terrain.field, sim.config.craters.cell
    for x in np.linspace(sim.terrain.x0 + 1.0, sim.terrain.x1 - 1.0, 40):
        j = round(x / cell)
        x = j * cell  # a grid column: the planner's bilinear and MuJoCo's triangles agree there
        row = round((FOOT_Y + sim.config.craters.width / 2) / cell)  # the grid row nearest the left foot's
        y = -sim.config.craters.width / 2 + row * cell
        expected = field.columns(j, 1)[row, 0]
        assert sim.terrain.height(x, y) == pytest.approx(expected, abs=1e-12)
        assert sim._ground(x, 0) == sim.terrain.height(x, FOOT_Y)  # what the landing planner reads
        hit = np.zeros(1, np.int32)
        top = 2.0
        dist = mujoco.mj_ray(sim.model, sim.data, np.array([x, y, top]), np.array([0.0, 0.0, -1.0]), None, 1, -1, hit)
        assert top - dist == pytest.approx(expected, abs=1e-6)  # float32 data, 1 um


def _run_to_move(sim: Simulation) -> None:
    moves = sim.terrain.moves
    while sim.terrain.moves == moves:
        sim.step()
        assert not sim.fallen


def _trajectory(sim: Simulation, ticks: int) -> np.ndarray:
    rows = []
    for _ in range(ticks):
        sim.step()
        rows.append(sim.data.qpos.copy())
    return np.array(rows)


def test_a_restore_across_a_window_move_repeats_the_run_bit_for_bit() -> None:
    sim = Simulation(SimConfig(seed=0))
    while sim.state().x < sim.terrain.x1 - 10.0 - 2.0:  # two hops or so before the first move
        sim.step()
    before = sim.snapshot()
    assert before.terrain_first == sim.terrain.start
    _run_to_move(sim)
    moved = sim.snapshot()
    assert moved.terrain_first != sim.terrain.start
    after = _trajectory(sim, 3000)

    # Back across the move: the window returns to where it stood, the move happens again.
    sim.restore(before)
    assert sim.terrain.first == sim.terrain.start
    _run_to_move(sim)
    assert sim.time == moved.time and sim.terrain.first == moved.terrain_first
    assert np.array_equal(_trajectory(sim, 3000), after)

    # Forward into a fresh simulation, whose window is at the start, and through a keyframe file.
    for restore in (lambda s: s.restore(moved), lambda s: keyframes.apply(s, _through_json(moved, s))):
        other = Simulation(SimConfig(seed=0))
        restore(other)
        assert other.terrain.first == moved.terrain_first
        assert np.array_equal(other.model.hfield_data, sim.model.hfield_data)
        assert np.array_equal(_trajectory(other, 3000), after)


def _through_json(snap, sim: Simulation) -> keyframes.Keyframe:
    text = keyframes.to_json(keyframes.Keyframe("moved", snap))
    assert json.loads(text)["terrain_first"] == snap.terrain_first
    return keyframes.from_json(text, sim)


def test_a_reset_brings_the_window_back_to_the_start() -> None:
    sim = Simulation(SimConfig(seed=0))
    sim.terrain.place(sim.terrain.first + 500)
    sim.reset()
    fresh = Simulation(SimConfig(seed=0))
    assert sim.terrain.first == sim.terrain.start
    assert np.array_equal(sim.model.hfield_data, fresh.model.hfield_data)
    assert np.array_equal(sim.model.geom_pos, fresh.model.geom_pos)


def test_a_drag_past_the_windows_edge_moves_it_on_the_ground() -> None:
    """No flight, no apex: the health check moves the window once the torso is that close to its edge."""
    sim = Simulation(SimConfig(terrain="flat"))
    for _ in range(100):
        sim.step()
    sim.data.qpos[sim.layout.q_x] = sim.terrain.x1 - 2.0  # as a drag or a slide would leave it
    for _ in range(100):
        sim.step()
    assert sim.terrain.moves == 1 and sim.terrain.x1 - sim.state().x > 20.0
