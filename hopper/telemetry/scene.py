"""The recording's static 3D scene: the robot's bodies in their named frames, and the terrain."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import rerun as rr

from hopper.meshes import BodyMesh, terrain_mesh

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


def log_terrain(rec: rr.RecordingStream, sim: Simulation, cache: dict[str, Any] | None = None) -> None:
    """Static, so a terrain change mid-recording shows its new terrain for the whole replay (the
    3D view's time range would otherwise draw every terrain at once); the event log has the change.

    `cache` keeps the mesh of the current heights (each rolled-over part logs it again)."""
    if cache is not None and cache.get("heights") is sim.heights:  # a reference: no id reuse
        archetype = cache["mesh"]
    else:
        mesh = terrain_mesh(sim.heights, sim.config.craters)
        archetype = _mesh3d(mesh.vertices, mesh.faces, mesh.visual.vertex_colors)
        if cache is not None:
            cache.update(heights=sim.heights, mesh=archetype)
    rec.log("world/terrain", archetype, static=True)


def _mesh3d(vertices: Any, faces: Any, colors: Any) -> rr.Mesh3D:
    return rr.Mesh3D(
        vertex_positions=np.asarray(vertices, dtype=np.float32),
        triangle_indices=np.asarray(faces, dtype=np.uint32),
        vertex_colors=np.asarray(colors, dtype=np.uint8),
    )


def _torso_box(model: Any) -> rr.Boxes3D:
    geom = model.geom("torso")
    rgba = np.clip(np.asarray(geom.rgba) * 255, 0, 255).astype(np.uint8)
    return rr.Boxes3D(
        half_sizes=[geom.size],
        centers=[geom.pos],
        colors=[rgba],
        fill_mode=rr.components.FillMode.TransparentFillMajorWireframe,
    )
