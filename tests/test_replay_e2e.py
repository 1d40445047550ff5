"""End to end in a real headless Chromium: re-fly with overlaid before/after traces, scrubbing back
10 s and resuming, and a keyframe saved, the robot reset, the keyframe restored bit for bit.
Skips without /usr/bin/chromium, except under CI=true. Screenshots (1440x900) go to the test's
tmp_path, and also to $HOPPER_SHOTS when set.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
from hopper.app.dashboard.server import Dashboard
from net import wait_until
from pages import wait_for_ab_table
from test_dashboard_e2e import PAGE_LOAD_MS
from test_workbench_e2e import _type

from hopper import keyframes
from hopper.control.memory import MEMORY

VIEWPORT = {"width": 1440, "height": 900}  # for the screenshots
# Headless Chromium draws the scene's WebGL in software: on a loaded machine a full-size frame takes
# long enough to hold each click for seconds. The page is driven in a smaller window, resized for shots.
WORK_VIEWPORT = {"width": 1100, "height": 700}
_REFLY_CHART = "[...document.querySelectorAll('.uplot')].find(e => e.innerText.includes('after (°)'))"
REFLY_CHART_JS = (
    f"() => {{ const u = {_REFLY_CHART}; u.scrollIntoView(); const r = u.querySelector('.u-over')"
    ".getBoundingClientRect(); return [r.x + r.width / 2, r.y + r.height / 2]; }"
)
LEGEND_JS = f"() => [...{_REFLY_CHART}.querySelectorAll('.u-legend .u-value')].map(v => v.innerText)"
NOTES_JS = "() => [...document.querySelectorAll('.mantine-Notification-root')].map(n => n.innerText).join(' | ')"


def _shot(page, tmp_path: Path, name: str) -> None:
    # Headless Chromium renders WebGL in software, and viser says so in a notification over the scene.
    page.evaluate(
        "() => document.querySelectorAll('.mantine-Notification-root').forEach("
        "n => { if (n.innerText.includes('WebGL')) n.remove(); })"
    )
    path = tmp_path / name
    page.set_viewport_size(VIEWPORT)
    page.wait_for_timeout(500)  # let the scene and the charts redraw at the new size (a picture, not an assertion)
    page.screenshot(path=str(path))
    page.set_viewport_size(WORK_VIEWPORT)
    if os.environ.get("HOPPER_SHOTS"):
        Path(os.environ["HOPPER_SHOTS"]).mkdir(parents=True, exist_ok=True)
        shutil.copy(path, Path(os.environ["HOPPER_SHOTS"]) / name)


def _open(browser, dashboard: Dashboard):  # noqa: F811
    page = browser.new_page(viewport=WORK_VIEWPORT)
    page.set_default_timeout(60_000)  # a bound for a loaded machine, not a pace
    page.goto(dashboard.url)
    page.get_by_role("tab", name="Replay").wait_for(timeout=PAGE_LOAD_MS)
    assert wait_until(lambda: len(dashboard.server.get_clients()) == 1, timeout=30)
    page.get_by_role("tab", name="Replay").click()
    return page


def _input(page, handle):
    """The text input beside a viser slider or text field (viser labels it by the handle's id)."""
    label = page.locator(f'label[for="{handle._impl.uuid}"]')
    return label.locator("xpath=ancestor::div[contains(@style,'padding-inline')][1]").locator("input").last


def _fast(dashboard: Dashboard) -> None:
    dashboard.layout.simulation.set_speed(4.0)


def _state(dashboard: Dashboard) -> list[bytes]:
    d, mem = dashboard.sim.data, dashboard.sim.controller.mem
    return [d.qpos.tobytes(), d.qvel.tobytes(), d.act.tobytes(), d.ctrl.tobytes(), np.float64(d.time).tobytes()] + [
        mem[name].tobytes() for name in MEMORY.names
    ]


def test_refly_overlays_before_and_after(browser, dashboard: Dashboard, tmp_path: Path):  # noqa: F811
    _fast(dashboard)
    assert wait_until(lambda: dashboard.history.last_flight is not None, timeout=60), "no flight recorded"
    dashboard.layout.simulation.set_paused(True)  # the last flight was flown with the default gains
    page = _open(browser, dashboard)
    try:
        page.get_by_role("tab", name="Gains").click()
        _type(page, dashboard.layout.gains.entries["kd"], "70")
        assert wait_until(lambda: dashboard.sim.gains.kd == 70.0, timeout=30)
        page.get_by_role("tab", name="Replay").click()
        page.get_by_role("button", name="Re-fly last flight").click()
        replay = dashboard.layout.replay
        assert wait_until(lambda: replay.last is not None, timeout=30)
        c = replay.last
        assert c.before_identical  # same state, same gains: the recorded flight, bit for bit
        assert c.before.gains == c.recorded.gains != c.after.gains and c.after.gains.kd == 70.0
        n = min(len(c.after.pitch), len(c.recorded.pitch))
        assert np.abs(c.after.pitch[:n] - c.recorded.pitch[:n]).max() > 1e-5  # other gains: another flight
        # Both traces reach the page: hovering the middle of the re-fly pitch chart, its legend shows a
        # value for "before" and for "after" (uPlot shows "--" where a series has no data).
        wait_for_ab_table(page, "identical to the recorded flight", "450/50/30", "450/50/70")
        # Every cell holds its text: the first row's label and liftoff time once ran over its gains.
        spills = page.evaluate(
            "() => [...document.querySelectorAll('table.hd-ab td')]"
            ".filter(td => td.scrollWidth > td.clientWidth + 1).map(td => td.innerText)"
        )
        assert spills == [], spills
        x, y = page.evaluate(REFLY_CHART_JS)
        page.mouse.move(x, y)
        page.wait_for_function(
            f"() => {{ const v = ({LEGEND_JS})(); return v.length == 3 && v.every(t => /\\d/.test(t)); }}"
        )
        # A chart drawn from its own data keeps viser's expand button (only the live, fed charts hide it).
        button_shown = """([x, y]) => {
            const box = document.elementFromPoint(x, y)?.closest('.uplot-container');
            const button = box?.querySelector(':scope > .mantine-ActionIcon-root');
            return !!button && getComputedStyle(button).display !== 'none';
        }"""
        page.wait_for_function(button_shown, arg=[x, y])
        data = replay.plots.pitch.data
        assert len(data) == 3 and np.isfinite(data[1]).sum() > 100 and np.isfinite(data[2]).sum() > 100
        assert wait_until(lambda: dashboard.ghost.shown_frame >= 0, timeout=30)  # the ghost is flying
        first = dashboard.ghost.shown_frame
        assert wait_until(lambda: dashboard.ghost.shown_frame != first, timeout=30)
        page.get_by_text("Re-fly: before / after").first.scroll_into_view_if_needed()
        _shot(page, tmp_path, "refly.png")
    finally:
        page.close()


def test_scrub_back_ten_seconds_and_resume(browser, dashboard: Dashboard, tmp_path: Path):  # noqa: F811
    _fast(dashboard)
    assert wait_until(lambda: dashboard.history.span >= 11.0, timeout=90), dashboard.history.span
    page = _open(browser, dashboard)  # the history goes on growing meanwhile
    try:
        assert wait_until(lambda: dashboard.history.span >= 12.0, timeout=90), dashboard.history.span
        replay = dashboard.layout.replay
        box = _input(page, replay.back.handle)  # the typed Back: read after a short quiet time
        box.fill("-10")
        assert wait_until(lambda: replay.scrubbed is not None, timeout=30)
        snap = replay.scrubbed
        ring = list(dashboard.history.ring)
        # 10 s back is 100 ring entries (0.1 s apart) before the newest at the time of the scrub; a
        # few more may have come before the loop saw the pause. (Index, not time: a reset may lie between.)
        assert 100 <= len(ring) - 1 - ring.index(snap) <= 140, (len(ring), ring.index(snap))
        assert wait_until(lambda: dashboard.sim.time == snap.time and dashboard.pacer.paused, timeout=30)
        # The robot shown is the robot then: the published pose is the restored state's.
        expected = dashboard.sim.data.xpos[dashboard.sim.layout.torso].copy()
        assert wait_until(lambda: np.allclose(dashboard.robot.torso_position, expected), timeout=30)
        page.wait_for_function("() => document.body.innerText.includes('10.0 s back')", timeout=30_000)
        _shot(page, tmp_path, "scrubber.png")
        page.get_by_role("button", name="Resume from here").click()
        ticks = dashboard.sim.ticks
        assert wait_until(lambda: dashboard.sim.ticks > ticks + 1000, timeout=30)  # it runs again
        assert not dashboard.pacer.paused
        # From the scrubbed moment on: the history after it was dropped, the ring continues from it.
        ring = list(dashboard.history.ring)
        after = ring[ring.index(snap) + 1]
        assert abs(after.time - snap.time - 0.1) < 1.5e-3, (snap.time, after.time)
    finally:
        page.close()


def test_keyframe_save_reset_restore_export_import(browser, dashboard: Dashboard, tmp_path: Path):  # noqa: F811
    _fast(dashboard)
    assert wait_until(lambda: dashboard.sim.time > 2.0, timeout=60)
    dashboard.layout.simulation.set_paused(True)
    page = _open(browser, dashboard)
    try:
        replay = dashboard.layout.replay
        name = _input(page, replay.name)
        name.fill("mid hop")
        name.press("Tab")
        assert wait_until(lambda: replay.name.value == "mid hop", timeout=30)
        page.get_by_role("button", name="Save keyframe").click()
        assert wait_until(lambda: "mid hop" in replay.keyframes, timeout=30)
        saved = _state(dashboard)
        assert replay.keyframes["mid hop"].time == dashboard.sim.time

        page.get_by_role("button", name="Reset robot").click()
        assert wait_until(lambda: dashboard.sim.time == 0.0, timeout=30)
        assert _state(dashboard) != saved
        page.get_by_role("button", name="Restore keyframe").click()
        assert wait_until(lambda: _state(dashboard) == saved, timeout=30)  # bit for bit
        page.wait_for_function(f"() => ({NOTES_JS})().includes('Keyframe restored')", timeout=30_000)
        _shot(page, tmp_path, "keyframes.png")

        # Export: a download the browser receives, which reads back as the same keyframe.
        with page.expect_download(timeout=30_000) as download:
            page.get_by_role("button", name="Export keyframe").click()
        text = Path(download.value.path()).read_text()
        assert json.loads(text)["name"] == "mid hop"
        assert keyframes.from_json(text, dashboard.sim).snapshot.physics.tobytes() == (
            replay.keyframes["mid hop"].snapshot.physics.tobytes()
        )
        # A damaged file is refused with a visible notification; nothing changes.
        damaged = text.replace('"sha256": "', '"sha256": "0')
        upload = page.locator("input[type=file]")
        upload.set_input_files(files=[{"name": "bad.json", "mimeType": "application/json", "buffer": damaged.encode()}])
        page.wait_for_function(f"() => ({NOTES_JS})().includes('Keyframe refused')", timeout=30_000)
        assert list(replay.keyframes) == ["mid hop"] and _state(dashboard) == saved
        # The file as exported imports.
        renamed = text.replace('"name": "mid hop"', '"name": "imported"')
        upload.set_input_files(files=[{"name": "k.json", "mimeType": "application/json", "buffer": renamed.encode()}])
        assert wait_until(lambda: "imported" in replay.keyframes, timeout=30)
    finally:
        page.close()
