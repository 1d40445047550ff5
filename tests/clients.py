"""A headless client on a served dashboard, as the tests open it (hopper.app.dashboard.probe)."""

from __future__ import annotations

from hopper.app.dashboard.probe import ProbeClient
from hopper.app.dashboard.server import Dashboard
from net import wait_until


def connect(dashboard: Dashboard, clients: int = 1) -> ProbeClient:
    """A probe that has seen the page and that the server has registered (`clients` then connected).

    Seeing the page is not being a client: viser registers a connection only once it has handled
    its first camera message, and until then notifications (sent to server.get_clients()) and GUI
    callbacks (dropped for an unknown client) miss it. On a loaded machine that can come later.
    """
    client = ProbeClient(dashboard.url)
    assert client.wait_for(lambda p: len(p.gui) > 20 and p.pose_frames > 0), "the probe never saw the page"
    assert wait_until(lambda: len(dashboard.server.get_clients()) == clients), "the server never registered the probe"
    return client


def titles(client: ProbeClient) -> list[str]:
    """The titles of the notifications the client was shown, in order."""
    return [n.get("title", "") for n in client.notifications]
