"""What the dashboard puts on the wire for each viewer: chart payloads, batched pose frames, counts.

Counts, not speeds: how many messages a published frame or refresh holds and what they carry is
deterministic; how fast they come is the benchmark's business (benchmarks/bench_dashboard.py).
"""

from __future__ import annotations

import json
import math
import struct

import mujoco
import numpy as np
import pytest
import viser
from hopper.app.dashboard.plots import PLOT_PUBLISH_S, LivePlots
from hopper.app.dashboard.probe import CATEGORIES, ProbeClient
from hopper.app.dashboard.scene import ROBOT, WORLD, RobotView, kinematic_parents, local_poses, matte
from hopper.app.dashboard.server import Dashboard
from net import free_port, wait_until

from hopper.config import SimConfig
from hopper.control import Phase
from hopper.meshes import body_meshes, body_poses
from hopper.sim import Simulation

pytestmark = pytest.mark.integration  # servers, processes or pools (conftest: the suite in parts)


# -- charts ----------------------------------------------------------------------------------------
# What a refresh carries is tests/test_chart_feed.py's; here, when refreshes go out.
def test_charts_refresh_on_a_fixed_grid_of_publish_periods() -> None:
    """30 frames a second for 3 s, a new sample each: 3 / PLOT_PUBLISH_S refreshes, not one per 7 frames."""
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    try:
        plots = LivePlots(server)
        client = ProbeClient(f"http://127.0.0.1:{server.get_port()}")
        assert wait_until(lambda: len(server.get_clients()) == 1, timeout=20)
        for frame in range(90):
            now = 100.0 + frame / 30
            plots.sample(frame * 0.033, 0.0, 0.0, 0.0, 0.0)
            plots.publish(now)
        assert plots.feed.pushes == round(3.0 / PLOT_PUBLISH_S)
        client.close()
    finally:
        server.stop()


# -- poses -----------------------------------------------------------------------------------------
def test_local_poses_compose_back_to_the_world_poses() -> None:
    sim = Simulation(SimConfig())
    for _ in range(1500):  # into the first hop: every joint away from zero
        sim.step()
    meshes = body_meshes(sim.model)
    parents = kinematic_parents(sim.model, meshes)
    assert [meshes[p].name if p >= 0 else None for p in parents] == [
        None, "torso", "torso", "thigh_L", "torso", "thigh_R"
    ]  # fmt: skip
    world_p, world_q = body_poses(sim.model, sim.data, meshes)
    local_p, local_q = local_poses(world_p, world_q, parents)
    composed_p, composed_q = np.zeros_like(world_p), np.zeros_like(world_q)
    for i, parent in enumerate(parents):
        if parent < 0:  # the root: its position goes on the robot frame, its rotation on its node
            composed_p[i], composed_q[i] = world_p[i] + local_p[i], local_q[i]
            continue
        offset = np.zeros(3)
        mujoco.mju_rotVecQuat(offset, local_p[i], composed_q[parent])
        composed_p[i] = composed_p[parent] + offset
        mujoco.mju_mulQuat(composed_q[i], composed_q[parent], local_q[i])
    assert np.allclose(composed_p, world_p, atol=1e-12) and np.allclose(composed_q, world_q, atol=1e-12)
    # Hinges turn their bodies about their own origins: the offsets from the parents never change.
    sim.step()
    later_p, _ = local_poses(*body_poses(sim.model, sim.data, meshes), parents)
    assert np.allclose(later_p, local_p, atol=1e-12)


def test_multi_colour_bodies_go_as_matte_glb_in_the_colours_of_the_plain_ones() -> None:
    """The wheel and the shanks (vertex colours) are sent as GLB: with a non-metal material, not the
    glTF loader's default metalness 1 (the wheel's face rendered black without the environment map),
    and their colours linear, as glTF reads them: a shank (rgba 0.3 0.3 0.35, as the thighs') matches
    the thighs, sent as sRGB colours."""
    sim = Simulation(SimConfig())
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    sent: dict[str, bytes] = {}
    add_glb = server.scene.add_glb

    def record(name: str, glb_data: bytes, **kwargs: object) -> viser.GlbHandle:
        sent[name.rpartition("/")[2]] = glb_data
        return add_glb(name, glb_data, **kwargs)  # type: ignore[arg-type]

    server.scene.add_glb = record  # type: ignore[method-assign]
    try:
        RobotView(server.scene, sim.model)
    finally:
        server.stop()
    assert {"wheel", "shank_L", "shank_R"} <= set(sent), sorted(sent)
    for name, glb in sent.items():
        length = struct.unpack("<I", glb[12:16])[0]
        tree = json.loads(glb[20 : 20 + length])
        primitive = tree["meshes"][0]["primitives"][0]
        material = tree["materials"][primitive["material"]]["pbrMetallicRoughness"]
        assert material["metallicFactor"] == 0.0 and material["roughnessFactor"] == 1.0, (name, material)
        assert "COLOR_0" in primitive["attributes"], name
    shank = next(b for b in body_meshes(sim.model) if b.name == "shank_L")
    capsule = shank.colors[0, :3] / 255.0  # the shank's first geom: the capsule, 0.3 0.3 0.35
    assert np.allclose(capsule, [0.3, 0.3, 0.35], atol=0.003)
    linear = ((capsule + 0.055) / 1.055) ** 2.4  # the sRGB transfer function (above its linear toe)
    assert np.allclose(matte(shank.mesh).visual.vertex_attributes["color"][0, :3] / 255.0, linear, atol=0.003)


def test_the_phase_label_switches_labels_and_never_re_sends_a_text() -> None:
    """One label per phase, only the current one visible (RobotView): viser's client draws a visibility
    in the frame it arrives with the poses, a new text a render frame later."""
    sim = Simulation(SimConfig())
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    try:
        robot = RobotView(server.scene, sim.model)
        sent: list[str] = []
        for handle in robot.labels.values():
            handle._queue_update = lambda name, value: sent.append(name)  # type: ignore[method-assign]
        phases = [phase.label for phase in Phase]
        assert [handle.text for handle in robot.labels.values()] == phases
        for phase in [*phases, "stance", "stance"]:
            robot.update(sim.model, sim.data, 0.0, phase)
            assert [h.text for h in robot.labels.values() if h.visible] == [phase] and robot.label.text == phase
        robot.show_label = False  # the View panel's "Phase label" unticked
        robot.update(sim.model, sim.data, 0.0, "flight")
        assert not any(h.visible for h in robot.labels.values()) and robot.label.text == "flight"
        robot.show_label = True
        robot.update(sim.model, sim.data, 0.0, "flight")
        assert [h.text for h in robot.labels.values() if h.visible] == ["flight"]
        assert sent == [], sent  # no label's text (or other property) ever changed
    finally:
        server.stop()


def test_every_frame_moves_the_whole_robot_in_one_message(dashboard: Dashboard, client: ProbeClient) -> None:
    robot: RobotView = dashboard.robot
    nodes = {ROBOT, *robot.paths}
    frames: list[list[dict]] = []
    # Past the first frames, which may come with the backlog (the bodies' constant offsets among it).
    settled = client.snapshot()[2] + 3
    assert client.wait_for(lambda p: p.pose_frames >= settled)

    def full_frame(p: ProbeClient) -> bool:
        if p.last_pose_frame and (not frames or p.last_pose_frame is not frames[-1]):
            frames.append(p.last_pose_frame)
        return any({m["name"] for m in f} >= nodes for f in frames)

    # Within a bounded window, a frame whose one websocket message moves every body and the robot frame.
    assert client.wait_for(full_frame, timeout=20.0), [sorted(m["name"] for m in f) for f in frames[-3:]]
    for frame in frames:
        names = [m["name"] for m in frame]
        assert len(names) == len(set(names)), f"a node moved twice in one frame: {names}"
        assert set(names) <= nodes | {WORLD}, names
        # The robot frame moves (a position), every body turns (a rotation): no body sends a position.
        assert all(m["type"] == "SetOrientationMessage" for m in frame if m["name"] in robot.paths), frame
        assert len(frame) <= len(robot.paths) + 2


def test_scene_updates_and_chart_refreshes_are_counted_and_bytes_add_up(
    dashboard: Dashboard, client: ProbeClient
) -> None:
    start = client.traffic_snapshot()

    def enough(p: ProbeClient) -> bool:
        since = p.traffic.minus(start)
        charts = since.chart_refreshes
        return since.scene_updates >= 30 and len(charts) == 3 and min(charts.values()) >= 5

    assert client.wait_for(enough, timeout=30.0)
    client.close()  # nothing more arrives: the totals are final
    traffic = client.traffic_snapshot()
    assert traffic.scene_updates == client.pose_frames
    assert all(traffic.bytes[c] > 0 for c in CATEGORIES), traffic.bytes
    assert math.isclose(sum(traffic.bytes.values()), client.bytes, rel_tol=1e-9)
    assert sum(traffic.messages.values()) == sum(client.counts.values())
