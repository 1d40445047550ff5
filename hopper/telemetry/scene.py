"""The recording's static 3D scene: the robot's bodies in their named frames, and the terrain's tiles."""

from __future__ import annotations

import collections
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import rerun as rr

from hopper.meshes import BodyMesh, terrain_tile
from hopper.terrain import Field

TILE_CACHE = 16  # tile meshes kept for the next part: a window's 9 or 10, and room for its move

if TYPE_CHECKING:
    from hopper.sim import Simulation


def log_robot(rec: rr.RecordingStream, sim: Simulation, meshes: Sequence[BodyMesh]) -> None:
    """Z-up world; each body mesh static in its own frame, which `world/tf` rows then pose."""
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    for mesh in meshes:
        # rerun draws mesh vertex alpha opaque, and the torso box would hide the wheel inside it:
        # draw the torso as a transparent box with its edges instead.
        shape = _torso_box(sim.model) if mesh.name == "torso" else _mesh3d(mesh.vertices, mesh.faces, mesh.colors)
        rec.log(f"world/robot/{mesh.name}", shape, rr.CoordinateFrame(mesh.name), static=True)


class TerrainLog:
    """The terrain in a recording, one static mesh per tile of the field (`world/terrain/<k>`, k
    the tile's index, hopper.terrain.field), logged as the tile enters the simulation's window.

    Static, so the replay shows the ground wherever the robot went, at any time cursor: the
    same world x always has the same ground. A new terrain blanks the tiles of the old one (it
    shows for the whole replay, as a change always did; the event log has the change). Call
    `sync` from the thread that steps the simulation; it returns the meshes it logged.
    """

    def __init__(self) -> None:
        self._field: Field | None = None
        self._first: int | None = None
        self._logged: set[int] = set()  # tiles of the current field in this part
        self._meshes: collections.OrderedDict[int, rr.Mesh3D] = collections.OrderedDict()

    def new_part(self) -> None:
        """The next sync logs the window's tiles again: a part opens and verifies alone."""
        self._logged, self._first = set(), None

    def sync(self, rec: rr.RecordingStream, sim: Simulation) -> int:
        window = sim.terrain
        if window.field is self._field and window.first == self._first:
            return 0
        logged = 0
        if window.field is not self._field:
            for k in self._logged - set(window.tiles()):
                rec.log(_tile_path(k), EMPTY_MESH, static=True)
                logged += 1
            self._logged, self._field = set(), window.field
            self._meshes.clear()
        self._first = window.first
        for k in window.tiles():
            if k not in self._logged:
                rec.log(_tile_path(k), self._mesh(window.field, k), static=True)
                self._logged.add(k)
                logged += 1
        return logged

    def _mesh(self, field: Field, k: int) -> rr.Mesh3D:
        archetype = self._meshes.get(k)
        if archetype is None:
            mesh = terrain_tile(field, k)
            archetype = self._meshes[k] = _mesh3d(mesh.vertices, mesh.faces, mesh.visual.vertex_colors)
            while len(self._meshes) > TILE_CACHE:
                self._meshes.popitem(last=False)
        return archetype


def _tile_path(k: int) -> str:
    return f"world/terrain/{k}"


def _mesh3d(vertices: Any, faces: Any, colors: Any) -> rr.Mesh3D:
    return rr.Mesh3D(
        vertex_positions=np.asarray(vertices, dtype=np.float32),
        triangle_indices=np.asarray(faces, dtype=np.uint32),
        vertex_colors=np.asarray(colors, dtype=np.uint8),
    )


EMPTY_MESH = _mesh3d(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 4)))  # a tile of an old terrain


def _torso_box(model: Any) -> rr.Boxes3D:
    geom = model.geom("torso")
    rgba = np.clip(np.asarray(geom.rgba) * 255, 0, 255).astype(np.uint8)
    return rr.Boxes3D(
        half_sizes=[geom.size],
        centers=[geom.pos],
        colors=[rgba],
        fill_mode=rr.components.FillMode.TransparentFillMajorWireframe,
    )
