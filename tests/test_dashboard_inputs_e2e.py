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
from PIL import Image
from test_dashboard_e2e import LARGEST_CANVAS_JS, browser  # noqa: F401  (browser: the Chromium fixture)

VIEWPORT = {"width": 1440, "height": 900}


def start(tmp_path: Path, **config: object) -> Dashboard:
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
    page.get_by_text("Kp", exact=True).first.wait_for(timeout=30_000)
    assert wait_until(lambda: len(dashboard.server.get_clients()) == 1, timeout=30)
    close_notice = page.locator(".mantine-Notification-root").get_by_role("button")  # viser's software-GL notice
    if close_notice.count():
        close_notice.first.click()
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


def type_into(page, locator, text: str) -> None:
    """Select what the box holds and type over it, key by key, as a person does."""
    locator.click()
    page.keyboard.press("Control+A")
    page.keyboard.type(text)


def notice(page, text: str):
    """Wait for a notification that contains `text`; returns it."""
    found = page.locator(".mantine-Notification-root", has_text=text)
    found.first.wait_for(timeout=10_000)
    return found


def gain_changes(dashboard: Dashboard) -> list[tuple[float, float, float]]:
    return [(e.data["kp"], e.data["ki"], e.data["kd"]) for e in list(dashboard.sim.events) if e.kind == "gains"]


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
    dashboard.layout.simulation.set_paused(True)
    shot = tmp_path / "torque-chart.png"
    chart.screenshot(path=str(shot))
    page.screenshot(path=str(tmp_path / "page.png"))
    pixels = np.asarray(Image.open(shot).convert("RGB")).astype(int)
    red = np.array([int(LIMIT_COLOR[i : i + 2], 16) for i in (1, 3, 5)])
    height, width, _ = pixels.shape
    # A dashed line across the plot draws its colour in over an eighth of its row (the antialiased
    # half of each dash aside); the legend's swatches and the torque trace (another red) do not.
    rows = np.flatnonzero((np.abs(pixels - red).sum(axis=2) < 20).sum(axis=1) > width / 8)
    assert rows.size, "no limit line drawn"
    assert rows.min() < height / 3 and height / 3 < rows.max(), f"one line above zero and one below: rows {rows}"
