"""The live charts' feed (hopper.app.dashboard.chart_feed): each page's copy of the window, rebuilt from
the pushes by a probe client exactly as static/charts.js does, equals the server's window; a refresh
carries only the samples that page lacks."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest
import viser
from hopper.app.dashboard.chart_feed import decode_push
from hopper.app.dashboard.plots import _N, PLOT_PUBLISH_S, LivePlots
from hopper.app.dashboard.probe import ProbeClient
from net import free_port, wait_until

from hopper.config import WHEEL_TORQUE_LIMIT
from hopper.metrics import RAD_S_TO_RPM

pytestmark = pytest.mark.integration  # a real ViserServer and websocket clients


@pytest.fixture
def served() -> Iterator[tuple[viser.ViserServer, LivePlots]]:
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    yield server, LivePlots(server)
    server.stop()


class Feeder:
    """Samples a hopping-like trace into the plots, 25 ms apart, and refreshes on a 0.2 s wall grid."""

    def __init__(self, plots: LivePlots, seed: int = 0) -> None:
        self.plots, self.rng, self.time, self.now = plots, np.random.default_rng(seed), 0.0, 100.0

    def samples(self, n: int) -> None:
        for _ in range(n):
            t = self.time
            pitch = 1.2 * math.sin(2 * math.pi * 0.8 * t) + self.rng.normal(0, 0.05)
            rpm = 300 * math.sin(2 * math.pi * 0.3 * t)
            torque = 20 * math.sin(2 * math.pi * 1.3 * t)
            self.plots.sample(t, math.radians(pitch), rpm / RAD_S_TO_RPM, torque, torque + self.rng.normal(0, 0.5))
            self.time += 0.025

    def publish(self) -> None:
        self.now += PLOT_PUBLISH_S
        self.plots.publish(self.now)


def expected(plots: LivePlots) -> dict[str, list]:
    """The window each page must hold: every column at its decimals, the constants as their values."""
    window = plots.window.columns()
    out = {}
    for spec in plots.feed.charts:
        columns = []
        for column, decimals in zip(spec.columns, spec.decimals, strict=True):
            if isinstance(column, int):
                columns.append(np.round(window[column].astype(np.float64), decimals).tolist())
            else:
                columns.append(column)
        out[spec.uuid] = columns
    return out


def connect(server: viser.ViserServer, probes: list[ProbeClient]) -> ProbeClient:
    before = len(server.get_clients())
    probe = ProbeClient(f"http://127.0.0.1:{server.get_port()}")
    probes.append(probe)
    assert wait_until(lambda: len(server.get_clients()) == before + 1, timeout=20), "viser never registered it"
    return probe


def holds(probe: ProbeClient, plots: LivePlots) -> bool:
    want = expected(plots)
    return probe.wait_for(lambda p: all(_same(p.chart_windows.get(u), w) for u, w in want.items()), timeout=20)


def _same(have: list | None, want: list) -> bool:
    return (
        have is not None
        and len(have) == len(want)
        and all(h == w if not isinstance(w, list) else np.array_equal(h, w) for h, w in zip(have, want, strict=True))
    )


def started(
    served: tuple[viser.ViserServer, LivePlots], probes: list[ProbeClient], seed: int, samples: int
) -> tuple[Feeder, ProbeClient]:
    """A feeder and a page that holds the window of its first `samples` samples."""
    server, plots = served
    feed = Feeder(plots, seed=seed)
    page = connect(server, probes)
    feed.samples(samples)
    feed.publish()
    assert holds(page, plots)
    return feed, page


def last_rows(probe: ProbeClient) -> int:
    """Rows of the time column in the latest push the probe received."""
    update = decode_push(probe.scripts[-1])
    assert update is not None
    (rows,) = {len(u["c"][0]) for u in update.values()}  # every chart got the same rows
    return rows


def test_a_page_gets_the_window_once_then_only_the_new_samples(
    served: tuple[viser.ViserServer, LivePlots], probes: list[ProbeClient]
) -> None:
    server, plots = served
    feed = Feeder(plots)
    a = connect(server, probes)
    feed.samples(_N + 50)  # more than a window: the oldest have scrolled out
    feed.publish()
    assert holds(a, plots) and last_rows(a) == _N
    assert len(a.chart_windows[plots.feed.charts[0].uuid][0]) == _N
    for _ in range(5):
        feed.samples(8)  # 0.2 s of simulation at 1x
        feed.publish()
        assert holds(a, plots), "the page's window is not the server's"
        assert last_rows(a) == 8
    # The limit lines are constants: one number each, never a column of them.
    rpm, torque = (a.chart_windows[spec.uuid] for spec in plots.feed.charts[1:])
    assert rpm[2:] == [pytest.approx(plots.rpm_limit), pytest.approx(-plots.rpm_limit)]
    assert torque[3:] == [pytest.approx(WHEEL_TORQUE_LIMIT), pytest.approx(-WHEEL_TORQUE_LIMIT)]
    # Nothing new, nothing sent.
    pushes = plots.feed.pushes
    feed.publish()
    assert plots.feed.pushes == pushes


def test_a_later_page_gets_the_whole_window_and_the_first_one_still_only_what_is_new(
    served: tuple[viser.ViserServer, LivePlots], probes: list[ProbeClient]
) -> None:
    server, plots = served
    feed, a = started(served, probes, seed=1, samples=100)
    b = connect(server, probes)
    feed.publish()  # paused: no new sample, yet the new page gets the window
    assert holds(b, plots) and last_rows(b) == 100
    feed.samples(8)
    feed.publish()
    assert holds(a, plots) and holds(b, plots)
    assert last_rows(a) == last_rows(b) == 8
    assert len(a.scripts) == 2 and len(b.scripts) == 2
    assert "window.hopperCharts = {" in a.scripts[0]  # the page's script came with the first push
    assert "window.hopperCharts = {" not in a.scripts[1]  # and only with it


@pytest.mark.parametrize("how", ["reset", "restore"])
def test_after_a_reset_or_a_restore_every_page_gets_the_window_whole(
    served: tuple[viser.ViserServer, LivePlots], probes: list[ProbeClient], how: str
) -> None:
    server, plots = served
    feed, a = started(served, probes, seed=2, samples=200)
    if how == "reset":
        plots.clear()
        feed.time = 0.0
        feed.samples(12)
    else:
        plots.drop_after(2.0)  # back to t = 2 s: the later samples are gone
        feed.time = 2.025
    feed.publish()
    assert holds(a, plots), "the page kept samples the server dropped"
    assert decode_push(a.scripts[-1]) and all(u["r"] for u in decode_push(a.scripts[-1]).values())
