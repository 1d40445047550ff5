"""The 3D scene: robot meshes sent once, then only poses, a trail and a following camera (the terrain: terrain_view)."""

from __future__ import annotations

import bisect
import math
import warnings

import mujoco
import numpy as np
import trimesh
import viser

from hopper.control import Phase
from hopper.history import RING_SPAN_S
from hopper.meshes import BodyMesh, body_meshes, body_poses
from hopper.robot import PACKAGED, Robot

# A client can leave between listing the clients and moving its camera; viser then warns that the
# message will never be delivered, which is exactly right and not worth a warning per frame.
warnings.filterwarnings("ignore", message=r"Queued a SetCamera\w+ on a closed connection")

WORLD = "/world"  # parent of every scene node; following the robot moves this frame only
ROBOT = f"{WORLD}/robot"  # the robot's scene tree: a frame at the torso's position
TRAIL_SAMPLE_S = 0.05  # s of simulation between trail points
TRAIL_CHUNK = 10  # segments per line-segment node; only the newest chunk is re-sent
TRAIL_CHUNKS = 30  # nodes shown: 15 s of trail
# Chunks kept: those shown and the replay history's reach before them (RING_SPAN_S at 1x), so that a
# moment put back up to 40 s ago shows the 15 s of path that led to it.
TRAIL_KEPT = TRAIL_CHUNKS + math.ceil(RING_SPAN_S / (TRAIL_SAMPLE_S * TRAIL_CHUNK))
TRAIL_PUBLISH_S = 0.2  # s of wall time between re-sends of the newest chunk; 5 a second, as the charts refresh
TRAIL_COLOR = (255, 176, 59)
# m: a path whose last point before a rewound moment is farther from the robot does not lead to it.
# The torso moves less between two points: they are the charts' samples, 0.05 s of simulation apart at
# 1x, 0.4 s at 64x (a hop's 0.5-1 m/s). At the worst (Max on a fast machine) a path is forgotten.
TRAIL_JOIN_M = 1.0
SATURATION_COLORS = ((70, 200, 120), (245, 190, 40), (235, 60, 50))  # free, half, saturated
RING_STEP = 0.1  # of saturation: the ring's colour steps (10 from free to saturated; finer re-sent it 9 times a second)
LABEL_POSITION = (0.0, 0.0, 0.42)  # m above the torso's origin: the phase label clears the wheel
# Poses go on binary grids finer than the eye can tell apart (2^-12 of a quaternion's unit: 0.03 deg;
# 2^-12 m: 0.24 mm, under a pixel with half a metre in view): the float64s msgpack carries then end in
# zero bytes, which the frame's zstd squeezes out, and a body holding still within a step is not re-sent
# (the torso's orientation in stance: 24 updates a second instead of 30).
QUAT_GRID = 2.0**-12
POSITION_GRID = 2.0**-12  # m
CAMERA_OFFSET = np.array([0.0, -4.4, 1.9])  # m from the look-at point: side view from 23 deg above
LOOK_OFFSET = np.array([0.3, 0.0, -0.3])  # m from the followed torso: a little ahead (it hops toward +x), down
CAMERA_FOV = math.radians(45.0)  # vertical; about 4 m of height in view at the default distance
ENVIRONMENT_INTENSITY = 0.25
AMBIENT, SIMPLE_AMBIENT = "/ambient", 2.0  # the simple lighting's stand-in for the environment
FOLLOW_TAU_X, FOLLOW_TAU_Z = 0.25, 1.5  # s, camera smoothing; slow in z so hops do not bob it


def configure_lighting(scene: viser.SceneApi, lighting: str = "full") -> None:
    """Light the scene: `full` a dim environment (viser's default studio light flattens the hillshaded
    craters) and shadowed lights (they show the hop height); `no-shadows` the same unshadowed;
    `simple` the lights and an ambient light in place of the environment, for software-rendered
    browsers (without either the robot is near black)."""
    simple = lighting == "simple"
    if simple:
        scene.configure_environment_map(None)
    else:
        scene.configure_environment_map("warehouse", environment_intensity=ENVIRONMENT_INTENSITY)
    scene.configure_default_lights(enabled=True, cast_shadow=lighting == "full")
    scene.add_light_ambient(AMBIENT, intensity=SIMPLE_AMBIENT, visible=simple)  # the same node, replaced


def on_grid(values: np.ndarray, grid: float) -> np.ndarray:
    """`values` rounded to multiples of `grid` (a power of two: exact in float64, short on the wire)."""
    return np.round(np.asarray(values, dtype=np.float64) / grid) * grid


def saturation(wheel_torque: float, wheel_speed: float, robot: Robot = PACKAGED) -> float:
    """How close `robot`'s wheel is to its limits, 0..1: the larger of torque/limit and speed/no-load speed."""
    torque, speed = abs(wheel_torque) / robot.wheel_torque_limit, abs(wheel_speed) / robot.wheel_no_load_speed
    return min(max(torque, speed), 1.0)


def saturation_color(level: float) -> tuple[int, int, int]:
    """Green when free, amber at half, red at the limit (linear between)."""
    low, mid, high = (np.array(c, dtype=float) for c in SATURATION_COLORS)
    rgb = low + (mid - low) * (level / 0.5) if level < 0.5 else mid + (high - mid) * min((level - 0.5) / 0.45, 1.0)
    return tuple(int(round(v)) for v in rgb)  # type: ignore[return-value]


def _add_body(scene: viser.SceneApi, name: str, body: BodyMesh) -> viser.SceneNodeHandle:
    """Single-colour bodies go as plain meshes (with their alpha); multi-colour ones as GLB vertex colours."""
    colors = body.colors
    if (colors == colors[0]).all():
        r, g, b, a = (int(c) for c in colors[0])
        return scene.add_mesh_simple(
            name,
            body.vertices,
            body.faces,
            color=(r, g, b),
            opacity=None if a == 255 else a / 255,
            flat_shading=len(body.vertices) <= 24,  # boxes: flat faces, not smeared normals
            side="double" if a < 255 else "front",
            cast_shadow=a == 255,
        )
    return scene.add_mesh_trimesh(name, matte(body.mesh))


def matte(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """`mesh` with its vertex colours under a matte, non-metal material (the plain meshes' look).

    A glTF primitive without a material gets the loader's default, metalness 1: lit by the
    environment map alone, so under the simple lighting (no map) the wheel's face rendered black.
    glTF vertex colours are linear and the model's rgba, as the plain meshes' colours, sRGB: so
    they are converted, or the shanks would show lighter than the thighs of the same rgba.
    """
    colors = mesh.visual.vertex_colors.copy()
    srgb = colors[:, :3] / 255.0
    linear = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
    colors[:, :3] = np.round(linear * 255.0).astype(np.uint8)
    out = mesh.copy()
    out.visual = trimesh.visual.TextureVisuals(
        material=trimesh.visual.material.PBRMaterial(
            baseColorFactor=[255, 255, 255, 255], metallicFactor=0.0, roughnessFactor=1.0
        )
    )
    out.visual.vertex_attributes["color"] = colors
    return out


def kinematic_parents(model: mujoco.MjModel, meshes: list[BodyMesh]) -> list[int]:
    """For each mesh, the index of the mesh of its nearest ancestor body among `meshes`, or -1 (the root).

    Parents come before their children in the list (checked), so poses can be composed in order.
    """
    index = {m.body_id: i for i, m in enumerate(meshes)}
    parents = []
    for i, mesh in enumerate(meshes):
        body = int(model.body_parentid[mesh.body_id])
        while body != 0 and body not in index:
            body = int(model.body_parentid[body])
        parent = index.get(body, -1)
        if parent >= i:
            raise ValueError(f"body {mesh.name} is listed before its parent {meshes[parent].name}")
        parents.append(parent)
    if parents.count(-1) != 1:
        raise ValueError("the robot's meshes must hang from exactly one root body")
    return parents


def local_poses(positions: np.ndarray, quats: np.ndarray, parents: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """World poses (n, 3) and wxyz (n, 4) to poses in each parent's frame; the root's becomes its rotation alone."""
    local_p, local_q = np.zeros_like(positions), quats.copy()
    inverse = np.zeros(4)
    for i, parent in enumerate(parents):
        if parent < 0:
            continue
        mujoco.mju_negQuat(inverse, quats[parent])
        mujoco.mju_rotVecQuat(local_p[i], positions[i] - positions[parent], inverse)
        mujoco.mju_mulQuat(local_q[i], inverse, quats[i])
    return local_p, local_q


class RobotView:
    """The robot's bodies as a scene tree that mirrors the model's, a wheel-saturation ring and a phase label.

    A frame at the torso's position carries the label; under it the torso takes its rotation and every
    other body its pose relative to its parent body. A hinge only turns its body, so a frame moves the
    frame (one position) and sends one rotation per body: viser skips the constant offsets.

    The label is one label per phase, the current one visible: viser's client (1.1.1,
    label/LabelRenderer.tsx) draws a label's new text one render frame after the poses it came with (the
    text reaches its renderer through a React effect), a visibility in the frame it arrives. With a new
    text, a page drawing about a frame a second (headless Chromium, software WebGL) showed "flight" over
    a robot in stance under a STANCE badge; a switch of labels is drawn with the poses and the badge.
    """

    def __init__(self, scene: viser.SceneApi, model: mujoco.MjModel) -> None:
        self._meshes = body_meshes(model)
        self._parents = kinematic_parents(model, self._meshes)
        self.root = scene.add_frame(ROBOT, show_axes=False)
        paths: list[str] = []
        for mesh, parent in zip(self._meshes, self._parents, strict=True):
            paths.append(f"{paths[parent] if parent >= 0 else ROBOT}/{mesh.name}")
        self.paths = paths
        self._handles = [_add_body(scene, path, body) for path, body in zip(paths, self._meshes, strict=True)]
        # The ring sits around the wheel rim on the camera side of the torso and takes the torso's
        # pose, so it shows the limit without spinning; only its colour is ever re-sent.
        ring = trimesh.creation.annulus(r_min=0.158, r_max=0.178, height=0.02, sections=48)
        ring.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [1, 0, 0]))
        self._level = -1.0
        self.ring = scene.add_mesh_simple(
            f"{paths[self._parents.index(-1)]}/saturation",
            np.asarray(ring.vertices, np.float32),
            np.asarray(ring.faces, np.uint32),
            color=SATURATION_COLORS[0],
            position=(0.0, -0.07, 0.0),
            cast_shadow=False,
        )
        # Above the torso, unrotated: children of the frame that only follows the torso's position.
        self.labels = {
            phase.label: scene.add_label(
                f"{ROBOT}/label_{phase.label}",
                phase.label,
                position=LABEL_POSITION,
                anchor="bottom-center",
                font_screen_scale=0.9,
                visible=phase is Phase.STANCE,
            )
            for phase in Phase
        }
        self.phase = Phase.STANCE.label  # the phase labelled (shown if show_label)
        self.show_label = True
        self.torso_position = np.zeros(3)  # m, in the world frame, as last sent

    @property
    def label(self) -> viser.LabelHandle:
        """The label of the phase labelled now."""
        return self.labels[self.phase]

    def grabbable(self) -> list[viser.SceneNodeHandle]:
        """The nodes a mouse drag pulls the torso by: the torso, the bodies fixed on it (the wheel), its ring."""
        root = self._parents.index(-1)
        bodies = [h for h, mesh, parent in zip(self._handles, self._meshes, self._parents, strict=True)
                  if parent == -1 or (parent == root and mesh.name == "wheel")]  # fmt: skip
        return [*bodies, self.ring]

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, level: float, phase: str) -> None:
        """Send this frame's poses (call inside server.atomic(), from the simulation loop)."""
        positions, quats = body_poses(model, data, self._meshes)
        root = self._parents.index(-1)
        local_p, local_q = local_poses(positions, quats, self._parents)
        self.root.position = on_grid(positions[root], POSITION_GRID)
        local_p, local_q = on_grid(local_p, POSITION_GRID), on_grid(local_q, QUAT_GRID)
        for handle, p, q in zip(self._handles, local_p, local_q, strict=True):
            handle.position = p  # constant for hinged bodies: viser sends it only when it changes
            handle.wxyz = q
        # Re-send the colour only when it visibly changes: in steps of RING_STEP, and only once the level has
        # moved a whole step from the one shown (a level at a rounding edge would flip it every frame).
        if abs(level - self._level) >= RING_STEP:
            self._level = round(level / RING_STEP) * RING_STEP
            self.ring.color = saturation_color(self._level)
        self.torso_position = positions[root]  # in the world frame, as sent
        self.phase = phase
        for label, handle in self.labels.items():
            handle.visible = self.show_label and label == phase  # viser sends only the two that change


class Trail:
    """The torso's recent path as TRAIL_CHUNKS line-segment nodes of TRAIL_CHUNK segments each.

    Each node is created once and then only its points are re-sent (about 0.26 kB, where re-creating
    it cost about 0.6 with the pose and visibility messages viser sends with a new node): a chunk
    always has TRAIL_CHUNK segments, those not yet reached collapsed onto its newest point, so its
    colours never change shape. A chunk is sent again only when its points change: the newest as it
    grows, a recycled one, the one a rewind cuts.

    The path is kept as far back as the replay history reaches (TRAIL_KEPT chunks), and its newest
    TRAIL_CHUNKS are shown: a moment put back 40 s shows the 15 s of path that led to it.
    While the robot is rewound (a restore), the path ends at the moment shown; the rest is kept aside
    (a later moment shown again brings it back) until the path grows again from the moment: the run
    then takes another course, and the path it left is dropped, as the history after it is.
    """

    def __init__(self, scene: viser.SceneApi) -> None:
        self._scene = scene
        self._handles: dict[int, viser.LineSegmentsHandle] = {}
        # node slot -> (chunk, its samples) shown: a rewound path regrown to the same length differs
        self._sent: dict[int, tuple[int, tuple[tuple[float, float, float], ...]]] = {}
        # (t s, x m, z m), oldest first; chunk k holds samples k * TRAIL_CHUNK to (k + 1) * TRAIL_CHUNK.
        self._path: list[tuple[float, float, float]] = []
        self._first = 0  # the chunk _path[0] begins
        self._ahead: list[tuple[float, float, float]] = []  # after a rewound moment
        self._next_time = 0.0
        self._dirty = False
        self._shown = True
        self._next_publish = -math.inf
        self.visible = True  # asked from any thread; applied by publish() on the loop thread

    def sample(self, time: float, x: float, z: float) -> None:
        """Offer the torso position at simulation `time`; kept every TRAIL_SAMPLE_S."""
        if time < self._next_time:
            return
        self._next_time = time + TRAIL_SAMPLE_S
        self._ahead.clear()  # the run goes on from the moment rewound to: the path it left is no more
        self._path.append((time, x, z))
        if len(self._path) > TRAIL_KEPT * TRAIL_CHUNK + 1:  # a chunk more than kept: the oldest goes
            del self._path[:TRAIL_CHUNK]
            self._first += 1
        self._dirty = True

    def rewind(self, time: float, x: float, z: float) -> None:
        """The robot was put back to simulation `time` (s), its torso at (x, z) (m): show the path up to
        there. A path that does not lead there (another run's moment, a keyframe from elsewhere) is
        not the robot's: it is forgotten."""
        path = self._path + self._ahead
        n = bisect.bisect_right(path, time, key=lambda p: p[0])  # the points up to `time`
        if n == 0:  # before the path's oldest point (the history reaches further back than the trail):
            self._path, self._ahead = [], path  # nothing to show there, the path kept for a later moment
            self._next_time, self._dirty = time, True
            return
        if math.hypot(path[n - 1][1] - x, path[n - 1][2] - z) > TRAIL_JOIN_M:
            self.clear()
            self._next_time = time
            return
        self._path, self._ahead = path[:n], path[n:]
        self._next_time = path[n - 1][0] + TRAIL_SAMPLE_S
        self._dirty = True

    def _shown_from(self) -> int:
        """The index in the path of the first point shown: the newest TRAIL_CHUNKS chunks are."""
        chunks = -(-(len(self._path) - 1) // TRAIL_CHUNK)  # the last one partly grown
        return max(chunks - TRAIL_CHUNKS, 0) * TRAIL_CHUNK

    @property
    def points(self) -> list[tuple[float, float]]:
        """The path shown, (x, z) m, oldest first (for tests)."""
        return [(x, z) for _, x, z in self._path[self._shown_from() :]]

    def publish(self, now: float | None = None) -> None:
        """Send the chunks that changed (at most every TRAIL_PUBLISH_S of wall time `now`, if given)."""
        if self.visible != self._shown:
            self._shown = self.visible
            for slot in self._sent:
                self._handles[slot].visible = self._shown
        if not self._dirty or (now is not None and now < self._next_publish):
            return
        self._dirty = False
        if now is not None:
            self._next_publish = now + TRAIL_PUBLISH_S
        # Fast-forward samples several chunks between two publishes: each is sent once, as it is now.
        chunks = {}
        for i in range(self._shown_from(), max(len(self._path) - 1, 0), TRAIL_CHUNK):
            chunk = self._first + i // TRAIL_CHUNK
            chunks[chunk % TRAIL_CHUNKS] = (chunk, tuple(self._path[i : i + TRAIL_CHUNK + 1]))
        for slot in [s for s in self._sent if s not in chunks]:  # beyond a rewound moment
            self._handles[slot].visible = False
            del self._sent[slot]
        for slot, shown in chunks.items():
            if self._sent.get(slot) != shown:
                self._send(slot, [(x, 0.0, z) for _, x, z in shown[1]])
                self._sent[slot] = shown

    def _send(self, slot: int, points: list[tuple[float, float, float]]) -> None:
        """Show `points` (2 to TRAIL_CHUNK + 1) in node `slot`."""
        path = np.asarray(points + points[-1:] * (TRAIL_CHUNK + 1 - len(points)), dtype=np.float32)
        segments = np.stack([path[:-1], path[1:]], axis=1)
        handle = self._handles.get(slot)
        if handle is None:
            self._handles[slot] = self._scene.add_line_segments(
                f"{WORLD}/trail/{slot}", segments, TRAIL_COLOR, thickness=0.012, visible=self._shown
            )
        else:
            handle.points = segments  # a recycled, growing or cut chunk: one small update
            handle.visible = self._shown  # a node hidden beyond a rewound moment shows again

    def clear(self) -> None:
        """Forget the path (after a reset or a new terrain)."""
        for handle in self._handles.values():
            handle.remove()
        self._handles.clear()
        self._sent.clear()
        self._path, self._ahead, self._first, self._next_time, self._dirty = [], [], 0, 0.0, False
        self._next_publish = -math.inf


class CameraFollow:
    """Keeps the robot in view by sliding the world under the cameras, which never move.

    Every scene node lives under the WORLD frame; following sets that one frame's position to
    minus the (smoothed) robot position: one message a frame for all clients, and each user's own
    orbit, zoom and pan are never touched (moving each browser's camera instead fights the user
    and drifts, as a browser reports the camera it last rendered). Unticking follow freezes the
    world where it is.
    """

    def __init__(self, scene: viser.SceneApi, x: float, z: float) -> None:
        self.enabled = True
        self.x, self.z = x, z  # the followed point, m: the world frame sits at minus it
        self.robot = (x, z)  # the robot's latest (x, z), m, followed or not
        self.world = scene.add_frame(WORLD, show_axes=False)
        self._move_world()

    def _move_world(self) -> None:
        self.world.position = on_grid(np.array([-self.x, 0.0, -self.z]), POSITION_GRID)

    def configure_initial(self, server: viser.ViserServer) -> None:
        """The side view new clients start from (and viser's own "reset view" returns to)."""
        initial = server.initial_camera
        initial.fov, initial.up = CAMERA_FOV, (0.0, 0.0, 1.0)
        initial.position, initial.look_at = LOOK_OFFSET + CAMERA_OFFSET, LOOK_OFFSET

    def shown_robot(self) -> np.ndarray:
        """Where the robot is drawn (m, scene frame): its position plus the world frame's offset.

        With follow on that is near the origin; with follow off, wherever the robot has gone since.
        """
        (x, z), (fx, fz) = self.robot, (self.x, self.z)  # set by the loop thread: at worst a frame old
        return np.array([x - fx, 0.0, z - fz])

    def home(self, client: viser.ClientHandle) -> None:
        """Put a client's camera at the side view of the robot, wherever it is drawn."""
        look_at = self.shown_robot() + LOOK_OFFSET
        with client.atomic():
            client.camera.fov = CAMERA_FOV
            client.camera.up_direction = (0.0, 0.0, 1.0)
            client.camera.position = look_at + CAMERA_OFFSET
            client.camera.look_at = look_at

    def update(self, x: float, z: float, dt: float, target: tuple[float, float] | None = None) -> None:
        """Note the robot at (x, z) (m); if following, move the followed point toward it (or toward
        `target`, m: a replayed log's ghosts) and the world to match."""
        self.robot = (x, z)
        if not self.enabled:
            return
        tx, tz = (x, z) if target is None else target
        self.x += (tx - self.x) * (1.0 - math.exp(-dt / FOLLOW_TAU_X))
        self.z += (tz - self.z) * (1.0 - math.exp(-dt / FOLLOW_TAU_Z))
        self._move_world()


GHOST_COLOR = (140, 200, 255)  # light blue: the re-flown "after" flight
GHOST_OPACITY = 0.35


class GhostRobot:
    """A semi-transparent copy of the robot replaying a re-flown flight (qpos frames) in a loop.

    Its own MjData turns each stored qpos into body poses; the live robot's data is never touched.
    """

    def __init__(
        self,
        scene: viser.SceneApi,
        model: mujoco.MjModel,
        *,
        name: str = "ghost",
        color: tuple[int, int, int] = GHOST_COLOR,
        offset: tuple[float, float, float] = (0.0, 0.0, 0.0),  # m, added to every pose (a ghost beside another)
    ) -> None:
        self._model, self._data = model, mujoco.MjData(model)
        self._meshes = body_meshes(model)
        self._offset = np.asarray(offset, dtype=float)
        self._handles = [
            scene.add_mesh_simple(
                f"{WORLD}/{name}/{body.name}",
                body.vertices,
                body.faces,
                color=color,
                opacity=GHOST_OPACITY,
                side="double",
                cast_shadow=False,
                visible=False,
            )
            for body in self._meshes
        ]
        self._poses = np.empty((0, 0))
        self._frame_s = 0.01
        self._started = 0.0
        self.shown_frame = -1  # index of the pose last sent, for tests
        self._visible = False

    def play(self, poses: np.ndarray, frame_s: float, now: float) -> None:
        """Replay `poses` (qpos rows, `frame_s` s apart in simulation) from wall time `now`, looping."""
        self._poses, self._frame_s, self._started = poses, frame_s, now
        self.shown_frame = -1

    def hide(self) -> None:
        self._poses = np.empty((0, 0))
        self._show(False)

    def _show(self, visible: bool) -> None:
        if visible != self._visible:
            self._visible = visible
            for handle in self._handles:
                handle.visible = visible

    @property
    def playing(self) -> bool:
        return len(self._poses) > 0

    def update(self, now: float) -> None:
        """Send the pose due at wall time `now` (call inside server.atomic(), from the loop)."""
        if not len(self._poses):
            return
        frame = int((now - self._started) / self._frame_s) % len(self._poses)
        if frame == self.shown_frame:
            return
        self.shown_frame = frame
        self._data.qpos[:] = self._poses[frame]
        mujoco.mj_kinematics(self._model, self._data)
        positions, quats = body_poses(self._model, self._data, self._meshes)
        for handle, p, q in zip(self._handles, positions, quats, strict=True):
            handle.position, handle.wxyz = p + self._offset, q
        self._show(True)
