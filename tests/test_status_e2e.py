"""The status strip in Chromium: the server sends its table when the layout changes and its values
alone five times a second (hopper.app.dashboard.panels.status); the page's script (static/status.js)
writes each value into its cell, so the page reads as the server's strip.

The loop thread is not started: this test publishes the frames itself, so each strip it compares is
the one the page was last sent. Skips without /usr/bin/chromium, except under CI=true.
"""

from __future__ import annotations

import html
import re
from pathlib import Path

from hopper.app.dashboard.config import DashboardConfig
from hopper.app.dashboard.server import FRAME_S, Dashboard
from net import free_port, wait_until
from pages import BROWSER_LIGHTING
from test_dashboard_e2e import PAGE_LOAD_MS
from test_dashboard_inputs_e2e import VIEWPORT

STRIP_TEXT_JS = "() => document.querySelector('.hd-status')?.textContent ?? ''"


def text(strip: str) -> str:
    """What a page shows of a strip's HTML: its text, as the DOM's textContent reads it."""
    return html.unescape(re.sub(r"<[^>]+>", "", strip))


def test_the_page_writes_each_status_value_into_the_strip_sent_once(browser, tmp_path: Path) -> None:  # noqa: F811
    config = DashboardConfig(port=free_port(), sessions_dir=tmp_path / "s", lighting=BROWSER_LIGHTING)
    d = Dashboard(config, verbose=False)
    try:
        page = browser.new_page(viewport=VIEWPORT)
        page.goto(d.url)
        page.locator(".hd-status").first.wait_for(timeout=PAGE_LOAD_MS)
        assert wait_until(lambda: len(d.server.get_clients()) == 1, timeout=30)  # its script is sent
        status, ticks = d.layout.status, round(FRAME_S / d.sim.model.opt.timestep)
        d._publish(0.0, FRAME_S, True)
        frame, shown = status.frame.content, []
        for frame_no in range(1, 40):  # 1.2 s of simulation: the time, pitch and wheel move each frame
            for _ in range(ticks):
                d.sim.step()
            d._publish(frame_no * FRAME_S, FRAME_S, True)
            want = text(status.shown)
            shown.append(want)
            assert wait_until(lambda w=want: page.evaluate(STRIP_TEXT_JS) == w, timeout=30), (
                page.evaluate(STRIP_TEXT_JS),
                want,
            )
        assert status.frame.content == frame, "the table was sent again with the same layout"
        assert len(set(shown)) == len(shown), "a value did not change between two frames"
        assert "hd-phase hd-" + d.sim.phase.label in page.inner_html(".hd-status")  # the badge's colour
        page.close()
    finally:
        d.stop()
