"""Typing, keys and charts in a real headless Chromium: what reaches the controller and what the page shows.

Skips without /usr/bin/chromium, except under CI=true, where a missing browser is a failure.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from hopper.app.dashboard.config import DashboardConfig
from hopper.app.dashboard.plots import LIMIT_COLOR
from hopper.app.dashboard.server import Dashboard
from net import free_port, wait_until
from pages import BROWSER_LIGHTING, close_notices
from PIL import Image
from test_dashboard_e2e import LARGEST_CANVAS_JS, PAGE_LOAD_MS

from hopper.config import Gains

VIEWPORT = {"width": 1440, "height": 900}


def start(tmp_path: Path, **config: object) -> Dashboard:
    config.setdefault("lighting", BROWSER_LIGHTING)
    d = Dashboard(DashboardConfig(port=free_port(), sessions_dir=tmp_path / "sessions", **config), verbose=False)
    d.start()
    # Paused: commands still apply (between frames), and a software-rendered page stays responsive.
    d.layout.simulation.set_paused(True)
    return d


# Software WebGL frames here stall the page's key handling for up to a second at times, so keys
# typed in one go reach the server as if typed slowly; these tests are about the inputs, so the 3D
# scene is hidden while they type (the charts, plain canvases, stay).
HIDE_SCENE = ":not(.u-wrap) > canvas { display: none !important; }"


def open_page(browser, dashboard: Dashboard, *, scene: bool = True):  # noqa: F811
    page = browser.new_page(viewport=VIEWPORT)
    page.goto(dashboard.url)
    page.get_by_text("Kp", exact=True).first.wait_for(timeout=PAGE_LOAD_MS)
    assert wait_until(lambda: len(dashboard.server.get_clients()) == 1, timeout=30)
    close_notices(page)  # viser's software-WebGL notice
    if not scene:
        page.evaluate(
            "css => { const s = document.createElement('style'); s.id = 'hide-scene'; s.textContent = css;"
            " document.head.append(s); }",
            HIDE_SCENE,
        )
    return page


def show_scene(page) -> None:
    """Undo HIDE_SCENE and wait until the 3D scene is drawn again (for a screenshot)."""
    page.evaluate("() => document.getElementById('hide-scene').remove()")
    scene = page.locator("canvas").nth(page.evaluate(LARGEST_CANVAS_JS))
    assert wait_until(lambda: len(page_colours(scene)) > 500, timeout=60), "the 3D scene was not drawn"


def page_colours(locator) -> set[tuple[int, int, int]]:
    image = Image.open(io.BytesIO(locator.screenshot())).convert("RGB")
    return {c for _, c in image.getcolors(maxcolors=image.width * image.height)}


@pytest.fixture
def dashboard(tmp_path: Path):
    d = start(tmp_path)
    yield d
    d.stop()


@pytest.fixture
def page(browser, dashboard: Dashboard):  # noqa: F811
    p = open_page(browser, dashboard, scene=False)
    yield p
    p.close()


def box(page, handle):
    """The <input> of the GUI element `handle`: its label points at its id."""
    label = page.locator(f'label[for="{handle._impl.uuid}"]')
    return label.locator("xpath=ancestor::div[contains(@style,'padding-inline')][1]").locator("input").first


def type_into(page, locator, text: str, *, key_by_key: bool = True) -> None:
    """Select what the box holds and type over it, key by key as a person does, or in one input
    event (a paste) where the keys' timing is not what a step tests: a box applies a finished number
    after QUIET_S without a keystroke, and a loaded page has delivered two keys 0.5 s apart (CI:
    `1e9` applied `1` first)."""
    locator.click()
    page.keyboard.press("Control+A")
    if key_by_key:
        page.keyboard.type(text)
    else:
        page.keyboard.insert_text(text)


def notice(page, text: str):
    """Wait for a notification that contains `text`; returns it."""
    found = page.locator(".mantine-Notification-root", has_text=text)
    found.first.wait_for(timeout=10_000)
    return found


def gain_changes(dashboard: Dashboard) -> list[tuple[float, float, float]]:
    return [
        (e.payload.gains.kp, e.payload.gains.ki, e.payload.gains.kd)
        for e in list(dashboard.sim.events)
        if e.kind == "gains"
    ]


def test_typed_gains_apply_once_are_clamped_or_refused_and_the_box_shows_what_runs(
    page, dashboard: Dashboard, tmp_path: Path
) -> None:
    gains = dashboard.layout.gains
    kp, ki, kd = (box(page, gains.entries[name].handle) for name in ("kp", "ki", "kd"))
    assert box(page, gains.kp).is_hidden(), "the slider's own number box must not be offered"
    assert (kp.input_value(), ki.input_value(), kd.input_value()) == ("450", "50", "30")

    # Typing 800 applies 800, once: not 8, then 80, then 800.
    type_into(page, kp, "800")
    assert wait_until(lambda: dashboard.sim.gains.kp == 800.0), dashboard.sim.gains
    assert gain_changes(dashboard) == [(800.0, 50.0, 30.0)]
    assert kp.input_value() == "800"

    # 1e9 is a number: clamped to the range, with its units. (Pasted: the step is about the range.)
    type_into(page, kp, "1e9", key_by_key=False)
    notice(page, "Kp 1000000000 N m/rad is outside [0, 2000] N m/rad; clamped to 2000 N m/rad")
    assert wait_until(lambda: dashboard.sim.gains.kp == 2000.0)
    assert wait_until(lambda: kp.input_value() == "2000"), kp.input_value()
    type_into(page, ki, "900", key_by_key=False)
    notice(page, "Ki 900 N m/(rad s) is outside [0, 500] N m/(rad s); clamped to 500 N m/(rad s)")
    assert wait_until(lambda: dashboard.sim.gains.ki == 500.0)
    assert wait_until(lambda: ki.input_value() == "500"), ki.input_value()

    # Not numbers: refused with a notice, the box shows the gain in use again, nothing is applied.
    for text, message in [
        ("1,5", "Kd: '1,5' is not a number; use a point for decimals; kept 30 N m s/rad"),
        ("abc", "Kd: 'abc' is not a number; kept 30 N m s/rad"),
        ("NaN", "Kd: 'NaN' is not a number; kept 30 N m s/rad"),
        ("inf", "Kd: 'inf' is not a number; kept 30 N m s/rad"),
    ]:
        type_into(page, kd, text, key_by_key=False)
        notice(page, message)
        assert wait_until(lambda: kd.input_value() == "30"), (text, kd.input_value())
    type_into(page, kd, "12.5", key_by_key=False)
    assert wait_until(lambda: dashboard.sim.gains.kd == 12.5)
    assert wait_until(lambda: kd.input_value() == "12.5")
    applied = [(800.0, 50.0, 30.0), (2000.0, 50.0, 30.0), (2000.0, 500.0, 30.0), (2000.0, 500.0, 12.5)]
    assert gain_changes(dashboard) == applied, "one change a typed value, none for refused text"
    assert dashboard.sim.config.gains == Gains(kp=2000.0, ki=500.0, kd=12.5)

    # The slider still drags, and the box follows it.
    track = page.locator(f'[id="{gains.kp._impl.uuid}"]')
    area = track.bounding_box()
    page.mouse.click(area["x"] + 0.25 * area["width"], area["y"] + area["height"] / 2)
    assert wait_until(lambda: dashboard.sim.gains.kp < 1000.0), dashboard.sim.gains
    assert wait_until(lambda: kp.input_value() == f"{dashboard.sim.gains.kp:g}"), kp.input_value()

    # What a person sees after a clamp, the scene drawn too.
    show_scene(page)
    type_into(page, ki, "900")
    notice(page, "Ki 900 N m/(rad s) is outside [0, 500] N m/(rad s)")
    assert wait_until(lambda: ki.input_value() == "500"), ki.input_value()
    page.mouse.move(700, 850)  # no hint tooltip over the boxes
    page.locator('[role="tooltip"]').first.wait_for(state="hidden", timeout=5_000)
    page.screenshot(path=str(tmp_path / "gains-clamped.png"))


def test_the_disturb_and_world_boxes_take_typed_numbers_checked_on_the_server(page, dashboard: Dashboard) -> None:
    page.get_by_role("tab", name="Disturb").click()
    kick = box(page, dashboard.layout.disturbances.magnitudes["pitch_kick"].handle)
    type_into(page, kick, "-99")
    notice(page, "Kick magnitude -99 N m s is outside [-5, 5] N m s; clamped to -5 N m s")
    assert wait_until(lambda: kick.input_value() == "-5"), kick.input_value()
    type_into(page, kick, "abc")
    notice(page, "Kick magnitude: 'abc' is not a number; kept -5 N m s")
    assert wait_until(lambda: kick.input_value() == "-5"), kick.input_value()
    # A value typed just before the button counts, without waiting for the quiet time. The
    # browser sends the box's text and the click as separate messages, and may hold back the
    # last keystroke's text for a moment: click once the server has the text, well inside the
    # quiet time, as a person's click after typing would be.
    type_into(page, kick, "0.5")
    entry = dashboard.layout.disturbances.magnitudes["pitch_kick"]
    assert wait_until(lambda: entry.handle.value == "0.5", timeout=5), entry.handle.value
    page.get_by_role("button", name="Pitch kick").click()
    assert wait_until(lambda: any(e.kind == "disturbance" for e in list(dashboard.sim.events)))
    (kicked,) = [e for e in list(dashboard.sim.events) if e.kind == "disturbance"]
    assert kicked.payload.magnitude == 0.5

    page.get_by_role("tab", name="World").click()
    seed = box(page, dashboard.layout.terrain.seed.handle)
    type_into(page, seed, "12.5")
    notice(page, "Seed must be a whole number, got '12.5'; kept 0")
    assert wait_until(lambda: seed.input_value() == "0"), seed.input_value()
    type_into(page, seed, "1e3")
    assert wait_until(lambda: seed.input_value() == "1000"), seed.input_value()
    assert dashboard.sim.config.seed == 0, "a typed seed waits for Regenerate"
    page.get_by_role("button", name="Regenerate").click()
    assert wait_until(lambda: dashboard.sim.config.seed == 1000, timeout=20)


def test_text_typed_into_the_speed_and_back_boxes_is_refused_and_the_box_filled_again(
    page, dashboard: Dashboard, tmp_path: Path
) -> None:
    """viser's number boxes beside the Speed and Back sliders went blank on NaN or abc, without a
    word: the browser never sent the text. They are text boxes now: the server says why and fills
    the box with the value in use again. Speed's box also takes Max typed, and says Max."""
    speed = box(page, dashboard.layout.simulation.entry.handle)
    for text in ("NaN", "abc"):
        type_into(page, speed, text)
        notice(page, f"Speed: '{text}' is not a number (or Max); kept 1 x")
        assert wait_until(lambda: speed.input_value() == "1"), speed.input_value()
    page.screenshot(path=str(tmp_path / "speed-refilled.png"))
    type_into(page, speed, "max")
    assert wait_until(lambda: dashboard.pacer.flat_out), dashboard.pacer.speed
    assert wait_until(lambda: speed.input_value() == "Max"), speed.input_value()

    page.get_by_role("tab", name="Replay").click()
    back = box(page, dashboard.layout.replay.back.handle)
    for text in ("NaN", "abc"):
        type_into(page, back, text)
        notice(page, f"Back: '{text}' is not a number; kept 0 s")
        assert wait_until(lambda: back.input_value() == "0"), back.input_value()
    assert dashboard.layout.replay.scrubbed is None
    page.screenshot(path=str(tmp_path / "back-refilled.png"))
    print(f"\nscreenshots: {tmp_path}")


def test_gains_given_at_start_show_as_given(browser, tmp_path: Path) -> None:  # noqa: F811
    """`hopper-dashboard --kp 1500 --ki 120 --kd 12.25`: every handle and box shows those, not a default."""
    dashboard = start(tmp_path, kp=1500.0, ki=120.0, kd=12.25)
    try:
        gains = dashboard.layout.gains
        assert (gains.kp.value, gains.ki.value, gains.kd.value) == (1500.0, 120.0, 12.25)
        assert [gains.entries[n].handle.value for n in ("kp", "ki", "kd")] == ["1500", "120", "12.25"]
        assert dashboard.sim.gains == Gains(kp=1500.0, ki=120.0, kd=12.25)
        page = open_page(browser, dashboard)
        try:
            shown = [box(page, gains.entries[n].handle).input_value() for n in ("kp", "ki", "kd")]
            assert shown == ["1500", "120", "12.25"]
            thumb = page.locator(f'[id="{gains.kp._impl.uuid}"] [role="slider"]')
            assert thumb.get_attribute("aria-valuenow") == "1500"
        finally:
            page.close()
    finally:
        dashboard.stop()


def test_help_closes_with_escape_and_with_its_button(page) -> None:
    modal = page.locator(".mantine-Modal-content")
    page.get_by_role("button", name="Help").click()
    modal.wait_for(state="visible", timeout=10_000)
    assert "Lunar hopper dashboard" in modal.inner_text()
    page.keyboard.press("Escape")
    modal.wait_for(state="detached", timeout=10_000)
    page.get_by_role("button", name="Help").click()
    modal.wait_for(state="visible", timeout=10_000)
    modal.get_by_role("button", name="Close").click()
    modal.wait_for(state="detached", timeout=10_000)


def test_the_torque_chart_draws_its_limit_lines(page, dashboard: Dashboard, tmp_path: Path) -> None:
    dashboard.layout.simulation.set_paused(False)
    assert wait_until(lambda: len(dashboard.layout.plots.window) > 40, timeout=30)
    chart = page.locator(".uplot").nth(2)  # pitch, wheel speed, torque
    chart.wait_for(timeout=10_000)
    chart.get_by_text("+limit").wait_for(timeout=10_000)  # its legend
    shot = tmp_path / "torque-chart.png"
    red = np.array([int(LIMIT_COLOR[i : i + 2], 16) for i in (1, 3, 5)])

    def limit_rows() -> tuple[np.ndarray, int]:
        """The chart's pixel rows drawn in the limit's colour, and its height (px)."""
        chart.screenshot(path=str(shot))
        pixels = np.asarray(Image.open(shot).convert("RGB")).astype(int)
        height, width, _ = pixels.shape
        # A dashed line across the plot draws its colour in over an eighth of its row (the antialiased
        # half of each dash aside); the legend's swatches and the torque trace (another red) do not.
        return np.flatnonzero((np.abs(pixels - red).sum(axis=2) < 20).sum(axis=1) > width / 8), height

    # The legend comes with the chart, the lines with its first data: the page draws them after the
    # server has the window (CI once read the chart before that).
    assert wait_until(lambda: limit_rows()[0].size, timeout=30), "no limit line drawn"
    dashboard.layout.simulation.set_paused(True)
    rows, height = limit_rows()
    page.screenshot(path=str(tmp_path / "page.png"))
    assert rows.size, "the limit lines went when the simulation paused"
    assert rows.min() < height / 3 and height / 3 < rows.max(), f"one line above zero and one below: rows {rows}"
