"""The Simulation owns its state: snapshot() / restore() carry every field, with none named by hand."""

from __future__ import annotations

import dataclasses
import json
import math

from hopper import keyframes
from hopper.config import SimConfig
from hopper.control import Phase
from hopper.metrics import HopInProgress
from hopper.schedule import KickSchedule
from hopper.sim import Simulation
from hopper.snapshot import Pending


def test_every_field_of_the_loop_state_and_the_hop_in_progress_round_trips(flat_sim: Simulation) -> None:
    """Distinct values in every field of Pending and HopInProgress come back from a snapshot, new
    fields included: restore() copies the dataclasses whole."""
    sim = flat_sim
    for i, f in enumerate(dataclasses.fields(Pending)):
        setattr(sim.pending, f.name, 100.0 + i)
    for i, f in enumerate(dataclasses.fields(HopInProgress)):
        setattr(sim.metrics.progress, f.name, 200.0 + i)
    snap = sim.snapshot()
    expected = dataclasses.asdict(sim.pending), dataclasses.asdict(sim.metrics.progress)
    sim.pending, sim.metrics.progress = Pending(), HopInProgress()
    sim.restore(snap)
    assert (dataclasses.asdict(sim.pending), dataclasses.asdict(sim.metrics.progress)) == expected
    sim.pending.kick_at = -1.0
    assert snap.pending.kick_at == 100.0 + 3, "the snapshot holds a copy, not the live state"


def _to_touchdown(sim: Simulation) -> dict:
    hops = len(sim.hops)
    while len(sim.hops) == hops and not sim.fallen:
        sim.step()
    return sim.hops[-1].as_dict()


def test_a_restore_mid_flight_after_a_kick_measures_the_response_from_the_kick() -> None:
    """The hop in progress is restored whole: the kick's time, which the metrics measure the
    response from, was left out before (a restored kicked flight read as unkicked)."""
    sim = Simulation(SimConfig(terrain="flat"))
    sim.set_schedule(KickSchedule("pitch_kick", 0.3, delay_s=0.15))
    sim.run(1)
    while not (sim.phase is Phase.FLIGHT and sim.metrics.progress.response_start is not None):
        sim.step()
    for _ in range(100):
        sim.step()
    snap = sim.snapshot()
    original = _to_touchdown(sim)
    other = Simulation(SimConfig(terrain="flat"))
    other.restore(snap)
    again = _to_touchdown(other)
    assert original["kicked"] and again == original


def test_a_version_1_keyframe_file_still_reads_into_the_named_fields(flat_sim: Simulation) -> None:
    sim = flat_sim
    sim.run(1)
    doc = json.loads(keyframes.to_json(keyframes.save(sim, "now")))
    assert doc["version"] == 4 and set(doc["pending"]) == {f.name for f in dataclasses.fields(Pending)}
    p, h = doc.pop("pending"), doc.pop("progress")
    p = {k: math.inf if v is None else v for k, v in p.items()}  # never: null from version 4, inf before
    doc.pop("terrain_first")
    doc["version"] = 1  # the same state as the first format wrote it
    doc["pulse"] = [p["pulse_armed"], p["pulse_magnitude"], p["pulse_at"]]
    doc["kick"] = [p["kick_at"], p["liftoff_at"]]
    doc["metrics"] = {f"_{k}": v for k, v in h.items() if k != "response_start"}
    old = keyframes.from_json(json.dumps(doc), sim)
    assert dataclasses.asdict(old.snapshot.pending) == p
    assert dataclasses.asdict(old.snapshot.progress) == h | {"response_start": None}
