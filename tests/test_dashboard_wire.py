"""What the dashboard puts on the wire for each viewer: chart payloads, batched pose frames, counts.

Counts, not speeds: how many messages a published frame or refresh holds and what they carry is
deterministic; how fast they come is the benchmark's business (benchmarks/bench_dashboard.py).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
import viser
from hopper.app.dashboard.plots import (
    PLOT_HEIGHT_PX,
    PLOT_PUBLISH_S,
    SIMPLIFY_ABOVE,
    TOLERANCE_PX,
    LivePlots,
    simplify,
)
from hopper.app.dashboard.probe import CATEGORIES, ProbeClient
from hopper.app.dashboard.scene import ROBOT, WORLD, RobotView, kinematic_parents, local_poses
from hopper.app.dashboard.server import Dashboard
from net import free_port

from hopper.config import WHEEL_TORQUE_LIMIT, SimConfig
from hopper.control import Phase
from hopper.meshes import body_meshes, body_poses
from hopper.metrics import RAD_S_TO_RPM
from hopper.sim import Simulation

pytestmark = pytest.mark.integration  # servers, processes or pools (conftest: the suite in parts)


def _signal(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Times (s) 25 or 26 ms apart and a hopping-like trace: slow swings, a ringing kick, steps, noise."""
    t = np.cumsum(rng.choice([0.025, 0.026], size=n)).astype(np.float32)
    y = 1.2 * np.sin(2 * np.pi * 0.8 * t) + 0.4 * np.exp(-3 * (t % 2.5)) * np.sin(2 * np.pi * 4.8 * t)
    y += np.where((t % 3.0) < 0.2, 0.8, 0.0) + rng.normal(0, 0.01, n)
    return t, y.astype(np.float32)


def _max_error_px(t: np.ndarray, y: np.ndarray, mask: np.ndarray, units_per_px: float) -> float:
    """The largest vertical distance (px) of any sample from the line drawn through the kept ones."""
    t64, y64 = t.astype(np.float64), y.astype(np.float64)
    return float(np.abs(np.interp(t64, t64[mask], y64[mask]) - y64).max() / units_per_px)


# -- charts ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_simplify_keeps_every_sample_within_the_tolerance(seed: int) -> None:
    t, y = _signal(np.random.default_rng(seed), 400)
    units_per_px = 4.0 / PLOT_HEIGHT_PX
    mask = simplify(t, y, units_per_px)
    assert mask[0] and mask[-1] and mask[np.argmax(y)] and mask[np.argmin(y)]
    assert _max_error_px(t, y, mask, units_per_px) <= TOLERANCE_PX
    assert mask.sum() < 0.6 * len(y), f"kept {mask.sum()} of {len(y)}"
    # A coarser tolerance keeps fewer, and a straight line needs only its ends.
    assert simplify(t, y, units_per_px, 2.0).sum() < mask.sum()
    line = (0.3 * t - 1.0).astype(np.float32)
    assert simplify(t, line, units_per_px).sum() == 2


def _chart_columns(client: ProbeClient, chart: viser.GuiUplotHandle) -> list[np.ndarray]:
    data = client.chart_data[chart._impl.uuid]
    # Plain number lists, not binary buffers (which the probe would hand back as (dtype, bytes)).
    assert all(isinstance(column, list) and all(isinstance(v, float) for v in column) for column in data)
    return [np.asarray(column, dtype=np.float64) for column in data]


def test_a_refresh_sends_each_chart_the_window_samples_its_line_needs() -> None:
    server = viser.ViserServer(port=free_port(), verbose=False)
    try:
        plots = LivePlots(server.gui)
        client = ProbeClient(f"http://127.0.0.1:{server.get_port()}")
        assert client.wait_for(lambda p: len(p.uplots) == 3)
        rng = np.random.default_rng(7)
        t, pitch = _signal(rng, 400)
        _, rpm = _signal(rng, 400)
        _, torque = _signal(rng, 400)
        command = torque + rng.normal(0, 0.05, 400).astype(np.float32)
        for row in zip(t, pitch, 100 * rpm, 8 * torque, 8 * command, strict=True):
            time, pitch_deg, speed_rpm, applied, asked = (float(v) for v in row)
            plots.sample(time, math.radians(pitch_deg), speed_rpm / RAD_S_TO_RPM, applied, asked)
        plots.publish(now=10.0)
        assert client.wait_for(lambda p: len(p.chart_data) == 3)
        window = plots.window.columns()
        charts = (
            (plots.pitch, (1,), plots._pitch_range(window[1])),
            (plots.rpm, (2,), plots.rpm_range),
            (plots.torque, (3, 4), plots.torque_range),
        )
        for chart, rows, y_range in charts:
            sent_t, *sent = _chart_columns(client, chart)
            # The same window: its first and last sample times, and only times from the window.
            assert sent_t[0] == window[0][0] and sent_t[-1] == window[0][-1]
            index = np.searchsorted(window[0], sent_t)
            assert np.array_equal(window[0][index], sent_t.astype(np.float32))
            assert len(sent_t) < len(window[0]), "a full window is simplified"
            mask = np.zeros(len(window[0]), dtype=bool)
            mask[index] = True
            for row, column in zip(rows, sent, strict=False):
                # The very samples (float32 values, exact in the lists' float64) ...
                assert np.array_equal(column.astype(np.float32), window[row][index])
                # ... and every sample left out lies within the tolerance of the line through them.
                assert _max_error_px(window[0], window[row], mask, y_range / PLOT_HEIGHT_PX) <= TOLERANCE_PX
            limits = sent[len(rows) :]
            if limits:
                level = plots.rpm_limit if chart is plots.rpm else WHEEL_TORQUE_LIMIT
                for column, sign in zip(limits, (1, -1), strict=True):
                    assert len(column) == len(sent_t) and np.all(column == column[0])
                    assert column[0] == pytest.approx(sign * level, rel=1e-6)
        client.close()
    finally:
        server.stop()


def test_a_short_window_is_sent_whole() -> None:
    server = viser.ViserServer(port=free_port(), verbose=False)
    try:
        plots = LivePlots(server.gui)
        client = ProbeClient(f"http://127.0.0.1:{server.get_port()}")
        assert client.wait_for(lambda p: len(p.uplots) == 3)
        for i in range(SIMPLIFY_ABOVE):
            plots.sample(i * 0.025, math.radians(math.sin(i)), 10.0 * math.cos(i), 5.0, 6.0)
        plots.publish(now=1.0)
        assert client.wait_for(lambda p: len(p.chart_data) == 3)
        sent_t, sent_pitch = _chart_columns(client, plots.pitch)
        window = plots.window.columns()
        assert np.array_equal(sent_t.astype(np.float32), window[0])
        assert np.array_equal(sent_pitch.astype(np.float32), window[1])
        client.close()
    finally:
        server.stop()


def test_charts_refresh_on_a_fixed_grid_of_publish_periods() -> None:
    """30 frames a second for 3 s, a new sample each: 3 / PLOT_PUBLISH_S refreshes, not one per 7 frames."""
    server = viser.ViserServer(port=free_port(), verbose=False)
    try:
        plots = LivePlots(server.gui)
        sent = []
        plots.pitch._queue_update = lambda name, value: sent.append(name)  # type: ignore[method-assign]
        for frame in range(90):
            now = 100.0 + frame / 30
            plots.sample(frame * 0.033, 0.0, 0.0, 0.0, 0.0)
            plots.publish(now)
        assert len(sent) == round(3.0 / PLOT_PUBLISH_S)
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
