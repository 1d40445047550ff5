"""A terrain tile as a compact binary glTF (GLB), for the scene: a third of what trimesh writes.

trimesh's GLB holds float32 positions and a uint32 index per triangle corner: 131 kB a 4 m tile,
the largest message a client receives as the robot hops on (issue 22's stream budget). Here
positions are int8 (KHR_mesh_quantization, which three.js's GLTFLoader reads: the node's scale
and translation undo the quantization; x and y count the grid's columns and rows, exact, z has
255 levels over the tile's heights, 1.2 mm over 0.3 m), and the grid is one triangle
strip of uint16 indices, a band of rows after another joined by degenerate triangles (about one
index per triangle instead of three); the colours stay RGBA uint8. No normals, as trimesh's: the
viewer computes them.
"""

from __future__ import annotations

import json
import struct

import numpy as np

BYTE, UNSIGNED_BYTE, UNSIGNED_SHORT = 5120, 5121, 5123  # glTF component types
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
STRIP = 5  # glTF's TRIANGLE_STRIP mode


def _pad(data: bytes, fill: bytes) -> bytes:
    return data + fill * (-len(data) % 4)


def grid_strip(nrow: int, ncol: int) -> np.ndarray:
    """One triangle strip over a row-major grid of nrow x ncol vertices, counter-clockwise from +z
    (rows along +y, columns along +x) as hopper.meshes' triangles are. Each band of two rows zigzags
    from its upper row to its lower; a band ends with its last index repeated and the next band's
    first, so that every band starts at an even position (the strip's winding) and the joins draw
    nothing (triangles of no area)."""
    bands = []
    for r in range(nrow - 1):
        band = np.empty(2 * ncol, np.int64)
        band[0::2], band[1::2] = (r + 1) * ncol + np.arange(ncol), r * ncol + np.arange(ncol)
        if bands:
            bands.append(np.array([bands[-1][-1], band[0]]))
        bands.append(band)
    return np.concatenate(bands)


def grid_positions(vertices: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions of a row-major grid as int8 (n, 4) (x, y, z, pad), and the node's scale and translation
    that give them back (m): x and y count columns and rows from the grid's middle (exact on a regular
    grid), z is 255 levels over the grid's heights (1.2 mm over a tile's 0.3 m)."""
    nrow, ncol = shape
    if max(nrow, ncol) > 255:
        raise ValueError(f"a grid of {nrow} x {ncol} has more rows or columns than int8 positions count (255)")
    grid = vertices.reshape(nrow, ncol, 3)
    step_x = (grid[0, -1, 0] - grid[0, 0, 0]) / max(ncol - 1, 1)
    step_y = (grid[-1, 0, 1] - grid[0, 0, 1]) / max(nrow - 1, 1)
    lo, hi = grid[..., 2].min(), grid[..., 2].max()
    step_z = max((hi - lo) / 254, 1e-9)
    mid_x, mid_y = (ncol - 1) // 2, (nrow - 1) // 2
    out = np.zeros((nrow, ncol, 4), np.int8)  # a vertex attribute's stride is a multiple of 4 bytes
    out[..., 0] = np.arange(ncol)[None, :] - mid_x
    out[..., 1] = np.arange(nrow)[:, None] - mid_y
    out[..., 2] = np.round((grid[..., 2] - (lo + hi) / 2) / step_z)
    scale = np.array([step_x or 1.0, step_y or 1.0, step_z])
    translation = np.array([grid[0, mid_x, 0], grid[mid_y, 0, 1], (lo + hi) / 2])
    return out.reshape(-1, 4), scale, translation


def tile_glb(vertices: np.ndarray, shape: tuple[int, int], colors: np.ndarray) -> bytes:
    """GLB of a regular grid mesh: `vertices` (nrow * ncol, 3) m, row-major in `shape` (nrow, ncol),
    columns along x and rows along y, at most 255 of each; `colors` (n, 4) uint8."""
    vertices = np.asarray(vertices, np.float64)
    positions, scale, translation = grid_positions(vertices, shape)
    faces = grid_strip(*shape)
    q = positions[:, :3]
    blobs = [positions.tobytes(), np.ascontiguousarray(colors, np.uint8).tobytes(), faces.astype(np.uint16).tobytes()]
    views, offset = [], 0
    for blob, target, stride in zip(
        blobs, (ARRAY_BUFFER, ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER), (4, 4, None), strict=True
    ):
        view = {"buffer": 0, "byteOffset": offset, "byteLength": len(blob), "target": target}
        views.append(view | ({"byteStride": stride} if stride else {}))
        offset += len(_pad(blob, b"\0"))
    gltf = {
        "asset": {"version": "2.0", "generator": "hopper-dashboard"},
        "extensionsUsed": ["KHR_mesh_quantization"],
        "extensionsRequired": ["KHR_mesh_quantization"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "translation": translation.tolist(), "scale": scale.tolist()}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "COLOR_0": 1}, "indices": 2, "mode": STRIP}]}],
        "buffers": [{"byteLength": offset}],
        "bufferViews": views,
        "accessors": [
            {
                "bufferView": 0, "componentType": BYTE, "count": len(q), "type": "VEC3",
                "min": q.min(axis=0).tolist(), "max": q.max(axis=0).tolist(),
            },
            {"bufferView": 1, "componentType": UNSIGNED_BYTE, "normalized": True, "count": len(q), "type": "VEC4"},
            {"bufferView": 2, "componentType": UNSIGNED_SHORT, "count": faces.size, "type": "SCALAR"},
        ],
    }  # fmt: skip
    text = _pad(json.dumps(gltf, separators=(",", ":")).encode(), b" ")
    binary = b"".join(_pad(blob, b"\0") for blob in blobs)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(binary), 0x004E4942) + binary
    return struct.pack("<III", 0x46546C67, 2, 12 + len(chunks)) + chunks
