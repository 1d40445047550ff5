"""The hop tables and the event log on the wire (panels/rows.py): a probe client rebuilds what the page
shows from the elements and their updates, and it equals the server's tables; a new hop or event
sends its own rows (and the means), never the rows already shown."""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Iterator

import pytest
import viser
from hopper.app.dashboard.panels.events import LINES, build_event_log
from hopper.app.dashboard.panels.hops import ROWS, HopTable, build_hop_table
from hopper.app.dashboard.probe import ProbeClient
from hopper.app.dashboard.viser_compat import element_id
from net import free_port, wait_until

from hopper.events import Disturbance, Event
from hopper.metrics import HopMetrics

pytestmark = pytest.mark.integration  # a real ViserServer and websocket clients


def hop(index: int, **changes: object) -> HopMetrics:
    base = HopMetrics(
        index=index, distance_m=0.8 + 0.01 * index, apex_height_m=0.25, flight_time_s=1.2, stance_time_s=0.5,
        peak_pitch_deg=12.0 - 0.1 * index, rms_pitch_rate_deg_s=40.0, landing_pitch_deg=2.0, saturation_time_s=0.3,
        peak_wheel_rpm=250.0 + index, liftoff_momentum=0.1, touchdown_time_s=3.0 * index, wheel_energy_j=26.4,
        leg_energy_j=34.2, cost_of_transport=5.67, kicked=index % 2 == 0, response_start_s=0.2,
    )  # fmt: skip
    return dataclasses.replace(base, **changes)


@pytest.fixture
def served() -> Iterator[tuple[viser.ViserServer, ProbeClient]]:
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    yield server, None  # type: ignore[misc]
    server.stop()


def connect(server: viser.ViserServer, probes: list[ProbeClient]) -> ProbeClient:
    probe = ProbeClient(f"http://127.0.0.1:{server.get_port()}")
    probes.append(probe)
    assert wait_until(lambda: len(server.get_clients()) == len(probes), timeout=20), "viser never registered it"
    return probe


def shows(probe: ProbeClient, folder: str, html: str) -> bool:
    return probe.wait_for(lambda p: p.shown_html(folder) == html, timeout=20)


def test_each_hop_sends_its_two_rows_and_the_means_and_the_page_shows_the_servers_tables(
    served: tuple[viser.ViserServer, None], probes: list[ProbeClient]
) -> None:
    server, _ = served
    with server.gui.add_folder("Hops") as folder:
        table: HopTable = build_hop_table(server.gui)
    probe = connect(server, probes)
    folder_id = element_id(folder)
    assert shows(probe, folder_id, table.html()) and "no hops yet" in table.html()
    for i in range(1, ROWS + 5):
        before = len(probe.gui_log)
        table.add(hop(i))
        assert shows(probe, folder_id, table.html()), f"hop {i}: the page's tables are not the server's"
        sent = probe.gui_log[before:]
        content = [u["content"] for _, u in sent if "content" in u]
        # The hop's row in each table, then the means that changed (the response header once, at the first kick).
        assert content[:2] == [table.rows.shown[-1], table.response_rows.shown[-1]]
        assert len(content) <= 4 + (i == 2), [c[:60] for c in content]
        if i >= ROWS:  # full tables: a hop sends a small part of them
            assert sum(len(c) for c in content) < len(table.html()) / 3
    assert table.html().count("<td>") > 0 and f"<td>{ROWS + 4}</td>" in table.html()
    assert "<td>4</td>" not in table.rows.shown[0]  # the oldest shown is hop 5: the ring moved on
    # A reset dims the last run; its first hop replaces it; a restore shows exactly the hops it had.
    table.clear()
    assert shows(probe, folder_id, table.html()) and "previous run" in table.html()
    table.add(hop(1, completed=False))
    assert shows(probe, folder_id, table.html()) and "previous run" not in table.html()
    assert "hd-fell" in table.html()
    table.show([hop(i) for i in range(1, 4)])
    assert shows(probe, folder_id, table.html())
    # A page that comes later sees the same.
    late = connect(server, probes)
    assert shows(late, folder_id, table.html())


def test_each_event_sends_its_own_line_newest_first(
    served: tuple[viser.ViserServer, None], probes: list[ProbeClient]
) -> None:
    server, _ = served
    with server.gui.add_folder("Events") as folder:
        log = build_event_log(server.gui)
    probe = connect(server, probes)
    folder_id = element_id(folder)
    assert shows(probe, folder_id, log.content) and "no events yet" in log.content
    for i in range(LINES + 4):
        before = len(probe.gui_log)
        log.add(Event(0.5 * i, 0, Disturbance("push_forward", float(i + 1), "N s")))
        assert shows(probe, folder_id, log.content), f"event {i}: the page's log is not the server's"
        content = [u["content"] for _, u in probe.gui_log[before:] if "content" in u]
        assert len(content) == 1 and f"+{i + 1} N s" in content[0]
        # The side panel cuts a long line with "…": its whole text shows on hover.
        cell = re.search(r"<td title='([^']*)'>([^<]*)</td>", content[0])
        assert cell is not None and cell[1] == cell[2], content[0]
    assert len(log.lines) == LINES and f"+{LINES + 4} N s" in log.lines[0]  # newest first
    late = connect(server, probes)
    assert shows(late, folder_id, log.content)
