"""Shared steps of the browser tests that act on the page itself."""

from __future__ import annotations

# A click from a script: the notice's own handler closes it, as a user's click does, but playwright
# does not then wait for "scheduled navigations" (that wait timed out at 30 s with both cores busy,
# after the click itself was done).
CLOSE_NOTICES_JS = "() => document.querySelectorAll('.mantine-Notification-root button').forEach(b => b.click())"


def close_notices(page) -> None:  # noqa: ANN001 (a playwright Page)
    """Close the notifications on the page (viser's notice about software WebGL covers the scene)."""
    page.evaluate(CLOSE_NOTICES_JS)
