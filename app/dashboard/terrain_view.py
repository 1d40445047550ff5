"""The terrain in the 3D scene: the simulation's window, drawn tile by tile, following it as it moves.

Each tile of the field (hopper.terrain.field, 4 m) is one mesh node, sent when it enters the
window and removed when it leaves, so a move sends only the ground that is new (41 kB a tile as
hopper.app.dashboard.tile_glb writes it: ~10 kB per metre travelled, whatever the window's
length); a new terrain replaces them all. The plain ground either side of the strip moves with
the window (a pose, not a mesh). A replayed log's ground (another world's) is drawn by LogGround
in place of these while its ghosts are watched.
"""

from __future__ import annotations

import math

import numpy as np
import viser
from hopper.app.dashboard.scene import WORLD
from hopper.app.dashboard.tile_glb import tile_glb
from hopper.terrain import CraterParams, Field

from hopper.meshes import terrain_tile
from hopper.sim import Simulation

GROUND_COLOR = (58, 58, 62)
GROUND_Z = -0.01  # m, just under the level start pad
TERRAIN_DIM = 0.72  # factor on the terrain's hillshaded colours: viser's default light is bright
GROUND_REACH_M = 40.0  # m of plain ground beyond each end of the window, more than the camera shows
GROUND_SIDE_M = 25.0  # m of plain ground either side of the strip


class TerrainView:
    """The meshes of the window's tiles; `sync(sim)` on the loop thread brings them up to date."""

    def __init__(self, scene: viser.SceneApi, sim: Simulation) -> None:
        self._scene = scene
        self._field: Field | None = None
        self._first: int | None = None
        self.tiles: dict[int, viser.GlbHandle] = {}  # tile index -> its node
        self.sent = 0  # tile meshes sent, for tests and the benchmark
        self.sent_bytes = 0  # their GLBs' bytes, which every client receives (benchmarks/bench_dashboard.py)
        self.hidden = False  # while another world's ground is shown in its place (LogGround)
        self.ground = _add_ground(scene, sim.config.craters)
        self.sync(sim)

    def hide(self, hidden: bool) -> None:
        """Hide (or show again) the live ground; the window keeps following the simulation meanwhile."""
        self.hidden = hidden
        for handle in (*self.tiles.values(), self.ground):
            handle.visible = not hidden

    def sync(self, sim: Simulation) -> None:
        """Send the tiles that entered the window, remove those that left (cheap when it did not move)."""
        window = sim.terrain
        if window.field is self._field and window.first == self._first:
            return
        if window.field is not self._field:  # a new terrain: every tile is another one
            self._remove(list(self.tiles))
            self._field = window.field
        self._first = window.first
        wanted = set(window.tiles())
        self._remove([k for k in self.tiles if k not in wanted])
        for k in sorted(wanted - self.tiles.keys()):
            self.tiles[k] = self._send(window.field, k)
        self.ground.position = (window.x0, 0.0, GROUND_Z)

    def _send(self, field: Field, k: int) -> viser.GlbHandle:
        glb = terrain_glb(field, k)
        self.sent += 1
        self.sent_bytes += len(glb)
        return self._scene.add_glb(f"{WORLD}/terrain/{k}", glb, cast_shadow=False, visible=not self.hidden)

    def _remove(self, tiles: list[int]) -> None:
        for k in tiles:
            self.tiles.pop(k).remove()


class LogGround:
    """A replayed log's ground (its own world's, whichever seed and terrain): the tiles under its
    track, drawn while its ghosts are watched (TerrainView hides the live ground meanwhile)."""

    def __init__(self, scene: viser.SceneApi) -> None:
        self._scene = scene
        self.tiles: dict[int, viser.GlbHandle] = {}

    def show(self, glbs: dict[int, bytes]) -> None:
        """Draw these tiles (index -> GLB, ground_glbs), in place of any drawn before."""
        self.hide()
        add = self._scene.add_glb
        self.tiles = {k: add(f"{WORLD}/log_terrain/{k}", glb, cast_shadow=False) for k, glb in glbs.items()}

    def hide(self) -> None:
        for handle in self.tiles.values():
            handle.remove()
        self.tiles = {}


def terrain_glb(field: Field, k: int) -> bytes:
    """Tile k of `field` as the scene draws it (hopper.meshes.terrain_tile, dimmed, as a GLB)."""
    mesh = terrain_tile(field, k)
    colors = np.asarray(mesh.visual.vertex_colors).copy()
    colors[:, :3] = (colors[:, :3] * TERRAIN_DIM).astype(np.uint8)
    nrow = field.params.shape[0]  # hopper.meshes' grid: row-major, rows along y
    return tile_glb(mesh.vertices, (nrow, len(mesh.vertices) // nrow), colors)


def ground_glbs(field: Field, x_lo: float, x_hi: float) -> dict[int, bytes]:
    """The tiles of `field` under world x from `x_lo` to `x_hi` (m), a tile more each side: index -> GLB."""
    tile = field.params.tile
    return {k: terrain_glb(field, k) for k in range(math.floor(x_lo / tile) - 1, math.floor(x_hi / tile) + 2)}


def _add_ground(scene: viser.SceneApi, craters: CraterParams) -> viser.MeshHandle:
    """Plain regolith either side of the strip and beyond the window's ends, in the window's frame
    (x from its -x edge), so the strip does not float in a void; moved with the window."""
    x0, x1, end = -GROUND_REACH_M, craters.length + GROUND_REACH_M, craters.length
    half, far = craters.width / 2, GROUND_SIDE_M
    quads = [(x0, x1, -far, -half), (x0, x1, half, far), (x0, 0.0, -half, half), (end, x1, -half, half)]
    corners = [((xa, ya), (xb, ya), (xb, yb), (xa, yb)) for xa, xb, ya, yb in quads]
    vertices = np.array([[x, y, 0.0] for quad in corners for x, y in quad], np.float32)
    faces = np.array([f for q in range(0, 16, 4) for f in ((q, q + 1, q + 2), (q, q + 2, q + 3))], np.uint32)
    return scene.add_mesh_simple(f"{WORLD}/ground", vertices, faces, color=GROUND_COLOR, cast_shadow=False)
