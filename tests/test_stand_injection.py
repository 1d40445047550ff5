"""A chirp played into the running stand (hopper.stand.Injection, the Inject command): it measures
what a batch record() does, tick for tick, while the loop runs as it runs (advance, other
listeners); it ends on a reset, a restore or a mode change, and is refused where it cannot play."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader

from hopper.analysis.bench import compare_stand, measure_stand
from hopper.analysis.frequency import ChirpSpec, excitation
from hopper.commands import Inject
from hopper.config import SimConfig
from hopper.events import EventKind
from hopper.sim import Simulation
from hopper.stand import Injection, StandSimulation, record
from hopper.telemetry.recorder import Telemetry

pytestmark = pytest.mark.unit

SPEC = ChirpSpec(f_min=2.0, f_max=200.0, amplitude=0.4, length=3.0)


def stand(legs: str = "locked") -> StandSimulation:
    sim = StandSimulation(SimConfig(terrain="flat", seed=11), legs=legs)  # type: ignore[arg-type]
    sim.settle(0.2)
    return sim


def play(sim: Simulation, command: Inject, ended: list[Injection], limit: int) -> None:
    """Submit `command` and run the loop as the dashboard does (advance) until it has ended."""
    sim.submit(command)
    ticks = 0
    while not ended and ticks < limit:
        ticks += sim.advance(50)[0]
    assert ended, f"the injection did not end within {limit} ticks"


@pytest.mark.parametrize(("legs", "at"), [("locked", "input"), ("free", "reference")])
def test_a_live_injection_records_what_a_batch_one_does(legs: str, at: str):
    spec = ChirpSpec(f_min=2.0, f_max=100.0, amplitude=0.4 if at == "input" else 0.02, length=3.0, at=at)
    live, batch = stand(legs), stand(legs)
    d = excitation(spec)
    expected = record(batch, d, spec.at)
    ended: list[Injection] = []
    play(live, Inject(d, spec.at, ended.append), ended, limit=len(d) + 200)
    injection = ended[0]
    assert injection.stopped == "" and injection.played == len(d) and not injection.playing
    got = injection.records()
    for name in expected:
        np.testing.assert_array_equal(got[name], expected[name], err_msg=name)
    assert injection not in live.listeners
    assert live.controller.mem["inject_torque" if at == "input" else "inject_ref"][0] == 0.0
    # The estimate from the live records, predicted at the stand the injection started on.
    live_result = compare_stand(legs, injection.start, spec, [got])
    assert live_result.where == f"stand (legs {legs})" and live_result.predicted is not None
    np.testing.assert_allclose(live_result.response.coherence, measure_stand(stand(legs), spec).response.coherence)


def test_a_reset_or_a_restore_ends_the_injection_and_says_why():
    sim = stand()
    ended: list[Injection] = []
    before = sim.snapshot()
    sim.inject(excitation(SPEC), "input", ended.append)
    for _ in range(100):
        sim.step()
    sim.reset()
    assert len(ended) == 1 and "reset" in ended[0].stopped and ended[0].played == 100
    assert len(ended[0].records()["u"]) == 100
    sim.inject(excitation(SPEC), "input", ended.append)
    sim.step()
    sim.restore(before)
    assert len(ended) == 2 and "restored" in ended[1].stopped
    assert sim.controller.mem["inject_torque"][0] == 0.0 and not [x for x in sim.listeners if isinstance(x, Injection)]


def test_an_injection_is_refused_off_the_stand_over_another_or_out_of_range():
    hopping = Simulation(SimConfig(terrain="flat"))
    hopping.submit(Inject(excitation(SPEC), "input", lambda _: None))
    hopping.step()
    failed = [e.payload for e in hopping.events if e.kind == EventKind.COMMAND_FAILED]
    assert failed and "needs the stand" in failed[-1].describe()

    sim = stand()
    sim.inject(excitation(SPEC), "input")
    with pytest.raises(Exception, match="an injection is playing"):
        sim.inject(excitation(SPEC), "input")
    sim.stop_injection("test")
    limit = sim.robot.wheel_torque_limit
    for bad in (np.array([]), np.array([0.1, np.nan]), np.full(10, 1.5 * limit), np.zeros((3, 2))):
        with pytest.raises(Exception, match="non-empty series of finite samples"):
            sim.inject(bad, "input")
    assert not sim.injection.playing


def test_an_injection_is_an_event_as_it_starts_and_as_it_ends(tmp_path: Path):
    """The event log and recordings show what was injected, and how it ended (they showed nothing)."""
    sim = stand()
    ended: list[Injection] = []
    d = excitation(ChirpSpec(f_min=20.0, f_max=100.0, amplitude=0.4, length=0.2))
    with Telemetry(sim, path=tmp_path / "stand.rrd"):
        sim.inject(d, "input", ended.append)
        while not ended:
            sim.step()
        sim.inject(excitation(SPEC), "reference", ended.append, what="a 3 s logarithmic chirp, 2-200 Hz, 1 deg")
        for _ in range(500):
            sim.step()
        sim.reset()
    lines = [
        "injecting a 0.2 s signal, peak 0.4 N m at the wheel torque",
        "injection played: a 0.2 s signal, peak 0.4 N m at the wheel torque",
        "injecting a 3 s logarithmic chirp, 2-200 Hz, 1 deg at the pitch reference",
        "injection stopped after 0.5 s: the stand was reset (user)",
    ]
    assert [e.describe() for e in sim.events if e.kind == EventKind.INJECTION] == lines
    assert len(ended) == 2, "each injection's own done still heard its end"
    recorded = [
        row[0]
        for chunk in RrdReader(tmp_path / "stand.rrd").stream()
        if chunk.entity_path == "/events"
        for row in chunk.to_record_batch().column("TextLog:text").to_pylist()
    ]
    assert [text for text in recorded if text.startswith("injection: ")] == [f"injection: {line}" for line in lines]
