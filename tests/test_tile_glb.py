"""The scene's terrain tiles as compact GLB: read back by the glTF rules, they are the physics' tile."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest
from hopper.app.dashboard.tile_glb import tile_glb

from hopper.config import SimConfig
from hopper.meshes import terrain_tile
from hopper.model import terrain_window

COMPONENTS = {5120: np.int8, 5121: np.uint8, 5123: np.uint16}
WIDTH = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}


def read_glb(glb: bytes) -> tuple[dict, dict[str, np.ndarray]]:
    """The glTF JSON and each accessor's values, as a reader applying the spec would (normalized
    ints scaled to [-1, 1] or [0, 1]; the node's scale and translation applied to POSITION)."""
    magic, version, length = struct.unpack_from("<III", glb)
    assert (magic, version, length) == (0x46546C67, 2, len(glb))
    n, kind = struct.unpack_from("<II", glb, 12)
    assert kind == 0x4E4F534A and n % 4 == 0
    gltf = json.loads(glb[20 : 20 + n])
    m, kind = struct.unpack_from("<II", glb, 20 + n)
    assert kind == 0x004E4942 and 28 + n + m == len(glb)
    binary = glb[28 + n :]
    primitive = gltf["meshes"][0]["primitives"][0]
    out = {}
    for name, index in [*primitive["attributes"].items(), ("indices", primitive["indices"])]:
        acc = gltf["accessors"][index]
        view = gltf["bufferViews"][acc["bufferView"]]
        dtype, width = COMPONENTS[acc["componentType"]], WIDTH[acc["type"]]
        stride = view.get("byteStride", width * np.dtype(dtype).itemsize)
        assert stride % 4 == 0 or name == "indices"
        raw = np.frombuffer(
            binary, dtype, count=acc["count"] * stride // np.dtype(dtype).itemsize, offset=view["byteOffset"]
        )
        values = raw.reshape(acc["count"], -1)[:, :width]
        if acc.get("normalized"):
            values = np.maximum(values / np.iinfo(dtype).max, -1.0)
        out[name] = values
    node = gltf["nodes"][0]
    out["POSITION"] = out["POSITION"] * np.array(node["scale"]) + np.array(node["translation"])
    return gltf, out


@pytest.fixture(scope="module")
def tile():
    config = SimConfig(terrain="crater", seed=3)
    return terrain_tile(terrain_window(config).field, 2)


def strip_triangles(strip: np.ndarray) -> set[tuple[int, int, int]]:
    """The triangles a GL triangle strip draws (odd ones with their first two corners swapped, as
    the glTF spec's mode 5), each rotated to start at its least index, the empty ones dropped."""
    out = set()
    for i in range(len(strip) - 2):
        a, b, c = (strip[i], strip[i + 1], strip[i + 2]) if i % 2 == 0 else (strip[i + 1], strip[i], strip[i + 2])
        if len({a, b, c}) == 3:
            k = int(np.argmin((a, b, c)))
            out.add(tuple(int(v) for v in np.roll((a, b, c), -k)))
    return out


def test_a_tile_reads_back_as_the_physics_tile_in_a_third_of_the_bytes(tile) -> None:  # noqa: ANN001
    colors = np.asarray(tile.visual.vertex_colors)
    nrow = SimConfig(terrain="crater").craters.shape[0]  # the grid's rows, along y
    glb = tile_glb(tile.vertices, (nrow, len(tile.vertices) // nrow), colors)
    gltf, got = read_glb(glb)
    assert gltf["extensionsRequired"] == ["KHR_mesh_quantization"]  # a reader without it must refuse, not misdraw
    # x and y count the grid's columns and rows: exact; z has 255 levels over the tile's heights.
    error = np.abs(got["POSITION"] - tile.vertices).max(axis=0)
    assert error[0] < 1e-9 and error[1] < 1e-9 and error[2] <= np.ptp(tile.vertices[:, 2]) / 254 / 2 + 1e-12, error
    assert gltf["meshes"][0]["primitives"][0]["mode"] == 5  # a triangle strip
    # The same triangles, each wound the same way (counter-clockwise from above: the lit side up).
    assert strip_triangles(got["indices"].ravel()) == {
        tuple(int(v) for v in np.roll(f, -int(np.argmin(f)))) for f in tile.faces
    }
    assert np.array_equal(np.round(got["COLOR_0"] * 255).astype(np.uint8), colors)
    # min/max as three.js reads them (raw ints) for the bounding box: 81 columns, 41 rows, z's 255 levels.
    assert gltf["accessors"][0]["min"] == [-40, -20, -127] and gltf["accessors"][0]["max"] == [40, 20, 127]
    assert len(glb) < 0.33 * len(tile.export(file_type="glb"))


def test_a_grid_beyond_int8_positions_is_refused() -> None:
    vertices = np.zeros((300 * 10, 3))
    with pytest.raises(ValueError, match="more rows or columns than int8 positions count"):
        tile_glb(vertices, (10, 300), np.zeros((3000, 4), np.uint8))
