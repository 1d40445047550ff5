"""Shared fixtures: small, seeded, headless; a dashboard on a free loopback port and a probe client."""

from __future__ import annotations

import signal
from collections.abc import Iterator
from pathlib import Path

import pytest
from clients import connect
from hopper.app.dashboard.config import DashboardConfig
from hopper.app.dashboard.probe import ProbeClient
from hopper.app.dashboard.server import Dashboard
from net import free_port
from pages import BROWSER_LIGHTING, launch_chromium

from hopper.config import SimConfig
from hopper.sim import Simulation


@pytest.fixture(scope="module")
def browser():
    """Chromium for a module's browser tests (tests/pages.py: frames capped, skips without it)."""
    yield from launch_chromium()


@pytest.fixture
def handlers() -> Iterator[None]:
    """The test process's stop handlers back (a CLI's main() installs its own) and no stop request, after the test."""
    from hopper import interrupts

    saved = {s: signal.getsignal(s) for s in interrupts.STOP_SIGNALS}
    yield
    for s, handler in saved.items():
        signal.signal(s, handler)
    interrupts.clear()


@pytest.fixture
def flat_sim() -> Simulation:
    return Simulation(SimConfig(terrain="flat"))


def _lit(request: pytest.FixtureRequest, settings: dict[str, object]) -> dict[str, object]:
    """`settings`, lit as tests/pages.py says for a browser test's dashboard unless they say otherwise."""
    if request.node.get_closest_marker("browser") is not None:
        settings.setdefault("lighting", BROWSER_LIGHTING)
    return settings


@pytest.fixture
def dashboard(request: pytest.FixtureRequest, tmp_path: Path):
    config = DashboardConfig(port=free_port(), sessions_dir=tmp_path / "sessions", **_lit(request, {}))  # type: ignore[arg-type]
    d = Dashboard(config, verbose=False).start()
    yield d
    d.stop()


@pytest.fixture
def start(request: pytest.FixtureRequest, tmp_path: Path):
    """Start dashboards with the given DashboardConfig settings on free loopback ports; all stop after the test."""
    dashboards: list[Dashboard] = []

    def make(**settings: object) -> Dashboard:
        config = DashboardConfig(port=free_port(), sessions_dir=tmp_path / "sessions", **_lit(request, settings))  # type: ignore[arg-type]
        dashboards.append(Dashboard(config, verbose=False).start())
        return dashboards[-1]

    yield make
    for d in dashboards:
        d.stop()


@pytest.fixture
def probes() -> Iterator[list[ProbeClient]]:
    """Headless clients a test opens (append them); all are closed after the test."""
    opened: list[ProbeClient] = []
    yield opened
    for p in opened:
        p.close()


@pytest.fixture
def client(dashboard: Dashboard):
    c = connect(dashboard)
    yield c
    c.close()


# The suite in parts (README, "Tests"): `-m unit` runs in under two minutes; `integration` starts
# servers, processes or pools; `browser` drives Chromium. A module or test says `integration`
# itself (pytestmark); the browser files and the tests on a served dashboard are found here.
SERVED = {"dashboard", "start", "client"}


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if item.path.name.endswith("_e2e.py"):
            item.add_marker(pytest.mark.browser)
            # Under `--dist loadgroup` the browser tests share one worker: each page keeps Chromium's
            # software WebGL busy (0.26 cores with the simple lighting, 0.8 before), and two at once
            # on two cores starved the servers they were testing (a page load once took over 30 s;
            # split over two workers, the suite took 599 s against 565 s, with the full lighting).
            item.add_marker(pytest.mark.xdist_group("browser"))
        elif SERVED & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.integration)
        if not any(item.get_closest_marker(m) for m in ("browser", "integration")):
            item.add_marker(pytest.mark.unit)
    # Repeated, the suite runs pass after pass (each test once, then each test again): a hunt cut
    # short has run every test about as often.
    items.sort(key=_pass)


def _pass(item: pytest.Item) -> int:
    """Which repetition `item` is (0 without --repeat)."""
    callspec = getattr(item, "callspec", None)
    return callspec.params.get("_repeat", 0) if callspec is not None else 0


# A flake hunt: `--repeat 20 -m "integration or browser"` runs every test that waits on a server
# or a browser 20 times, each a test of its own (`[repeat 7/20]`), so one failure names its run.
def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--repeat", type=int, default=1, metavar="N", help="run each test N times")


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    n = metafunc.config.getoption("repeat")
    if n > 1:
        metafunc.fixturenames.append("_repeat")
        metafunc.parametrize("_repeat", range(1, n + 1), ids=lambda i: f"repeat {i}/{n}")
