"""End to end in a real headless Chromium: a mouse drag on the torso pulls the robot, and the pull is
a disturbance in the event log and in the recording; the physics overlays are in the scene.
Skips without /usr/bin/chromium, except under CI=true.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from net import wait_until
from rrd import verify
from test_dashboard_e2e import open_workbench
from test_telemetry import cells, read

from hopper.events import Dragged

LOG_JS = "() => [...document.querySelectorAll('table.hd-log')].map(t => t.textContent).join(' | ')"


def _quat_matrix(wxyz: np.ndarray) -> np.ndarray:
    w, x, y, z = wxyz
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])  # fmt: skip


def _on_screen(camera, point: np.ndarray, width: float, height: float) -> tuple[float, float]:
    """Where a scene point is drawn in a canvas of width x height CSS pixels (viser's OpenCV camera)."""
    p = _quat_matrix(np.asarray(camera.wxyz)).T @ (point - np.asarray(camera.position))
    f = 0.5 * height / math.tan(0.5 * camera.fov)  # the fov is vertical
    return 0.5 * width + f * p[0] / p[2], 0.5 * height + f * p[1] / p[2]


def test_dragging_the_torso_pulls_the_robot_and_is_recorded_as_a_disturbance(browser, start, tmp_path: Path):  # noqa: F811
    path = tmp_path / "drag.rrd"
    dashboard = start(terrain="flat", rrd=path)
    page = open_workbench(browser, dashboard)
    try:
        # Standing, then paused: the torso holds still where it is drawn while the pointer finds it.
        assert wait_until(lambda: any(e.kind == "touchdown" for e in dashboard.sim.events), timeout=60)
        assert wait_until(lambda: dashboard.sim.phase.name == "STANCE", timeout=30)
        dashboard.layout.view.follow.value = False  # the world frame stops sliding under the robot
        dashboard.layout.simulation.set_paused(True)
        # The strip's "paused" goes in the same atomic batch as the poses of that frame, after them:
        # once the page shows it, the robot is drawn where it stays.
        page.wait_for_selector(".hd-paused", timeout=30_000)
        (client,) = dashboard.server.get_clients().values()
        box = page.locator("canvas").first.bounding_box()
        x, y = _on_screen(client.camera, dashboard.camera.shown_robot(), box["width"], box["height"])
        x, y = box["x"] + x, box["y"] + y
        before = dashboard.sim.state().x

        page.mouse.move(x, y)
        page.mouse.down()
        page.mouse.move(x + 60, y, steps=6)
        page.mouse.move(x + 120, y, steps=6)  # to the right of a side view: +x, forward
        assert wait_until(lambda: dashboard.sim.pull is not None, timeout=30), "the drag never grabbed the torso"
        assert dashboard.sim.pull.target[0] > dashboard.sim.state().x + 0.1  # the target is ahead of the torso
        dashboard.layout.simulation.set_paused(False)
        assert wait_until(lambda: dashboard.sim.state().x > before + 0.1, timeout=30), "the pull did not move it"
        # Release while paused: on a loaded machine the release arrives late, and a pull held on
        # drags the robot into a recovery hop past the pointer, which pulls it back (net x < 0).
        dashboard.layout.simulation.set_paused(True)
        page.mouse.up()
        assert wait_until(lambda: any(isinstance(e.payload, Dragged) for e in dashboard.sim.events), timeout=30)
        dashboard.layout.simulation.set_paused(False)

        assert wait_until(lambda: any(isinstance(e.payload, Dragged) for e in dashboard.sim.events), timeout=30)
        drag = next(e for e in dashboard.sim.events if isinstance(e.payload, Dragged))
        assert drag.payload.impulse_x > 0.5 and drag.payload.duration_s > 0.1, drag.payload
        page.wait_for_function(f"() => ({LOG_JS})().includes('drag +')", timeout=30_000)
    finally:
        page.close()
    dashboard.stop()  # closes the recording

    verify(path)
    events = read(path)["events"]
    texts = [
        t for t, kind in zip(cells(events, "TextLog:text"), cells(events, "kind"), strict=True) if kind == "disturbance"
    ]
    assert [t for t in texts if t.startswith("disturbance: drag +")] == [f"disturbance: {drag.describe()}"], texts
