"""End to end: a real headless Chromium drives the dashboard page against an in-process server.

Skips without /usr/bin/chromium, except under CI=true, where a missing browser is a failure.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

from calls import Call
from hopper.app.dashboard.config import DashboardConfig
from hopper.app.dashboard.server import Dashboard
from net import free_port, wait_until
from pages import close_notices
from PIL import Image

from hopper.events import Disturbance, Event, EventKind
from hopper.sim import Simulation

# A page's first load is bounded, not paced: its software WebGL shares two cores with the servers
# and the other tests (one browser test at a time: conftest.py's xdist group).
PAGE_LOAD_MS = 120_000
MIN_CANVAS_COLOURS = 500  # a blank or single-colour canvas has a handful; the scene has thousands


def open_workbench(browser, dashboard: Dashboard, viewport: dict | None = None):
    """A 1440x900 page on the dashboard, once its panels are up and the server counts it as a client."""
    page = browser.new_page(viewport=viewport or {"width": 1440, "height": 900})
    page.set_default_timeout(60_000)  # a bound for a loaded machine, not a pace
    page.goto(dashboard.url)
    page.get_by_text("Loop analysis").first.wait_for(timeout=PAGE_LOAD_MS)
    assert wait_until(lambda: len(dashboard.server.get_clients()) == 1, timeout=30)
    return page


class PitchProbe:
    """A listener (attached on the loop thread) that keeps pitch samples and events."""

    def __init__(self) -> None:
        self.samples: list[tuple[float, float]] = []  # (time s, pitch rad)
        self.events: list[Event] = []

    def tick(self, sim: Simulation) -> None:
        if not self.samples or sim.data.time - self.samples[-1][0] >= 0.005:
            self.samples.append((sim.data.time, float(sim.data.joint("pitch").qpos[0])))

    def event(self, sim: Simulation, event: Event) -> None:
        self.events.append(event)


def distinct_colours(path: Path) -> int:
    image = Image.open(path).convert("RGB")
    return len(image.getcolors(maxcolors=image.width * image.height))


HOP_ROWS_JS = """() => [...document.querySelectorAll('table.hd-hops:not(.hd-resp) tr:not(.hd-mean)')]
    .filter(row => row.querySelector('td')).map(row => row.innerText.trim().split(/\\s+/))"""
LOG_TEXT_JS = "() => [...document.querySelectorAll('table.hd-log')].map(t => t.textContent).join(' | ')"
LOG_HAS_JS = "line => [...document.querySelectorAll('table.hd-log')].some(t => t.textContent.includes(line))"
LARGEST_CANVAS_JS = """() => { const cs = [...document.querySelectorAll('canvas')];
    const area = c => c.clientWidth * c.clientHeight;
    return cs.reduce((best, c, i) => area(c) > area(cs[best]) ? i : best, 0); }"""


def test_dashboard_in_a_real_browser(browser, tmp_path: Path) -> None:
    dashboard = Dashboard(
        DashboardConfig(port=free_port(), speed=4.0, sessions_dir=tmp_path / "sessions"), verbose=False
    ).start()
    # Start paused, before any hop: the page is checked at rest, then resumed from the page. (A
    # software-rendered page is also far more responsive while nothing moves.)
    dashboard.layout.simulation.set_paused(True)
    page = browser.new_page(viewport={"width": 1280, "height": 800})
    started = time.monotonic()

    def elapsed() -> str:
        return f"{time.monotonic() - started:.0f} s in"

    try:
        # The page loads and registers as a client.
        page.goto(dashboard.url)
        page.get_by_text("Kp", exact=True).first.wait_for(timeout=PAGE_LOAD_MS)
        assert wait_until(lambda: len(dashboard.server.get_clients()) == 1, timeout=30)

        # The 3D canvas is not blank. Software WebGL needs a few seconds for the first frame, so poll;
        # viser's notice about software rendering is closed first so that it is not counted.
        close_notices(page)  # viser's software-WebGL notice
        scene = page.locator("canvas").nth(page.evaluate(LARGEST_CANVAS_JS))
        shot, colours = tmp_path / "canvas.png", 0

        def drawn() -> bool:
            nonlocal colours
            # The page's pixels in the canvas's box: an element's screenshot first waits for two
            # animation frames with the same box, which a loaded software-WebGL page took over 10 s
            # to give (the screenshot's timeout, before the poll's own).
            page.screenshot(path=str(shot), clip=scene.bounding_box())
            colours = distinct_colours(shot)
            return colours >= MIN_CANVAS_COLOURS

        wait_until(drawn, timeout=60)
        print(f"\n3D canvas: {colours} distinct colours ({elapsed()})")
        assert colours >= MIN_CANVAS_COLOURS, f"the 3D canvas looks blank ({colours} colours)"

        # Typing a gain in the Kp box reaches the controller (commands apply while paused too).
        kp_label = page.locator(f'label[for="{dashboard.layout.gains.entries["kp"].handle._impl.uuid}"]')
        kp_box = kp_label.locator("xpath=ancestor::div[contains(@style,'padding-inline')][1]").locator("input")
        kp_box.click()
        kp_box.press("Control+a")
        kp_box.press_sequentially("620", delay=50)
        kp_box.press("Tab")
        assert wait_until(lambda: dashboard.sim.gains.kp == 620.0, timeout=10), dashboard.sim.gains
        print(f"Kp typed in the page reached the controller ({elapsed()})")

        # The per-hop table fills in once resumed (4x real time: a hop is about 3 s of simulation).
        assert page.evaluate(HOP_ROWS_JS) == [["no", "hops", "yet"]]
        page.get_by_role("button", name="Resume").click()
        assert wait_until(lambda: len(page.evaluate(HOP_ROWS_JS)) >= 2, timeout=60), page.evaluate(HOP_ROWS_JS)
        first, second = page.evaluate(HOP_ROWS_JS)[:2]
        assert first[0] == "1" and second[0] == "2", (first, second)
        # hop, distance, apex, flight, peak, rms, landing, saturation, wheel rpm, wheel J, legs J, CoT
        assert len(first) == 12 and all(math.isfinite(float(v)) for v in first[1:]), first
        assert 0.3 < float(first[1]) < 1.5, f"hop distance {first[1]} m"
        sim_hop = dashboard.sim.hops[0]
        assert first[1] == f"{sim_hop.distance_m:.2f}" and first[4] == f"{sim_hop.peak_pitch_deg:.1f}"
        print(f"hop table filled: {first} ({elapsed()})")

        # Clicking Pitch kick kicks the torso: the pitch moves away from where it was.
        probe = PitchProbe()
        dashboard.sim.submit(Call(lambda sim: sim.listeners.append(probe)))
        page.get_by_role("tab", name="Disturb").click()
        page.get_by_role("button", name="Pitch kick").click()
        assert wait_until(lambda: any(e.kind is EventKind.DISTURBANCE for e in probe.events), timeout=20)
        kick = next(e for e in probe.events if e.kind is EventKind.DISTURBANCE)
        assert kick.payload == Disturbance("pitch_kick", 1.0, "N m s")
        assert wait_until(lambda: probe.samples and probe.samples[-1][0] > kick.time + 0.3, timeout=10)
        at_kick = min(probe.samples, key=lambda s: abs(s[0] - kick.time))[1]
        excursion = max(abs(p - at_kick) for t, p in probe.samples if kick.time <= t <= kick.time + 0.3)
        print(f"pitch excursion after the kick: {math.degrees(excursion):.1f} deg ({elapsed()})")
        assert math.degrees(excursion) > 1.5
        # The kick is shown in the event log: first in the server's log, then in the page's log table.
        # (Checked in two steps so that a failure says which side lost it.)
        line = "pitch kick +1 N m s"
        assert wait_until(lambda: any(line in row for row in list(dashboard.layout.events.lines)), timeout=20), list(
            dashboard.layout.events.lines
        )
        try:
            page.wait_for_function(LOG_HAS_JS, arg=line, timeout=20_000)
        except Exception:
            page.screenshot(path=str(tmp_path / "event-log.png"))
            raise AssertionError(f"not in the page's event log: {page.evaluate(LOG_TEXT_JS)!r}") from None
    finally:
        page.close()
        dashboard.stop()
