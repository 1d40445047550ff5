"""The hop table in Chromium: every header and number clear of its neighbours at the Live panel's widths.

Skips without /usr/bin/chromium, except under CI=true, where a missing browser is a failure.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hopper.app.dashboard.server import Dashboard
from net import wait_until
from pages import close_notices
from test_dashboard_e2e import PAGE_LOAD_MS
from test_dashboard_inputs_e2e import HIDE_SCENE, VIEWPORT, start
from test_table_rows import hop

# Hop numbers of every width up to 5 digits; each metric at the widest it takes in flight.
WIDEST = dict(
    distance_m=1.23, peak_pitch_deg=12.3, rms_pitch_rate_deg_s=140.0, landing_pitch_deg=1.5, peak_wheel_rpm=840.0,
    wheel_energy_j=126.0, leg_energy_j=134.0, cost_of_transport=12.3,
)  # fmt: skip
HOPS = [hop(9, **WIDEST), hop(1843, **WIDEST), hop(12345, **WIDEST)]
PANEL_WIDTHS = (400, 330)  # px: the Live panel's own (static/theme.json), and the control panel's
# Between two texts' boxes on one line, which include the glyphs' side bearings: the numbers stand 1.9 px
# apart at 330 px and read as separate; 'apex' ran into 'flight' (-1 px) before the headers took 9 px type.
MIN_GAP_PX = 1.5

# At a width of the Live panel (the nearest ancestor of the hop table whose width viser set in pixels),
# per part of the hop table (its header, each row, the mean), per row: each cell's text box and its box.
CELLS_JS = """width => {
    let panel = document.querySelector('table.hd-hops');
    while (panel && !(panel.style && panel.style.width.endsWith('px'))) panel = panel.parentElement;
    panel.style.width = width + 'px';
    return [...document.querySelectorAll('table.hd-hops:not(.hd-resp)')].map(table =>
        [...table.rows].map(row => [...row.cells].map(cell => {
            const range = document.createRange(); range.selectNodeContents(cell);
            const text = range.getBoundingClientRect(), box = cell.getBoundingClientRect();
            return {text: cell.innerText.trim(), left: text.left, right: text.right,
                    cellLeft: box.left, cellRight: box.right};
        })));
}"""


@pytest.fixture
def dashboard(tmp_path: Path):
    d = start(tmp_path)  # paused: no hop of its own joins the table
    assert wait_until(lambda: d.pacer.paused, timeout=30)
    d.layout.hops.show(HOPS)
    yield d
    d.stop()


def crowding(parts: list[list[list[dict]]]) -> list[str]:
    """What a reader could misread: a text out of its cell, two texts on one line too close to tell
    apart, a column's edge that moves between the parts, or one header name given to two headers."""
    faults = []
    header_edges = [round(c["cellRight"]) for c in parts[0][-1]]
    for part in parts:
        for row in part:
            texts = [c for c in row if c["text"]]
            for c in texts:
                if c["left"] < c["cellLeft"] - 0.5 or c["right"] > c["cellRight"] + 0.5:
                    faults.append(f"{c['text']!r} overflows its cell")
            for a, b in zip(texts, texts[1:], strict=False):
                if b["left"] - a["right"] < MIN_GAP_PX:
                    faults.append(f"{a['text']!r} and {b['text']!r} {b['left'] - a['right']:.1f} px apart")
        edges = [round(c["cellRight"]) for c in part[-1]]
        if len(edges) == len(header_edges) and edges != header_edges:
            faults.append(f"columns {edges} under headers {header_edges}")
    names = [c["text"].split("\n")[0] for c in parts[0][0]]  # a header's first line: its name
    words = [word for name in names for word in name.split() if len(word) > 1]  # not the E of E wheel, E legs
    faults += [f"{word!r} names two headers" for word in sorted({w for w in words if words.count(w) > 1})]
    return faults


def test_the_hop_tables_headers_and_numbers_stay_apart_at_the_panels_widths(
    browser,  # noqa: F811
    dashboard: Dashboard,
    tmp_path: Path,
) -> None:
    """'wheel' (rpm) stood next to 'E wheel' (J), and at 330 px 'apexflightpeak' ran together. The
    wheel's speed and energy now share one 'wheel' over 'rpm' and 'J'; names, units and hop numbers
    up to 12345 each keep to their cell, apart from their neighbours, in columns that line up."""
    page = browser.new_page(viewport=VIEWPORT)
    try:
        page.add_init_script(f"document.addEventListener('DOMContentLoaded', () => {{ const s = "
                             f"document.createElement('style'); s.textContent = {HIDE_SCENE!r}; "
                             f"document.head.append(s); }});")  # fmt: skip
        page.goto(dashboard.url, timeout=PAGE_LOAD_MS)
        page.locator("table.hd-hops td", has_text="12345").first.wait_for(timeout=PAGE_LOAD_MS)
        close_notices(page)
        header = page.locator("table.hd-hops").first
        faults = {}
        for width in PANEL_WIDTHS:
            parts = page.evaluate(CELLS_JS, width)
            assert [row[0]["text"] for part in parts[1:4] for row in part] == ["9", "1843", "12345"], parts
            faults[width] = crowding(parts)
            box = header.bounding_box()
            assert box is not None
            shot = tmp_path / f"hops-{width}.png"
            page.screenshot(path=str(shot), clip={"x": 0, "y": box["y"] - 4, "width": width + 10, "height": 130})
            print(f"\nscreenshot: {shot}")
        assert faults == {width: [] for width in PANEL_WIDTHS}, faults
    finally:
        page.close()
