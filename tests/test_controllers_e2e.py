"""In a real headless Chromium: the Gains tab's selector switches to the README's example controller
(a file outside the package, offered with --controller-choice), shows its params and the analysis'
verdict, and a controller that fails in flight is a notice while the PID flies on.
Skips without /usr/bin/chromium, except under CI=true. Screenshots go to tmp_path (and $HOPPER_SHOTS)."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest
from hopper.app.dashboard.feedback import format_number
from hopper.app.dashboard.server import Dashboard
from net import wait_until
from pages import pick, wait_for_ab_table
from test_controllers import readme_example
from test_dashboard_e2e import PAGE_LOAD_MS
from test_dashboard_inputs_e2e import box, notice, open_page, type_into
from test_dashboard_inputs_e2e import start as start_paused
from test_replay_e2e import NOTES_JS, WORK_VIEWPORT, _shot

from hopper.commands import SetControllerParam
from hopper.events import EventKind

LOG_JS = "() => [...document.querySelectorAll('table.hd-log')].map(t => t.textContent).join(' | ')"
FAILING = '''
import math
class FailsInFlight:
    """Flies its first 200 calls (the pre-run check's 35 are undone), then answers NaN."""
    def __init__(self):
        self.calls = 0
    def __call__(self, obs):
        self.calls += 1
        return math.nan if self.calls > 200 else 400.0 * obs.pitch + 30.0 * obs.rate
'''


def _open(browser, dashboard: Dashboard):  # noqa: F811
    page = browser.new_page(viewport=WORK_VIEWPORT)
    page.set_default_timeout(60_000)  # a bound for a loaded machine, not a pace
    page.goto(dashboard.url)
    page.get_by_text("Controller", exact=True).first.wait_for(timeout=PAGE_LOAD_MS)
    assert wait_until(lambda: len(dashboard.server.get_clients()) == 1, timeout=30)
    return page


def _pick(page, dashboard: Dashboard, option: str) -> None:
    """Open the Controller selector and click `option`, as a person does."""
    pick(page, dashboard.layout.controller.choice._impl.uuid, option)


def test_the_selector_switches_to_a_users_controller_and_back(browser, start, tmp_path: Path) -> None:  # noqa: F811
    user = tmp_path / "my_controller.py"
    user.write_text(readme_example())
    dashboard = start(controller_choice=(f"{user}:LandLevel",), speed=2.0)
    spec = f"{user}:LandLevel"
    page = _open(browser, dashboard)
    try:
        page.get_by_role("tab", name="Gains").click()
        _pick(page, dashboard, spec)
        assert wait_until(lambda: dashboard.sim.config.controller == spec, timeout=60), dashboard.sim.config
        page.get_by_text("flying LandLevel").wait_for()
        page.get_by_text("boost", exact=True).wait_for()  # its params, as sliders
        page.get_by_text("no loop analysis: LandLevel is not a linear law").wait_for()
        law = dashboard.sim.law
        assert wait_until(lambda: law.calls > 500, timeout=120), "it never flew"
        page.wait_for_function(f"() => ({LOG_JS})().includes('controller {spec} (LandLevel')")
        _shot(page, tmp_path, "controller-user.png")
        assert wait_until(lambda: (f := dashboard.history.last_flight) is not None and f.controller == spec, 120)
        dashboard.layout.simulation.set_paused(True)  # the last flight stays the user's; commands still apply
        _pick(page, dashboard, "lqr")
        assert wait_until(lambda: dashboard.sim.config.controller == "lqr", timeout=60)
        page.get_by_text("LQR as state feedback").first.wait_for()
        _shot(page, tmp_path, "controller-lqr.png")
        # Re-fly: the last flight (the user's controller's) flown again by the LQR, both in the A/B table.
        page.get_by_role("tab", name="Replay").click()
        page.get_by_role("button", name="Re-fly last flight").click()
        assert wait_until(lambda: dashboard.layout.replay.last is not None, timeout=60)
        c = dashboard.layout.replay.last
        assert c.recorded.controller == spec and c.after.controller == "lqr" and c.before_identical
        wait_for_ab_table(page, "my_controller.py:LandLevel", "lqr", timeout_ms=60_000)
        _shot(page, tmp_path, "controller-refly.png")
        dashboard.layout.simulation.set_paused(False)
        page.get_by_role("tab", name="Gains").click()
        assert not page.get_by_text("Kp", exact=True).first.is_visible()  # the PID's sliders wait hidden
        _pick(page, dashboard, "pid")
        assert wait_until(lambda: dashboard.sim.config.controller == "pid", timeout=60)
        page.get_by_text("Kp", exact=True).first.wait_for(state="visible")
        # Not asserted: the robot never fell. In 1 run of about 5 it fell at the session's first hop
        # (pitch past 60 deg in a bounce after the touchdown), the cause not found: 136 switches at
        # every moment of that hop, headless, never made it fall. The events say what flew.
        events = [f"{e.run} {e.time:.2f} {e.describe()}" for e in dashboard.sim.events if e.kind.value != "apex"]
        print("\n".join(events))
        assert dashboard.sim.controller_fault is None, events
    finally:
        page.close()


def test_a_controller_failing_in_flight_is_a_notice_and_the_pid_flies_on(browser, start, tmp_path: Path) -> None:  # noqa: F811
    bad = tmp_path / "bad.py"
    bad.write_text(FAILING)
    dashboard = start(controller_choice=(f"{bad}:FailsInFlight",), speed=2.0)
    page = _open(browser, dashboard)
    try:
        page.get_by_role("tab", name="Gains").click()
        _pick(page, dashboard, f"{bad}:FailsInFlight")
        assert wait_until(lambda: dashboard.sim.controller_fault is not None, timeout=120), "it never failed"
        page.wait_for_function(f"() => ({NOTES_JS})().includes('FailsInFlight returned nan N m')")
        assert wait_until(lambda: dashboard.layout.controller.choice.value == "pid", timeout=30)
        hops = len(dashboard.sim.hops)
        assert wait_until(lambda: len(dashboard.sim.hops) > hops, timeout=120), "the PID did not fly on"
        kinds = [e.kind for e in dashboard.sim.events]
        assert EventKind.CONTROLLER_FAILED in kinds and not dashboard.sim.fallen
        _shot(page, tmp_path, "controller-failed.png")
    finally:
        page.close()


def _param_changes(dashboard: Dashboard) -> list[dict[str, float]]:
    """The MPC's param values at each ControllerChanged since it began to fly."""
    flown = [e.payload for e in list(dashboard.sim.events) if e.kind == EventKind.CONTROLLER]
    return [dict(c.params) for c in flown if c.spec == "mpc"][1:]


def test_a_controllers_param_typed_applies_once_clamped_with_its_range_and_follows_its_slider(
    browser,  # noqa: F811
    tmp_path: Path,
    caplog: pytest.LogCaptureFixture,
) -> None:
    """The MPC's params had viser's slider boxes: 1.25 typed applied 1, 1.2 and 1.25, each rebuilding
    the controller, and 99 gave two raw 'SetControllerParam failed: ControllerError' notices with
    tracebacks. Now a typed box per param, as for the gains; slider and box show the value in use."""
    dashboard = start_paused(tmp_path)
    page = open_page(browser, dashboard, scene=False)
    try:
        _pick(page, dashboard, "mpc")
        assert wait_until(lambda: "horizon" in dashboard.layout.controller.entries, timeout=60), "no MPC boxes"
        panel = dashboard.layout.controller
        growth, horizon = (box(page, panel.entries[name].handle) for name in ("step_growth", "horizon"))
        assert box(page, panel.sliders["horizon"]).is_hidden(), "the slider's own number box must not be offered"
        assert (growth.input_value(), horizon.input_value()) == ("1.03", "1.25")

        type_into(page, growth, "1.25")  # once: not 1, then 1.2, then 1.25
        assert wait_until(lambda: dashboard.sim.law.values["step_growth"] == 1.25), dashboard.sim.law.values
        assert [c["step_growth"] for c in _param_changes(dashboard)] == [1.25]
        assert panel.sliders["step_growth"].value == 1.25 and growth.input_value() == "1.25"

        type_into(page, horizon, "99")
        notice(page, "horizon 99 x nominal flight is outside [0.1, 3] x nominal flight; clamped to 3 x nominal flight")
        assert wait_until(lambda: dashboard.sim.law.values["horizon"] == 3.0), dashboard.sim.law.values
        assert wait_until(lambda: horizon.input_value() == "3"), horizon.input_value()
        type_into(page, horizon, "abc")
        notice(page, "horizon: 'abc' is not a number; kept 3 x nominal flight")
        assert wait_until(lambda: horizon.input_value() == "3"), horizon.input_value()
        assert [c["horizon"] for c in _param_changes(dashboard)] == [1.25, 3.0], "one change a typed value"
        assert page.locator(".mantine-Notification-root", has_text="Command failed").count() == 0
        assert not [r for r in caplog.records if r.exc_info or r.levelno >= logging.ERROR], caplog.text

        # The slider still drags, and the box follows it.
        track = page.locator(f'[id="{panel.sliders["horizon"]._impl.uuid}"]')
        area = track.bounding_box()
        page.mouse.click(area["x"] + 0.25 * area["width"], area["y"] + area["height"] / 2)
        assert wait_until(lambda: dashboard.sim.law.values["horizon"] < 1.5), dashboard.sim.law.values
        dragged = dashboard.sim.law.values["horizon"]
        assert wait_until(lambda: horizon.input_value() == format_number(dragged)), (horizon.input_value(), dragged)

        # A change the simulation makes (not from this page) reaches both.
        dashboard.sim.submit(SetControllerParam("horizon", 2.0))
        assert wait_until(lambda: horizon.input_value() == "2"), horizon.input_value()
        thumb = page.locator(f'[id="{panel.sliders["horizon"]._impl.uuid}"] [role="slider"]')
        assert wait_until(lambda: thumb.get_attribute("aria-valuenow") == "2"), thumb.get_attribute("aria-valuenow")
        _shot(page, tmp_path, "controller-params.png")
    finally:
        page.close()
        dashboard.stop()
