"""End to end in a real headless Chromium: the repeatable test set in the Disturb tab fills the hop
table's response rows. Skips without /usr/bin/chromium, except under CI=true.
"""

from __future__ import annotations

import time

from hopper.app.dashboard.server import Dashboard
from net import wait_until
from pages import close_notices
from test_dashboard_e2e import PAGE_LOAD_MS
from test_workbench_e2e import _type

from hopper.schedule import KickSchedule

# The response table is one HTML element a part (header, each row, the mean): read them all, in order.
RESPONSE_JS = "() => [...document.querySelectorAll('table.hd-resp')].map(t => t.innerText).join('\\n')"
STATUS_JS = "() => document.body.innerText"


def _rows(text: str) -> dict[str, list[str]]:
    """The response table's rows by hop number: their cells as shown."""
    rows = {}
    for line in text.splitlines():
        cells = line.split("\t")
        if cells and cells[0].strip().isdigit():
            rows[cells[0].strip()] = [c.strip() for c in cells[1:]]
    return rows


def test_a_schedule_set_in_the_page_kicks_every_second_flight_and_fills_the_response_rows(
    browser,  # noqa: F811
    dashboard: Dashboard,
    tmp_path,
):
    start = time.monotonic()

    def elapsed() -> str:
        return f"{time.monotonic() - start:.1f} s"

    dashboard.set_speed(4.0)  # the hops come sooner; the schedule itself is set in the page
    dashboard.set_paused(True)  # until the schedule is set: a still scene leaves the page the CPU to type
    page = browser.new_page(viewport={"width": 1440, "height": 900})
    page.set_default_timeout(60_000)  # a bound for a loaded machine, not a pace
    try:
        page.goto(dashboard.url)
        page.get_by_text("Kp", exact=True).first.wait_for(timeout=PAGE_LOAD_MS)
        assert wait_until(lambda: len(dashboard.server.get_clients()) == 1, timeout=30)
        page.wait_for_function(f"() => ({RESPONSE_JS})().includes('no hops yet')", timeout=30_000)

        page.get_by_text("Disturb", exact=True).first.click()
        controls = dashboard.layout.disturbances.schedule
        _type(page, controls.magnitude, "0.5")
        _type(page, controls.every, "2")  # the delay stays at its default, 150 ms
        page.get_by_role("button", name="Start", exact=True).click()
        expected = KickSchedule("pitch_kick", 0.5, 0.15, 2)
        assert wait_until(lambda: dashboard.sim.schedule == expected, timeout=30), dashboard.sim.schedule
        status = "Schedule on: pitch kick +0.5 N m s, 150 ms after the liftoff of hops 2, 4, 6, …"
        page.wait_for_function(f"() => ({STATUS_JS})().includes('{status}')", timeout=30_000)

        dashboard.set_paused(False)
        # A kicked flight: its row shows the kick's delay and the metrics the core computed.
        assert wait_until(lambda: any(h.kicked for h in dashboard.sim.hops), timeout=120), dashboard.sim.hops
        page.wait_for_function(f"() => ({RESPONSE_JS})().includes('\\t150\\t')", timeout=30_000)
        rows = _rows(page.evaluate(RESPONSE_JS))
        hops = list(dashboard.sim.hops)  # the table shows the newest hops: compare one still on it
        hop = next(h for h in reversed(hops) if h.kicked and str(h.index) in rows)
        cells = rows[str(hop.index)]
        assert cells[0] == "150" and hop.index % 2 == 0  # the kick, 150 ms after this flight's liftoff
        before = rows.get(str(hop.index - 1))
        assert before is None or before[0] == "–"  # the odd hop in between: from liftoff
        assert cells[1] == f"{hop.response_peak_deg:.1f}" and hop.response_peak_deg > 0.5  # unkicked: ~0.23
        assert cells[2] == f"{hop.overshoot_deg:.2f}"
        assert cells[3] == (f"{hop.settling_time_s:.2f}" if hop.settled else f">{hop.settling_time_s:.2f}")
        assert cells[4] == f"{hop.peak_wheel_torque_nm:.1f}" and cells[5] == f"{hop.peak_momentum_pct:.0f}"
        assert cells[6] == f"{hop.landing_error_deg:+.2f}"
        close_notices(page)  # viser's software-WebGL notice
        # A script, not the locator's scroll: that waits for the table to be still, and it is live.
        page.evaluate("() => [...document.querySelectorAll('table.hd-resp')].pop().scrollIntoView({block: 'end'})")
        page.screenshot(path=str(tmp_path / "repeat-hop-table.png"))  # 1440x900, to look at
        print(f"\nresponse row of hop {hop.index}: {cells} ({elapsed()})")

        # Clear: the status says so and later flights go unkicked.
        page.get_by_role("button", name="Clear", exact=True).click()
        assert wait_until(lambda: dashboard.sim.schedule is None, timeout=30)
        page.wait_for_function(f"() => ({STATUS_JS})().includes('Schedule off')", timeout=30_000)
    finally:
        page.close()
