"""Two real Chromium pages on one dashboard: the operator drives, the viewer's controls are read-only
(and a viewer who re-enables a box by hand still changes nothing), then control is handed over.

Skips without /usr/bin/chromium, except under CI=true, where a missing browser is a failure.
"""

from __future__ import annotations

from pathlib import Path

import viser
from hopper.app.dashboard import assets
from hopper.app.dashboard.access import page_url
from hopper.app.dashboard.server import Dashboard
from net import free_port, wait_until
from pages import close_notices
from test_controllers_e2e import _pick
from test_dashboard_e2e import MIN_CANVAS_COLOURS, PAGE_LOAD_MS, distinct_colours
from test_dashboard_inputs_e2e import HIDE_SCENE, box, notice, start, type_into

from hopper.events import EventKind

VIEWPORT = {"width": 1280, "height": 800}


# Two software-rendered WebGL pages in one browser on a busy machine leave little time for input:
# each page's 3D scene is hidden from the start (shown again for screenshots).
HIDE_FROM_START = (
    "document.addEventListener('DOMContentLoaded', () => { const s = document.createElement('style');"
    f" s.id = 'hide-scene'; s.textContent = {HIDE_SCENE!r}; document.head.append(s); }});"
)


def open_page(browser, d: Dashboard, clients: int):  # noqa: F811
    """A page that has the dashboard and its own Control widgets."""
    page = browser.new_page(viewport=VIEWPORT)
    page.add_init_script(HIDE_FROM_START)
    page.goto(d.url, timeout=PAGE_LOAD_MS)
    page.get_by_text("Kp", exact=True).first.wait_for(timeout=PAGE_LOAD_MS)
    assert wait_until(lambda: len(d.roles.seated) == clients, timeout=60), "the page was never seated"
    page.locator(".hd-role").wait_for(timeout=60_000)
    close_notices(page)  # viser's software-WebGL notice
    return page


def slider_box(page, handle):
    """The number box viser draws beside the slider `handle` (right after the slider's root)."""
    return page.locator(f'[id="{handle._impl.uuid}"] + .mantine-NumberInput-root input')


def greyed(locator) -> bool:
    """Whether the element looks read-only: faded, and clicks pass it by."""
    return locator.evaluate(
        "e => { const s = getComputedStyle(e); return s.opacity < 1 && s.pointerEvents == 'none'; }"
    )


def controls(page, d: Dashboard) -> dict[str, bool]:
    """Whether each of a few shared controls is disabled on this page."""
    gains = d.layout.gains
    return {
        "Speed box": box(page, d.layout.simulation.entry.handle).is_disabled(),
        "Kp box": box(page, gains.entries["kp"].handle).is_disabled(),
        "Kd box": box(page, gains.entries["kd"].handle).is_disabled(),
        "Wheel on": page.locator(f'[id="{gains.wheel._impl.uuid}"]').is_disabled(),
        "Kp slider": page.locator(f'[id="{gains.kp._impl.uuid}"] .mantine-Slider-track[data-disabled="true"]').count()
        == 1,
        "Reset robot": page.get_by_role("button", name="Reset robot").is_disabled(),
    }


def screenshot(page, path: Path) -> None:
    """The page as its user sees the panels (the 3D scene stays hidden: two software-rendered
    scenes on a loaded machine can take minutes to draw a frame, and the test is about the panels)."""
    page.bring_to_front()
    page.screenshot(path=str(path), timeout=60_000)
    assert distinct_colours(path) >= MIN_CANVAS_COLOURS, f"{path} looks blank"
    print(f"\nscreenshot: {path}")


def test_a_viewer_changes_nothing_until_control_is_handed_over(browser, tmp_path: Path) -> None:  # noqa: F811
    d = start(tmp_path)
    first = second = None
    try:
        first = open_page(browser, d, 1)
        first.get_by_text("You operate").wait_for(timeout=10_000)
        second = open_page(browser, d, 2)
        operator, viewer = d.roles.seated
        assert d.roles.operator == operator
        second.get_by_text("Viewing").wait_for(timeout=10_000)
        second.get_by_text(f"{d.roles.name_of(operator)} operates").wait_for(timeout=10_000)

        # The viewer's controls are greyed; the operator's are not.
        assert wait_until(lambda: all(controls(second, d).values()), timeout=10), controls(second, d)
        assert not any(controls(first, d).values()), controls(first, d)
        screenshot(first, tmp_path / "operator.png")
        screenshot(second, tmp_path / "viewer.png")

        # A viewer who re-enables the Kp box by hand and types: the server drops it and says so.
        kp_box = box(second, d.layout.gains.entries["kp"].handle)
        kp_box.evaluate("input => input.removeAttribute('disabled')")
        refused = d.roles.refused
        type_into(second, kp_box, "700")
        assert wait_until(lambda: d.roles.refused > refused), "the viewer's typing never reached the server"
        notice(second, "Read-only")
        assert wait_until(lambda: kp_box.input_value() == "450"), "the viewer's box does not show the gain in use"
        assert d.sim.gains.kp == 450.0 and not [e for e in d.sim.events if e.kind == EventKind.GAINS]

        # The viewer asks; the operator hands over.
        second.get_by_role("button", name="Ask for control").click()
        notice(first, "asks for control")
        first.get_by_role("button", name=f"Hand over to {d.roles.name_of(viewer)}").click()
        assert wait_until(lambda: d.roles.operator == viewer)
        second.get_by_text("You operate").wait_for(timeout=10_000)
        first.get_by_text("Viewing").wait_for(timeout=10_000)

        # Now the second page drives, and the first page's controls are read-only.
        assert wait_until(lambda: not any(controls(second, d).values()), timeout=10), controls(second, d)
        assert wait_until(lambda: all(controls(first, d).values()), timeout=10), controls(first, d)
        type_into(second, box(second, d.layout.gains.entries["kp"].handle), "600")
        assert wait_until(lambda: d.sim.gains.kp == 600.0), "the new operator's gain did not apply"
        first.locator(".hd-log", has_text="handed over by").wait_for(timeout=10_000)
        assert [e.payload.gains.kp for e in d.sim.events if e.kind == EventKind.GAINS] == [600.0]  # type: ignore[union-attr]
        screenshot(second, tmp_path / "operator-after.png")
        screenshot(first, tmp_path / "viewer-after.png")

        # Controls built after the viewer came (a controller's params, as the operator picks it) reach it read-only.
        _pick(second, d, "lqr")
        assert wait_until(lambda: "pitch_tol" in d.layout.controller.entries, timeout=60), "no LQR params"
        late = d.layout.controller.entries["pitch_tol"].handle
        box(first, late).wait_for(state="attached", timeout=30_000)
        assert box(first, late).is_disabled() and not box(second, late).is_disabled()
    finally:
        for page in (first, second):
            if page is not None:
                page.close()
        d.stop()


def test_off_loopback_the_printed_url_opens_the_dashboard_and_the_bare_address_gets_nothing(
    browser,  # noqa: F811
    tmp_path: Path,
) -> None:
    """Bound to 0.0.0.0 with a token, opened over 127.0.0.1 only: the URL's `websocket` parameter
    carries the token in a real browser; without it the page stays empty and is refused."""
    d = start(tmp_path, host="0.0.0.0", token="auto")
    with_token = without = None
    try:
        url = page_url("127.0.0.1", d.server.get_port(), d.config.token)
        with_token = browser.new_page(viewport=VIEWPORT)
        with_token.add_init_script(HIDE_FROM_START)
        with_token.goto(url, timeout=PAGE_LOAD_MS)
        with_token.get_by_text("Kp", exact=True).first.wait_for(timeout=PAGE_LOAD_MS)
        assert wait_until(lambda: d.roles.operator is not None, timeout=60), "the token holder does not operate"

        without = browser.new_page(viewport=VIEWPORT)
        refused = d.gatekeeper.refused
        without.goto(f"http://127.0.0.1:{d.server.get_port()}/", timeout=PAGE_LOAD_MS)
        assert wait_until(lambda: d.gatekeeper.refused > refused, timeout=60), "the bare page was never refused"
        assert without.get_by_text("Kp", exact=True).count() == 0 and len(d.roles.seated) == 1
    finally:
        for page in (with_token, without):
            if page is not None:
                page.close()
        d.stop()


def test_a_disabled_sliders_own_number_box_is_greyed(browser, tmp_path: Path) -> None:  # noqa: F811
    """viser draws a slider's number box without the slider's `disabled`: a viewer's box looked live.
    The dashboard's stylesheet greys it and keeps clicks out while the slider is disabled, whether
    from the start or later (as the roles grey a viewer's controls), and no longer once enabled."""
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    page = None
    try:
        server.gui.add_html(f"<style>{assets.stylesheet()}</style>")
        live = server.gui.add_slider("Live", 0.0, 10.0, 1.0, 5.0)
        off = server.gui.add_slider("Off", 0.0, 10.0, 1.0, 5.0, disabled=True)
        page = browser.new_page(viewport=VIEWPORT)
        page.goto(f"http://127.0.0.1:{server.get_port()}", timeout=PAGE_LOAD_MS)
        slider_box(page, off).wait_for(timeout=PAGE_LOAD_MS)
        assert greyed(slider_box(page, off)) and not greyed(slider_box(page, live))
        live.disabled, off.disabled = True, False
        page.wait_for_function(
            "u => document.querySelector(`[id='${u}'] .mantine-Slider-track[data-disabled='true']`)",
            arg=live._impl.uuid,
        )
        page.wait_for_function(
            "u => !document.querySelector(`[id='${u}'] .mantine-Slider-track[data-disabled='true']`)",
            arg=off._impl.uuid,
        )
        assert greyed(slider_box(page, live)) and not greyed(slider_box(page, off))
        screenshot(page, tmp_path / "slider-boxes.png")
    finally:
        if page is not None:
            page.close()
        server.stop()
