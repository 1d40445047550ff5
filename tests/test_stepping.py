"""Compiled ticks (hopper.stepping) against Python's, bit for bit; the raw mj_step against the bindings'."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from hopper.config import SimConfig
from hopper.mujoco_compat import address, mj_step
from hopper.schedule import KickSchedule
from hopper.sim import Simulation

PYTHON_LAW = """
from hopper.laws.pid import PaperPID

class PythonPID(PaperPID):
    compiled = None  # the paper's law through the API: every flight tick comes back to Python
"""


class Every:
    """A listener that wants every tick (no idle_until): it counts them."""

    def __init__(self) -> None:
        self.ticks = 0

    def tick(self, sim: Simulation) -> None:
        self.ticks += 1

    def event(self, sim: Simulation, event: object) -> None:
        pass


class Sampler:
    """A listener idle between samples every 7 ms of simulated time, as the dashboard's plots are."""

    def __init__(self) -> None:
        self.next = 0.0
        self.times: list[float] = []

    def idle_until(self, sim: Simulation) -> float:
        return self.next

    def tick(self, sim: Simulation) -> None:
        if sim.data.time < self.next:
            return
        self.times.append(sim.data.time)
        self.next = sim.data.time + 0.007

    def event(self, sim: Simulation, event: object) -> None:
        pass


def test_the_raw_mj_step_is_the_bindings_step_to_the_bit() -> None:
    """The contract of hopper.mujoco_compat: the same structs (the addresses are the bindings' own),
    the same function; a contact-rich state so the step does real work."""
    sim = Simulation(SimConfig(seed=3))
    sim.run(1)
    a, b = mujoco.MjData(sim.model), mujoco.MjData(sim.model)
    for d in (a, b):
        mujoco.mj_copyData(d, sim.model, sim.data)
    for _ in range(200):
        mujoco.mj_step(sim.model, a)
        mj_step(address(sim.model), address(b))
    assert b.time == a.time and np.array_equal(b.qpos, a.qpos) and np.array_equal(b.qvel, a.qvel)
    assert np.array_equal(b.sensordata, a.sensordata) and b.ncon == a.ncon > 0


def _tick_by_tick(sim: Simulation, hops: int) -> None:
    """What Simulation.run did before compiled bursts: one step() at a time."""
    while len(sim.hops) < hops and not sim.fallen:
        sim.step()


def _same(a: Simulation, b: Simulation) -> None:
    assert a.ticks == b.ticks and a.data.time == b.data.time
    assert np.array_equal(a.data.qpos, b.data.qpos) and np.array_equal(a.data.qvel, b.data.qvel)
    assert np.array_equal(a.controller.mem, b.controller.mem)
    assert [(e.time, e.kind) for e in a.events] == [(e.time, e.kind) for e in b.events]
    assert a.hops == b.hops


@pytest.mark.parametrize("sensing", ["ideal", "realistic"])
def test_run_in_bursts_is_step_by_step_to_the_bit(sensing: str) -> None:
    """A kick schedule and a torque pulse (pending actions at their exact tick), an idle listener's
    samples, a gravity change mid-run (a command); against one step() a tick."""
    runs = []
    for bursts in (True, False):
        sim = Simulation(SimConfig(seed=2, sensing=sensing, gravity=3.71))
        sim.set_schedule(KickSchedule("pitch_kick", 0.3, delay_s=0.15, every=2))
        sim.disturb("torque_pulse", 2.0)
        sampler = Sampler()
        sim.listeners.append(sampler)
        if bursts:
            sim.run(3)
            sim.set_gravity(1.62)
            sim.run(5)
        else:
            _tick_by_tick(sim, 3)
            sim.set_gravity(1.62)
            _tick_by_tick(sim, 5)
        runs.append((sim, sampler))
    (a, sa), (b, sb) = runs
    _same(a, b)
    assert sa.times == sb.times and len(sa.times) > 1000
    assert float(a.controller.mem["clock"][0]) == a.data.time  # what the bursts compare their times on
    assert sum(h.kicked for h in a.hops) >= 2 and any(e.kind == "disturbance" for e in a.events)


def test_a_python_controller_and_a_listener_of_every_tick_still_see_every_tick(tmp_path: Path) -> None:
    """A Python law brings every flight tick back to Python, a listener without idle_until every tick."""
    law = tmp_path / "pylaw.py"
    law.write_text(PYTHON_LAW)
    runs = []
    for bursts in (True, False):
        sim = Simulation(SimConfig(seed=1, controller=f"{law}:PythonPID"))
        every = Every()
        sim.listeners.append(every)
        start = sim.ticks
        sim.run(3) if bursts else _tick_by_tick(sim, 3)
        assert every.ticks == sim.ticks - start
        runs.append(sim)
    _same(*runs)


def test_advance_stops_after_the_first_tick_with_events() -> None:
    sim = Simulation(SimConfig(terrain="flat"))
    taken, events = sim.advance(100_000)
    assert events and 0 < taken < 100_000 and sim.ticks == taken
    assert sim.advance(0) == (0, 0)
    taken, events = sim.advance(3)  # a liftoff's events are hundreds of ticks apart
    assert (taken, events) == (3, 0) and not math.isnan(sim.time)


def test_the_history_records_the_same_flights_and_ring_in_bursts() -> None:
    """History is idle in flight but for its trace, which the compiled ticks write (flight_trace)."""
    from hopper.history import History

    runs = []
    for bursts in (True, False):
        sim = Simulation(SimConfig(seed=4))
        history = History()
        sim.listeners.append(history)
        sim.run(4) if bursts else _tick_by_tick(sim, 4)
        runs.append((sim, history))
    (a, ha), (b, hb) = runs
    _same(a, b)
    fa, fb = ha.last_flight, hb.last_flight
    assert fa is not None and len(fa.pitch) > 100
    assert np.array_equal(fa.pitch, fb.pitch) and np.array_equal(fa.torque, fb.torque)
    assert [s.time for s in ha.ring] == [s.time for s in hb.ring] and len(ha.ring) > 3
