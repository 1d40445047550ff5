"""End to end, the tuning workbench in a real headless Chromium: the loop analysis follows a gain
change, and pole placement writes gains the controller then runs (and the event log says so).
Skips without /usr/bin/chromium, except under CI=true.
"""

from __future__ import annotations

import re

from hopper.app.dashboard.server import Dashboard
from net import wait_until
from test_dashboard_e2e import open_workbench

from hopper.analysis.loop import analyse

ANALYSIS_JS = "() => document.querySelector('.hd-analysis') ? document.querySelector('.hd-analysis').innerText : ''"
LOG_JS = "() => [...document.querySelectorAll('table.hd-log')].map(t => t.textContent).join(' | ')"


def _pair(text: str) -> tuple[float, float]:
    match = re.search(r"ωn ([\d.]+) rad/s · ζ ([\d.]+)", text.replace("\n", ""))
    assert match, f"no dominant pair in the analysis: {text!r}"
    return float(match.group(1)), float(match.group(2))


def _box(page, entry):
    """The input of a NumberEntry's text box (viser labels it by the handle's id)."""
    label = page.locator(f'label[for="{entry.handle._impl.uuid}"]')
    return label.locator("xpath=ancestor::div[contains(@style,'padding-inline')][1]").locator("input")


def _type(page, entry, text: str) -> None:
    # At once, not key by key: on a loaded machine a pause after "0." would let the box apply it
    # (clamped) before the 5 arrives. test_dashboard_e2e types key by key.
    box = _box(page, entry)
    box.fill(text)
    box.press("Tab")
    assert wait_until(lambda: entry.value == float(text), timeout=30), (entry.name, entry.value, text)


def test_analysis_follows_the_gains_and_pole_placement_drives_the_controller(browser, dashboard: Dashboard):  # noqa: F811
    dashboard.layout.simulation.set_paused(True)
    page = open_workbench(browser, dashboard)
    try:
        page.wait_for_function(f"() => ({ANALYSIS_JS})().includes('rad/s · ζ')", timeout=30_000)
        before = _pair(page.evaluate(ANALYSIS_JS))
        plant = dashboard.layout.analysis.plant
        expected = analyse(plant, dashboard.sim.gains)
        assert before == (round(expected.wn, 1), round(expected.zeta, 2))

        # A gain typed in the Kp box changes the analysis shown.
        layout = dashboard.layout
        _type(page, layout.gains.entries["kp"], "900")
        assert wait_until(lambda: dashboard.sim.gains.kp == 900.0, timeout=30)
        page.wait_for_function(f"() => ({ANALYSIS_JS})().includes('Kp 900')", timeout=30_000)
        after = _pair(page.evaluate(ANALYSIS_JS))
        assert after != before and after[0] > before[0], (before, after)  # a stiffer loop is faster

        # Pole placement: the designed gains reach the controller and the log says who chose them.
        page.get_by_text("Design gains").first.click()
        _type(page, layout.analysis.wn, "22")
        _type(page, layout.analysis.zeta, "0.5")
        page.get_by_role("button", name="Place poles").click()
        assert wait_until(lambda: dashboard.sim.gains.kp != 900.0, timeout=30), dashboard.sim.gains
        placed = analyse(plant, dashboard.sim.gains)
        assert abs(placed.wn - 22.0) < 0.3 and abs(placed.zeta - 0.5) < 0.01, placed
        page.wait_for_function(f"() => ({LOG_JS})().includes('pole placement (wn 22 rad/s, zeta 0.5)')", timeout=10_000)
        page.wait_for_function(f"() => ({ANALYSIS_JS})().includes('ωn 22.0 rad/s · ζ 0.50')", timeout=30_000)
        # The Kp box shows the designed gain.
        kp = dashboard.sim.gains.kp
        assert wait_until(lambda: abs(float(_box(page, layout.gains.entries["kp"]).input_value()) - kp) < 1e-3 * kp)
    finally:
        page.close()
