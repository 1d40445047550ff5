"""See the physics: ground reaction arrows, the predicted flight and landing, and the mouse's pull.

Drawn from the loop thread each frame, but sent only when something visibly changes: the arc and
the landing marks once per flight (again at the apex, when the controller has planned the legs'
reach, and after anything pushes the CoM off the arc), the arrows at most every FORCES_S.
Dragging the torso (or its wheel) pulls it with a spring (hopper.perturb); viewers' drags are
refused by the roles gate like any other input.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import mujoco
import numpy as np
import trimesh
import viser
from hopper.app.dashboard.scene import WORLD, CameraFollow, RobotView

from hopper.ballistics import Arc, predict
from hopper.commands import Grab, PullTo, Release
from hopper.control import Phase
from hopper.sim import Command, Simulation
from hopper.stand import StandSimulation

FORCE_COLOR = (88, 166, 255)  # blue: what the ground pushes
ARC_COLOR = (120, 220, 255)  # cyan: apart from the orange trail
LANDING_COLOR = (255, 123, 114)
PULL_COLOR = (240, 90, 220)
WEIGHT_M = 0.5  # m of arrow for the robot's weight at the current gravity: the same look on any body
FORCES_S = 0.1  # s of wall time between arrow updates
FORCE_MOVE_M = 0.01  # an arrow is re-sent when its tip moves this much
DASH_STEPS = 3  # the arc's dashes and gaps, in the prediction's steps (hopper.ballistics.STEP_S: 15 ms of flight)
REPLAN_M = 0.02  # m: the arc is recomputed when the CoM is this far off it (a push, a drag)


def _landing_mark() -> tuple[np.ndarray, np.ndarray]:
    ring = trimesh.creation.annulus(r_min=0.035, r_max=0.06, height=0.006, sections=32)
    return np.asarray(ring.vertices, np.float32), np.asarray(ring.faces, np.uint32)


class PhysicsView:
    """The overlays of one dashboard; `visible` is set from the View panel (any thread)."""

    def __init__(self, scene: viser.SceneApi, sim: Simulation) -> None:
        self.visible = True
        self._shown = True
        self._arrow_style = {"shaft_radius": 0.012, "head_radius": 0.03, "head_length": 0.06}
        zero = np.zeros((1, 2, 3), np.float32)
        self.forces = [
            scene.add_arrows(f"{WORLD}/physics/force_{side}", zero, FORCE_COLOR, visible=False, **self._arrow_style)
            for side in "LR"
        ]
        self.arc = scene.add_line_segments(f"{WORLD}/physics/arc", zero, ARC_COLOR, thickness=0.014, visible=False)
        vertices, faces = _landing_mark()
        self.marks = [
            scene.add_mesh_simple(f"{WORLD}/physics/landing_{side}", vertices, faces, color=LANDING_COLOR,
                                  cast_shadow=False, visible=False)
            for side in "LR"
        ]  # fmt: skip
        self.pull = scene.add_arrows(f"{WORLD}/physics/pull", zero, PULL_COLOR, visible=False, **self._arrow_style)
        self._feet = [sim.model.geom(f"foot_{side}").id for side in "LR"]
        self._foot_y = sim.robot.foot_y  # m, each foot's line
        self._force = np.zeros(6)
        self._tips: list[np.ndarray | None] = [None, None]
        self._next_forces = -math.inf
        self._arc: Arc | None = None
        self._flown = np.zeros((0, 2))  # CoM (x, z) of this flight's earlier arcs, up to their replanning
        self._planned_rising = False

    def terrain_changed(self, sim: Simulation) -> None:
        self._hide_arc()

    def update(self, sim: Simulation, now: float) -> None:
        """Bring the overlays up to date with `sim` (loop thread; `now`: wall s)."""
        shown = self.visible
        if shown != self._shown:
            self._shown = shown
            if not shown:
                self._hide_arc()
                for side in range(2):
                    self._set_force(side, None, 0.0)
                self.pull.visible = False
        if not shown:
            return
        flight = sim.phase is Phase.FLIGHT
        # On the stand the kernel flies its flight's attitude loop, but nothing is ballistic: no arc.
        self._update_arc(sim, flight and not isinstance(sim, StandSimulation))
        if now >= self._next_forces:
            self._next_forces = now + FORCES_S
            weight = float(sim.model.body_subtreemass[sim.layout.torso]) * sim.config.gravity  # N, at this gravity
            for side in range(2):
                self._set_force(side, None if flight else self._ground_force(sim, side), WEIGHT_M / weight)
        self._update_pull(sim)

    # -- the flight ----------------------------------------------------------------------------
    def _update_arc(self, sim: Simulation, flight: bool) -> None:
        if not flight:
            self._hide_arc()
            return
        s, layout = sim.data.sensordata, sim.layout
        com = np.array([s[layout.s_com], s[layout.s_com + 2]])
        velocity = (float(s[layout.s_com_vel]), float(s[layout.s_com_vel + 2]))
        rising = velocity[1] > 0.0
        arc = self._arc
        stale = (
            arc is None
            or (self._planned_rising and not rising)  # past the apex: the legs' reach is planned now
            or float(np.linalg.norm(arc.com_at(sim.time) - com)) > REPLAN_M
        )
        if not stale:
            return
        feet = sim.controller.landing_feet(sim.data, layout)
        if arc is not None:  # keep what was flown of the old arc: the whole flight stays drawn
            self._flown = np.concatenate([self._flown, arc.com[arc.times <= sim.time - arc.t0]])
        ground = sim.ground_profile()  # the window's, built once per window
        arc = predict(sim.time, (float(com[0]), float(com[1])), velocity, feet, sim.config.gravity, ground)
        self._arc, self._planned_rising = arc, rising
        path = np.concatenate([self._flown, arc.com])
        points = np.zeros((len(path), 3), np.float32)
        points[:, 0], points[:, 2] = path[:, 0], path[:, 1]
        # A dash over DASH_STEPS steps, a gap as long: at 5 ms steps a dash a step long drew a line the eye
        # could not tell from a solid one, in twice the segments (its 2.4 kB re-sent at each replanning).
        dashes = np.stack([points[: -DASH_STEPS : 2 * DASH_STEPS], points[DASH_STEPS :: 2 * DASH_STEPS]], axis=1)
        if len(dashes):
            self.arc.points = dashes
            self.arc.visible = True
        for side, mark in enumerate(self.marks):
            if arc.feet:
                x, z = arc.feet[side]
                mark.position = (x, self._foot_y if side == 0 else -self._foot_y, z + 0.004)
            mark.visible = bool(arc.feet)

    def _hide_arc(self) -> None:
        if self._arc is not None or self.arc.visible:
            self._arc, self._flown = None, np.zeros((0, 2))
            self.arc.visible = False
            for mark in self.marks:
                mark.visible = False

    # -- the ground ----------------------------------------------------------------------------
    def _ground_force(self, sim: Simulation, side: int) -> tuple[np.ndarray, np.ndarray] | None:
        """(contact point, force on the foot) in world coordinates (m, N), or None without contact."""
        model, data, foot = sim.model, sim.data, self._feet[side]
        total, point, count = np.zeros(3), np.zeros(3), 0
        for i in range(data.ncon):
            contact = data.contact[i]
            if foot not in (contact.geom1, contact.geom2):
                continue
            mujoco.mj_contactForce(model, data, i, self._force)
            world = contact.frame.reshape(3, 3).T @ self._force[:3]  # the normal points from geom1 to geom2
            total += world if contact.geom2 == foot else -world
            point += contact.pos
            count += 1
        if count == 0:
            return None
        return point / count, total

    def _set_force(self, side: int, force: tuple[np.ndarray, np.ndarray] | None, metres_per_newton: float) -> None:
        arrow = self.forces[side]
        if force is None:
            if self._tips[side] is not None:
                self._tips[side] = None
                arrow.visible = False
            return
        point, total = force
        tip = point + total * metres_per_newton
        previous = self._tips[side]
        if previous is not None and float(np.linalg.norm(tip - previous)) < FORCE_MOVE_M:
            return
        self._tips[side] = tip
        arrow.points = np.array([[point, tip]], np.float32)
        arrow.visible = True

    # -- the mouse -----------------------------------------------------------------------------
    def _update_pull(self, sim: Simulation) -> None:
        pull = sim.pull
        if pull is None:
            if self.pull.visible:
                self.pull.visible = False
            return
        start = pull.anchor_world(sim.data)
        end = np.array([pull.target[0], start[1], pull.target[1]])
        self.pull.points = np.array([[start, end]], np.float32)
        self.pull.visible = True


def bind_drag(robot: RobotView, camera: CameraFollow, submit: Callable[[Command], None]) -> None:
    """Dragging the torso, its wheel or its ring pulls the torso at the grabbed point toward the pointer.

    viser reports scene coordinates; the world frame sits at minus the camera's followed point.
    """

    async def on_drag(event: viser.SceneNodeDragEvent) -> None:  # async: phases arrive in order
        ox, oz = camera.x, camera.z
        if event.phase == "start":
            submit(Grab((event.start_position[0] + ox, event.start_position[2] + oz)))
        if event.phase == "end":
            submit(Release())
        else:
            submit(PullTo((event.end_position[0] + ox, event.end_position[2] + oz)))

    for handle in robot.grabbable():
        handle.on_drag(on_drag)
