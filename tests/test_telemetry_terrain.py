"""A recording on endless terrain: the terrain's tiles follow the window, in world x, as the robot's path does."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
from rerun.chunk import RrdReader
from rrd import verify

from hopper.config import SimConfig
from hopper.meshes import terrain_tile
from hopper.sim import Simulation
from hopper.telemetry import Telemetry


def test_the_recording_takes_in_the_tiles_of_each_window_and_the_path_in_world_x(tmp_path: Path) -> None:
    sim = Simulation(SimConfig(seed=0))
    path = tmp_path / "run.rrd"
    start_tiles = set(sim.terrain.tiles())
    with Telemetry(sim, path=path):
        while sim.terrain.moves == 0 or len(sim.hops) < 26:  # one move, and a few hops on the new ground
            sim.step()
            assert not sim.fallen
    verify(path)
    tiles: dict[int, np.ndarray] = {}
    trail_x = []
    for chunk in RrdReader(path).stream():
        entity = chunk.entity_path
        if entity.startswith("/world/terrain/"):
            assert chunk.is_static
            row = chunk.to_record_batch().to_pylist()[-1]
            tiles[int(entity.rsplit("/", 1)[1])] = np.array(row["Mesh3D:vertex_positions"])
        elif entity == "/world/trail":
            strips = pa.Table.from_batches([chunk.to_record_batch()]).to_pylist()
            trail_x += [p[0] for row in strips for strip in row["LineStrips3D:strips"] for p in strip]
    # Every tile of the start window and of the moved one, each once, where the field has it.
    assert set(tiles) == start_tiles | set(sim.terrain.tiles())
    k = max(tiles)
    assert np.array_equal(tiles[k], np.asarray(terrain_tile(sim.terrain.field, k).vertices, np.float32))
    assert tiles[k][:, 0].min() == k * sim.config.craters.tile
    # The torso's path runs on in world x past the start window's old end, without a jump.
    assert max(trail_x) > sim.terrain.start * sim.config.craters.cell + 20.0
    assert np.abs(np.diff(trail_x)).max() < 0.1
