"""End to end in a real headless Chromium: the World tab's Mode puts the robot on the test stand, the
Disturb tab's kick and the Reference ° box act on it, a bad reference is a notification, a chirp is
injected live and its Bode plot drawn, and Hopping gives the robot back. Skips without
/usr/bin/chromium, except under CI=true.
"""

from __future__ import annotations

import math
from pathlib import Path

from hopper.app.dashboard.server import Dashboard
from net import wait_until
from pages import close_notices, pick
from test_dashboard_e2e import PAGE_LOAD_MS
from test_dashboard_inputs_e2e import box, notice, type_into
from test_replay_e2e import WORK_VIEWPORT

from hopper.stand import StandSimulation


def _mode(page, dashboard: Dashboard, option: str) -> None:
    """Open the Mode selector and click `option`, as a person does."""
    assert dashboard.layout.stand is not None
    pick(page, dashboard.layout.stand.mode._impl.uuid, option)


def _inject_a_chirp(page, dashboard: Dashboard, sim: StandSimulation, tmp_path: Path) -> None:
    """The Chirp injection folder: a zero length, or one too short for its band, is refused; a 3 s
    chirp is played and drawn."""
    inject = dashboard.layout.stand.inject
    page.get_by_text("Chirp injection", exact=True).click()
    length = box(page, inject.length.handle)
    type_into(page, length, "0")  # the box itself refuses it
    notice(page, "Length 0 s is outside (0, 600] s; kept 10 s")
    type_into(page, length, "1")  # a length the box takes, too short for the band's 1 Hz: the chirp is refused
    # The click counts what the server has been sent: wait for the box's text to get there first.
    assert wait_until(lambda: inject.length.value == 1.0, timeout=10), inject.length.handle.value
    page.get_by_role("button", name="Inject", exact=True).click()
    notice(page, "under 2 cycles of f_min 1 Hz")
    assert sim.injection is None
    type_into(page, box(page, inject.f_max.handle), "200")
    type_into(page, length, "3")
    page.get_by_role("button", name="Inject", exact=True).click()
    assert wait_until(lambda: sim.injection is not None and not sim.injection.playing, timeout=60)
    assert sim.injection.stopped == "" and sim.injection.played == 3000
    assert wait_until(lambda: inject.bode.visible, timeout=60), "no Bode plot drawn"
    notice(page, "Injection measured")
    image = page.get_by_role("img").last
    image.scroll_into_view_if_needed()
    image.wait_for(state="visible")
    page.screenshot(path=str(tmp_path / "injected.png"))


def test_the_world_tab_puts_the_robot_on_the_stand_and_back(browser, start, tmp_path: Path) -> None:  # noqa: F811
    dashboard = start()
    page = browser.new_page(viewport=WORK_VIEWPORT)
    page.set_default_timeout(60_000)  # a bound for a loaded machine, not a pace
    try:
        page.goto(dashboard.url)
        page.get_by_text("Kp", exact=True).first.wait_for(timeout=PAGE_LOAD_MS)
        assert wait_until(lambda: len(dashboard.server.get_clients()) == 1, timeout=30)
        close_notices(page)
        page.get_by_role("tab", name="World").click()
        _mode(page, dashboard, "Stand, legs locked")
        notice(page, "On the stand, legs locked")
        assert wait_until(lambda: isinstance(dashboard.sim, StandSimulation) and dashboard.sim.time > 0.5)
        sim = dashboard.sim

        reference = box(page, dashboard.layout.stand.reference.handle)
        type_into(page, reference, "12")
        assert wait_until(lambda: abs(sim.state().pitch - math.radians(12.0)) < math.radians(0.5))
        type_into(page, reference, "lots")
        notice(page, "Reference")
        assert wait_until(lambda: reference.input_value() == "12"), reference.input_value()

        page.get_by_role("tab", name="Disturb").click()
        page.get_by_role("button", name="Pitch kick").click()
        assert wait_until(lambda: any(e.kind == "disturbance" for e in list(sim.events))), "no kick on the stand"
        assert wait_until(lambda: abs(sim.state().pitch - math.radians(12.0)) < math.radians(0.5))
        page.get_by_role("tab", name="World").click()
        page.screenshot(path=str(tmp_path / "stand.png"))

        _inject_a_chirp(page, dashboard, sim, tmp_path)

        _mode(page, dashboard, "Hopping")
        assert wait_until(lambda: dashboard.mode == "hop" and len(dashboard.sim.hops) > 0, timeout=60)
    finally:
        page.close()
