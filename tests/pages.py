"""Shared steps of the browser tests that act on the page itself."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
# The page's own animation frames, at most SCENE_FPS a second. Software WebGL draws the lit,
# shadowed scene at about 5 frames/s on this machine with both cores busy (SwiftShader's workers
# took 1.7 cores), and every playwright action waits on frames: a tab click took 2 s. Capped at
# 2 frames/s, the page takes 0.8 cores and a click 0.2-0.3 s; the scene still draws, the server
# under test keeps a core. Only the page's scripts see the cap: playwright's own checks run in
# their isolated world, on Chromium's real frames.
SCENE_FPS = 2
CAP_FRAMES_JS = """(() => {
    const period = PERIOD_MS, raf = window.requestAnimationFrame.bind(window);
    const caf = window.cancelAnimationFrame.bind(window), pending = new Map();
    let next = 0, last = 0;
    window.requestAnimationFrame = (callback) => {
        const id = ++last, wait = Math.max(0, next - performance.now());
        const timer = setTimeout(() => pending.set(id, raf((stamp) => {
            pending.delete(id);
            next = Math.max(next, performance.now() + period);
            callback(stamp);
        })), wait);
        pending.set(id, -timer - 1);
        return id;
    };
    window.cancelAnimationFrame = (id) => {
        const handle = pending.get(id);
        pending.delete(id);
        if (handle === undefined) return;
        if (handle < 0) clearTimeout(-handle - 1); else caf(handle);
    };
})();""".replace("PERIOD_MS", f"{1000 / SCENE_FPS:g}")

# The dashboards the browser tests open light their scene as a user without a GPU would
# (DashboardConfig.lighting): software WebGL then draws about 20 frames/s instead of 5, and the capped
# page takes 0.26 cores instead of 0.8. test_dashboard_e2e keeps the shipped lighting.
BROWSER_LIGHTING = "simple"

# A click from a script: the notice's own handler closes it, as a user's click does, but playwright
# does not then wait for "scheduled navigations" (that wait timed out at 30 s with both cores busy,
# after the click itself was done).
CLOSE_NOTICES_JS = "() => document.querySelectorAll('.mantine-Notification-root button').forEach(b => b.click())"


def close_notices(page) -> None:  # noqa: ANN001 (a playwright Page)
    """Close the notifications on the page (viser's notice about software WebGL covers the scene)."""
    page.evaluate(CLOSE_NOTICES_JS)


# The list of a viser dropdown (Mantine's searchable Select, `aria-expanded` on its input): open
# with `option` in it, or shut again (a re-render of the panel by the page's updates can shut it).
LIST_SETTLED_JS = """([id, option]) => {
    const open = document.getElementById(id).getAttribute('aria-expanded') === 'true';
    const shown = [...document.querySelectorAll('[role=option]')].some(o => o.textContent.trim() === option);
    return (open && shown) || !open;
}"""
PICK_TRIES = 3


def pick(page, uuid: str, option: str) -> None:  # noqa: ANN001 (a playwright Page)
    """Open the dropdown whose input is `uuid` and click `option`, as a person does: one who opens
    the list again if it shut before the click (a browser test once waited 60 s for an option of a
    list that had shut under it)."""
    select = page.locator(f'input[id="{uuid}"]')
    for _ in range(PICK_TRIES):
        select.click()
        page.wait_for_function("id => document.getElementById(id).getAttribute('aria-expanded') === 'true'", arg=uuid)
        page.wait_for_function(LIST_SETTLED_JS, arg=[uuid, option])
        wanted = page.get_by_role("option", name=option, exact=True)
        if wanted.is_visible():
            wanted.click()
            return
    raise AssertionError(f"the list of {uuid} shut {PICK_TRIES} times before {option!r} could be clicked")


def wait_for_ab_table(page, *texts: str, timeout_ms: float = 30_000) -> None:  # noqa: ANN001 (a Page)
    """Wait for a re-fly table (table.hd-ab) holding every one of `texts`; on a timeout, fail with the
    tables the page holds, so a miss says whether the table came late, came wrong or never came."""
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    wanted = " && ".join(f"t.innerText.includes({text!r})" for text in texts)
    try:
        page.wait_for_function(
            f"() => [...document.querySelectorAll('table.hd-ab')].some(t => {wanted})", timeout=timeout_ms
        )
    except PlaywrightTimeout:
        held = page.evaluate("() => [...document.querySelectorAll('table.hd-ab')].map(t => t.innerText)")
        waited = f"{timeout_ms / 1000:g} s"
        raise AssertionError(f"no re-fly table with {texts} after {waited}; the page holds {held}") from None


class CappedBrowser:
    """A playwright Browser whose new pages run their animation frames at SCENE_FPS."""

    def __init__(self, browser) -> None:  # noqa: ANN001 (a playwright Browser)
        self._browser = browser

    def new_page(self, **options):  # noqa: ANN003, ANN201
        page = self._browser.new_page(**options)
        page.add_init_script(CAP_FRAMES_JS)
        return page

    def __getattr__(self, name: str):  # noqa: ANN204 (the rest of Browser, unchanged)
        return getattr(self._browser, name)


def launch_chromium() -> Iterator[CappedBrowser]:
    """Debian's Chromium, headless; skips without it or playwright, except under CI=true (a failure)."""

    def unavailable(reason: str) -> None:
        if os.environ.get("CI") == "true":
            pytest.fail(f"{reason}: CI must run the browser test")
        pytest.skip(reason)

    if not CHROMIUM.exists():
        unavailable(f"no Chromium at {CHROMIUM}")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError as exc:
        unavailable(f"playwright is not installed ({exc})")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        yield CappedBrowser(browser)
        browser.close()
