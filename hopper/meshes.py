"""Triangle meshes of the robot's bodies and the terrain, for any 3D front end (viser, rerun)."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import trimesh

from hopper.terrain import CraterParams
from hopper.terrain.window import Field

VISUAL_BODIES = ("torso", "wheel", "thigh_L", "shank_L", "thigh_R", "shank_R")


@dataclasses.dataclass(frozen=True)
class BodyMesh:
    """One body's geoms merged into a mesh in the body frame, with per-vertex RGBA (uint8)."""

    name: str
    body_id: int
    mesh: trimesh.Trimesh

    @property
    def vertices(self) -> np.ndarray:  # (n, 3) float32
        return np.asarray(self.mesh.vertices, dtype=np.float32)

    @property
    def faces(self) -> np.ndarray:  # (m, 3) uint32
        return np.asarray(self.mesh.faces, dtype=np.uint32)

    @property
    def colors(self) -> np.ndarray:  # (n, 4) uint8
        return np.asarray(self.mesh.visual.vertex_colors, dtype=np.uint8)


def _geom_mesh(model: mujoco.MjModel, geom: int) -> trimesh.Trimesh | None:
    kind, size = model.geom_type[geom], model.geom_size[geom]
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        mesh = trimesh.creation.box(extents=2 * size)
    elif kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=size[0])
    elif kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        mesh = trimesh.creation.capsule(height=2 * size[1], radius=size[0], count=[12, 8])
    elif kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        mesh = trimesh.creation.cylinder(radius=size[0], height=2 * size[1], sections=48)
    else:
        return None
    transform = np.eye(4)
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, model.geom_quat[geom])
    transform[:3, :3] = rotation.reshape(3, 3)
    transform[:3, 3] = model.geom_pos[geom]
    mesh.apply_transform(transform)
    rgba = np.clip(model.geom_rgba[geom] * 255, 0, 255).astype(np.uint8)
    mesh.visual.vertex_colors = np.tile(rgba, (len(mesh.vertices), 1))
    return mesh


def body_meshes(model: mujoco.MjModel, bodies: tuple[str, ...] = VISUAL_BODIES) -> list[BodyMesh]:
    """Each named body's geoms as one mesh in its body frame (geom colours from the MJCF)."""
    out = []
    for name in bodies:
        body = model.body(name).id
        parts = [m for g in range(model.ngeom) if model.geom_bodyid[g] == body and (m := _geom_mesh(model, g))]
        out.append(BodyMesh(name, body, trimesh.util.concatenate(parts)))
    return out


def body_poses(model: mujoco.MjModel, data: mujoco.MjData, meshes: list[BodyMesh]) -> tuple[np.ndarray, np.ndarray]:
    """World positions (n, 3) and wxyz quaternions (n, 4) of the meshes' bodies."""
    ids = [m.body_id for m in meshes]
    return data.xpos[ids].copy(), data.xquat[ids].copy()


def terrain_colors(heights: np.ndarray, cell: float) -> np.ndarray:
    """Per-vertex RGBA (uint8), shape (nrow * (ncol - 2), 4), of every column but the first and
    the last (they only give the slopes at the others): regolith grey shaded by a low sun.

    Hillshading (light from -x, 20 deg above the horizon, as in lunar morning images) makes crater
    bowls and rims readable from any camera; depth below the level start tints the floors darker.
    Each vertex's colour depends on its neighbours alone, so tiles meet without a seam.
    """
    gy, gx = (g[:, 1:-1] for g in np.gradient(heights, cell))
    heights = heights[:, 1:-1]
    normal = np.stack([-gx, -gy, np.ones_like(gx)], axis=-1)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    sun = np.array([-np.cos(np.radians(20)), 0.25, np.sin(np.radians(20))])
    sun /= np.linalg.norm(sun)
    shade = np.clip(normal @ sun, 0.0, 1.0)
    depth = np.clip(heights / 0.15, -1.0, 1.0)
    grey = 0.30 + 0.55 * shade + 0.10 * depth
    rgb = np.stack([grey * 0.98, grey * 0.96, grey * 0.92], axis=-1)
    alpha = np.ones_like(grey)[..., None]
    return (np.clip(np.concatenate([rgb, alpha], axis=-1), 0, 1) * 255).astype(np.uint8).reshape(-1, 4)


def terrain_tile(field: Field, k: int) -> trimesh.Trimesh:
    """Tile k of the field (hopper.terrain.field) as a triangle mesh in world coordinates, from the
    physics' own heights: its columns and the next tile's first, so that tiles join.

    Vertex (row i, column j) sits at x = j cell, y = -width/2 + i cell, z = the field's height: the
    grid of MuJoCo's hfield (row 0 = -y), wherever the window is.
    """
    params = field.params
    n = round(params.tile / params.cell)
    padded = field.columns(k * n - 1, n + 3)  # one column more each side, for the slopes
    return _grid_mesh(padded[:, 1:-1], k * n, params, terrain_colors(padded, params.cell))


def _grid_mesh(heights: np.ndarray, first: int, params: CraterParams, colors: np.ndarray) -> trimesh.Trimesh:
    nrow, ncol = heights.shape
    xs = (first + np.arange(ncol)) * params.cell
    ys = -params.width / 2 + np.arange(nrow) * params.cell
    gx, gy = np.meshgrid(xs, ys)
    vertices = np.stack([gx, gy, heights], axis=-1).reshape(-1, 3)
    idx = np.arange(nrow * ncol).reshape(nrow, ncol)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    mesh.visual.vertex_colors = colors
    return mesh
