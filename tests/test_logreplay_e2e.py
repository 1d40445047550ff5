"""End to end in a real headless Chromium: a bad path is a notification and the simulation keeps running;
a captured log of two hops is replayed beside the simulation: two ghosts in step, on the log's ground, and
the error charts.
Skips without /usr/bin/chromium, except under CI=true. The screenshot goes to the test's tmp_path
(and to $HOPPER_SHOTS when set).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
from hopper.app.dashboard.server import Dashboard
from net import wait_until
from test_replay_e2e import NOTES_JS, _input, _open, _shot

from hopper.logs.capture import capture
from hopper.logs.io import write_log
from hopper.logs.synthetic import synthetic_log


def _load(page, dashboard: Dashboard, text: str) -> None:
    panel = dashboard.layout.logreplay
    before = panel.finished
    box = _input(page, panel.path)
    box.fill(text)
    box.press("Tab")
    assert wait_until(lambda: panel.path.value == text, timeout=30)
    page.get_by_role("button", name="Load and replay log").click()
    assert wait_until(lambda: panel.finished > before, timeout=60), "the load never ended"


def test_a_log_replays_beside_the_simulation(browser, dashboard: Dashboard, tmp_path: Path):  # noqa: F811
    # Another seed than the dashboard's: the replay must fly on the log's ground, not the dashboard's. Sensed
    # as capture's CLI does (the replay's drive delays the commands as the realistic sensing's motor does).
    world = dataclasses.replace(dashboard.sim.config, seed=dashboard.sim.config.seed + 1, sensing="realistic")
    recorded = capture(world, 2).log
    path = write_log(recorded, tmp_path / "two_hops.npz")
    page = _open(browser, dashboard)
    try:
        panel = dashboard.layout.logreplay
        start = dashboard.sim.data.time
        _load(page, dashboard, str(tmp_path / "missing.npz"))
        page.wait_for_function(f"() => ({NOTES_JS})().includes('Log not replayed')")
        assert "no such file" in page.evaluate(NOTES_JS)
        assert panel.last is None
        assert wait_until(lambda: dashboard.sim.data.time > start + 0.5, timeout=60), "the simulation stopped"
        stateless = write_log(synthetic_log(1.0, optional=False), tmp_path / "no_state.npz")  # no x, z, vx, ...
        _load(page, dashboard, str(stateless))
        page.wait_for_function(f"() => ({NOTES_JS})().includes('has no x')")
        assert panel.last is None

        _load(page, dashboard, str(path))
        done = panel.last
        assert done is not None and done.source == str(path) and len(done.parts) == done.found == 2
        assert done.logged.shape == done.simulated.shape and len(done.logged) > 100
        # The log's ghost is the log: its first pose stands where the log's robot was at the first liftoff.
        lay = dashboard.sim.layout
        first = done.parts[0][0].first
        assert abs(done.logged[0][lay.q_pitch] - recorded.signals["pitch"][first]) < 1e-12
        # Both ghosts play in step: the loop sends them the same frame.
        assert wait_until(lambda: 5 < panel.logged_ghost.shown_frame == panel.simulated_ghost.shown_frame, timeout=60)
        page.wait_for_function(f"() => ({NOTES_JS})().includes('Log replayed')")
        # They stand on the log's ground (another seed's), drawn in place of the live ground while watched.
        assert wait_until(lambda: panel.grounded is done, timeout=30)
        assert set(panel.ground.tiles) == set(done.ground) and dashboard.terrain.hidden
        assert not any(tile.visible for tile in dashboard.terrain.tiles.values())
        # The camera goes to the ghosts (where the log was recorded), and back to the live robot when unticked.
        assert panel.watch.value and panel.watched() is not None
        assert wait_until(lambda: abs(dashboard.camera.robot[0] - dashboard.sim.state().x) < 0.5, timeout=30)
        page.wait_for_function(
            "() => [...document.querySelectorAll('.hd-record')].some(e => e.innerText.includes('pitch RMS'))"
        )
        page.wait_for_function(
            "() => ['pitch error (°)', 'wheel speed error (rpm)', 'sim on ground'].every(l => "
            "[...document.querySelectorAll('.uplot')].some(u => u.innerText.includes(l)))"
        )
        e = done.errors
        # The robot that made the log, replayed on its own ground: it flies the same hops.
        assert f"seed {world.seed}" in done.world and "(the log's)" in done.world
        assert np.degrees(e.rms("pitch")) < 1e-3, done.world
        pitch = panel.plots.pitch.data
        assert len(pitch[0]) > 100 and pitch[0][0] == np.float32(e.time[0])
        assert np.isclose(pitch[1][0], np.degrees(e.pitch[0]), atol=1e-4)
        assert panel.plots.contact.data[1].max() == 1.0 and panel.plots.contact.data[1].min() == 0.0
        page.evaluate(
            "() => [...document.querySelectorAll('.uplot')].find(u => u.innerText.includes('pitch error'))"
            ".scrollIntoView()"
        )
        _shot(page, tmp_path, "logreplay.png")
        # Re-anchored, ticked in the page: the same hops in windows, each from the log's state.
        _input(page, panel.reanchor).check()
        assert wait_until(lambda: panel.reanchor.value, timeout=30)
        _load(page, dashboard, str(path))
        windows = panel.last
        assert windows.every == 0.3 and windows.shown == 2 and len(windows.parts) > 2 * len(done.parts)
        page.wait_for_function(
            "() => [...document.querySelectorAll('.hd-record')].some(e => e.innerText.includes('re-anchored every'))"
        )
        _shot(page, tmp_path, "logreplay_reanchored.png")
        # The legs held to the log's angles too, ticked in the page: said in the summary.
        _input(page, panel.servo).check()
        assert wait_until(lambda: panel.servo.value, timeout=30)
        _load(page, dashboard, str(path))
        assert panel.last.servo and panel.last.every == 0.3
        assert np.degrees(panel.last.errors.rms("pitch")) < 1e-3  # the log's own robot: nothing to hold
        page.wait_for_function(
            "() => [...document.querySelectorAll('.hd-record')].some(e => e.innerText.includes('legs held'))"
        )
        _shot(page, tmp_path, "logreplay_held.png")
        page.get_by_role("button", name="Stop log replay").click()
        assert wait_until(lambda: not panel.logged_ghost.playing and not panel.simulated_ghost.playing, timeout=30)
        assert panel.watched() is None and not panel.watch.value
        assert wait_until(lambda: panel.grounded is None, timeout=30), "the log's ground stayed"
        assert not panel.ground.tiles and all(tile.visible for tile in dashboard.terrain.tiles.values())
    finally:
        page.close()
