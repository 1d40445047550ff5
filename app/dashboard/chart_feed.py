"""The live charts' feed: each page gets the samples it has not seen, not the window again.

viser's uPlot element takes only whole data: each refresh re-sent the 10 s window (about 3.4 kB a
refresh for the three charts, 17 kB/s at 5 a second). Here every page keeps its own copy of each
chart's window (static/charts.js, installed with the first push) and each refresh sends it, on that
client's own queue, only the rows newer than the last it was sent, with the window's first time so
that it drops what scrolled out: 8 rows a refresh at 1x. A page that has nothing yet (a new client)
or whose window no longer matches (after a reset or a restore) gets the whole window once.

Values are sent to what a chart can show: each column rounded to a fixed number of decimals, at most a
quarter of a pixel of its chart (the pitch chart's least range, 4 deg over 105 px, is 0.038 deg a
pixel: 0.01 deg; the wheel speed's 840 rpm: 1 rpm; the torque's 64 N m: 0.1 N m; time: 1 ms, the
samples are 25 ms apart). Numbers go as JSON text inside the zstd-compressed frame.

What it costs: the charts are drawn by the page's script through viser's private chart registry
(viser_compat.CHART_INSTANCE_JS), and a chart's expand dialog (viser's second uPlot, not registered)
would show only its first sample: its button is hidden (static/dashboard.css).
"""

from __future__ import annotations

import dataclasses
import json
from typing import Any

import numpy as np
import viser
from hopper.app.dashboard import assets
from hopper.app.dashboard import viser_compat as compat

PUSH = "window.hopperCharts.push("  # what a push's source calls; the JSON argument follows
Column = int | float  # a window column's index (int), or a constant's value (float)


@dataclasses.dataclass(frozen=True)
class ChartSpec:
    """One chart: its element, its columns (the window's, by index, or constants) and their decimals."""

    uuid: str
    columns: tuple[Column, ...]  # the first is the time column
    decimals: tuple[int, ...]


def runtime() -> str:
    """The page's script, with the way to its charts filled in (once per page)."""
    return assets.chart_runtime().replace("CHART_INSTANCE", compat.CHART_INSTANCE_JS)


def _rounded(values: np.ndarray, decimals: int) -> list[float] | list[int]:
    rounded = np.round(values.astype(np.float64), decimals)
    return rounded.astype(np.int64).tolist() if decimals <= 0 else rounded.tolist()


@dataclasses.dataclass
class _Page:
    generation: int
    last_time: float  # s, the newest sample time it was sent


class ChartFeed:
    """Per client: which window (generation) and up to which sample time it has; `publish` sends the rest."""

    def __init__(self, server: viser.ViserServer, charts: tuple[ChartSpec, ...]) -> None:
        self._server = server
        self.charts = charts
        self.generation = 0  # bumped when the window is replaced rather than extended
        self._pages: dict[int, _Page] = {}
        self.pushes = 0  # pushes queued, all clients, for tests

    def replaced(self) -> None:
        """The window was cleared or cut back: every page gets it whole at the next publish."""
        self.generation += 1

    def behind(self, newest: float) -> bool:
        """Whether some connected page lacks a sample up to `newest` (s) or the current window."""
        return any(
            (page := self._pages.get(cid)) is None or page.generation != self.generation or page.last_time < newest
            for cid in self._server.get_clients()
        )

    def publish(self, columns: np.ndarray) -> None:
        """Send each connected page what it lacks of the window `columns` (shape (columns, n), oldest first)."""
        clients = self._server.get_clients()
        for gone in self._pages.keys() - clients.keys():
            del self._pages[gone]
        if columns.shape[1] == 0:
            return
        t = columns[0]
        newest, first = float(t[-1]), float(t[0])
        sources: dict[tuple[bool, float | None], str] = {}  # pages in the same state get the same text
        for cid, client in clients.items():
            if compat.connection_closed(client):
                continue
            page = self._pages.get(cid)
            whole = page is None or page.generation != self.generation
            since = None if whole else page.last_time  # type: ignore[union-attr]
            if since is not None and since >= newest:
                continue
            key = (page is None, since)
            if key not in sources:
                start = 0 if since is None else int(np.searchsorted(t, since, side="right"))
                payload = self._payload(columns[:, start:], first, replace=since is None)
                sources[key] = (runtime() + "\n" if page is None else "") + f"{PUSH}{payload});"
            compat.run_javascript(client, sources[key])
            self._pages[cid] = _Page(self.generation, newest)
            self.pushes += 1

    def _payload(self, rows: np.ndarray, first: float, replace: bool) -> str:
        update: dict[str, dict[str, Any]] = {}
        for chart in self.charts:
            cols = [
                _rounded(rows[c], d) if isinstance(c, int) else c
                for c, d in zip(chart.columns, chart.decimals, strict=True)
            ]
            update[chart.uuid] = {"r": int(replace), "f": round(first, chart.decimals[0]) - 1e-9, "c": cols}
        return json.dumps(update, separators=(",", ":"))


def decode_push(source: str) -> dict[str, Any] | None:
    """A push's update (uuid -> {"r", "f", "c"}) from a RunJavascriptMessage's source; None if it is none."""
    at = source.rfind(PUSH)
    if at < 0 or not source.endswith(");"):
        return None
    return json.loads(source[at + len(PUSH) : -2])


def apply_push(windows: dict[str, list[Any]], update: dict[str, Any]) -> None:
    """What static/charts.js does with a push, on `windows` (uuid -> columns): the probe's copy of a page."""
    for uuid, u in update.items():
        w = windows.get(uuid)
        if w is None or u["r"]:
            w = windows[uuid] = [c if isinstance(c, (int, float)) else [] for c in u["c"]]
        for i, c in enumerate(u["c"]):
            if isinstance(c, list):
                w[i].extend(c)
            else:
                w[i] = c
        t = next(c for c in w if isinstance(c, list))
        old = 0
        while old < len(t) and t[old] < u["f"]:
            old += 1
        if old:
            for i, c in enumerate(w):
                if isinstance(c, list):
                    w[i] = c[old:]
