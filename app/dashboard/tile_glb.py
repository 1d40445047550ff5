"""A terrain tile as a compact binary glTF (GLB), for the scene: 41 % of what trimesh writes.

trimesh's GLB holds float32 positions and a uint32 index per triangle corner: 131 kB a 4 m tile,
the largest message a client receives while the robot hops on (issue 22's stream budget). Here
positions are int16 (KHR_mesh_quantization, which three.js's GLTFLoader reads: the node's scale
and translation undo the quantization, 61 um steps over a 4 m tile), and the grid is one triangle
strip of uint16 indices, a band of rows after another joined by degenerate triangles (about one
index per triangle instead of three); the colours stay RGBA uint8. No normals, as trimesh's: the
viewer computes them.
"""

from __future__ import annotations

import json
import struct

import numpy as np

QUANT = 32767  # int16 normalized: value / 32767 in [-1, 1]
SHORT, UNSIGNED_BYTE, UNSIGNED_SHORT = 5122, 5121, 5123  # glTF component types
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


def tile_glb(vertices: np.ndarray, shape: tuple[int, int], colors: np.ndarray) -> bytes:
    """GLB of a grid mesh: `vertices` (nrow * ncol, 3) m, row-major in `shape` (nrow, ncol), at most
    65,536 of them; `colors` (n, 4) uint8."""
    vertices = np.asarray(vertices, np.float64)
    faces = grid_strip(*shape)
    if len(vertices) > 65536:
        raise ValueError(f"a tile of {len(vertices)} vertices needs 32-bit indices")
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    center, half = (lo + hi) / 2, np.maximum((hi - lo) / 2, 1e-9)
    q = np.round((vertices - center) / half * QUANT).astype(np.int16)
    positions = np.zeros((len(q), 4), np.int16)  # a vertex attribute's stride is a multiple of 4 bytes
    positions[:, :3] = q
    blobs = [positions.tobytes(), np.ascontiguousarray(colors, np.uint8).tobytes(), faces.astype(np.uint16).tobytes()]
    views, offset = [], 0
    for blob, target, stride in zip(
        blobs, (ARRAY_BUFFER, ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER), (8, 4, None), strict=True
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
        "nodes": [{"mesh": 0, "translation": center.tolist(), "scale": half.tolist()}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "COLOR_0": 1}, "indices": 2, "mode": STRIP}]}],
        "buffers": [{"byteLength": offset}],
        "bufferViews": views,
        "accessors": [
            {
                "bufferView": 0, "componentType": SHORT, "normalized": True, "count": len(q), "type": "VEC3",
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
