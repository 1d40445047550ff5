"""Snapshots, re-fly and keyframes on the real model: restores are bit-identical, bad files refused."""

from __future__ import annotations

import base64
import dataclasses
import json
import math

import numpy as np
import pytest

from hopper import keyframes
from hopper.config import Gains, SimConfig
from hopper.control.memory import MEMORY
from hopper.history import RING_PERIOD_S, RING_SPAN_S, History, fly
from hopper.schedule import KickSchedule
from hopper.sim import Simulation


def _state(sim: Simulation) -> list[bytes]:
    """qpos, qvel, act, ctrl, time and every field of the controller memory, as raw bytes."""
    d, mem = sim.data, sim.controller.mem
    return [d.qpos.tobytes(), d.qvel.tobytes(), d.act.tobytes(), d.ctrl.tobytes(), np.float64(d.time).tobytes()] + [
        mem[name].tobytes() for name in MEMORY.names
    ]


def _trace(sim: Simulation, ticks: int) -> bytes:
    out = np.empty(ticks)
    for i in range(ticks):
        sim.step()
        out[i] = sim.data.qpos[sim.layout.q_pitch]
    return out.tobytes()


@pytest.fixture(scope="module")
def flown() -> tuple[Simulation, History]:
    """Realistic sensing (IMU noise from the kernel's RNG, motor delay) through two hops."""
    sim = Simulation(SimConfig(sensing="realistic"))
    history = History()
    sim.listeners.append(history)
    sim.run(2)
    assert history.last_flight is not None and len(sim.hops) == 2
    return sim, history


def test_refly_with_the_recorded_gains_repeats_the_flight_bit_for_bit(flown):
    sim, history = flown
    recorded = history.last_flight
    assert recorded.hop == sim.hops[-1] and len(recorded.pitch) > 500  # the whole ~1 s flight, per tick
    before = fly(recorded.start)
    assert before.pitch.tobytes() == recorded.pitch.tobytes()
    assert before.torque.tobytes() == recorded.torque.tobytes()
    assert dataclasses.replace(before.hop, index=recorded.hop.index) == recorded.hop
    assert sim.hops[-1] is recorded.hop  # the live simulation was not touched


def test_refly_repeats_a_scheduled_kick():
    """Under the repeatable test's schedule, the re-flown flight gets the same kick at the same tick."""
    sim = Simulation(SimConfig(terrain="flat"))
    history = History()
    sim.listeners.append(history)
    sim.set_schedule(KickSchedule("pitch_kick", 1.0, 0.15))  # N m s: shows above 0.5 deg with the legs' share
    kicks = []
    sim.listeners.append(_Kicks(kicks))
    while len(sim.hops) < 2:
        sim.step()
    recorded = history.last_flight
    assert kicks and kicks[-1] > recorded.start.time  # the last flight was kicked
    before = fly(recorded.start)
    assert before.pitch.tobytes() == recorded.pitch.tobytes()
    assert np.abs(before.pitch).max() > np.radians(0.5)  # the kick shows


class _Kicks:
    def __init__(self, times: list[float]) -> None:
        self.times = times

    def tick(self, sim: Simulation) -> None:
        pass

    def event(self, sim: Simulation, event) -> None:
        if event.kind == "disturbance":
            self.times.append(event.time)


def test_refly_with_other_gains_flies_differently(flown):
    _, history = flown
    recorded = history.last_flight
    stiffer = Gains(kp=1200.0, ki=50.0, kd=60.0)
    after = fly(recorded.start, stiffer)
    assert after.gains == stiffer and recorded.gains == Gains()
    n = min(len(after.pitch), len(recorded.pitch))
    assert np.abs(after.pitch[:n] - recorded.pitch[:n]).max() > 1e-5
    assert after.summary()["peak_torque_nm"] != recorded.summary()["peak_torque_nm"]
    assert len(after.poses) >= n // 10  # the ghost's frames


def test_ring_holds_the_span_and_its_memory_is_small():
    sim = Simulation(SimConfig(terrain="flat"))
    history = History(span=3.0)
    sim.listeners.append(history)
    for _ in range(4000):
        sim.step()
    assert len(history.ring) == 30 and history.span == pytest.approx(2.9)
    assert history.ring[-1].time - history.ring[0].time == pytest.approx(2.9, abs=2e-3)
    per_snapshot = history.ring[-1].nbytes
    assert per_snapshot < 4096, per_snapshot
    full = History()
    assert full.ring.maxlen * RING_PERIOD_S >= 30.0 and RING_SPAN_S >= 30.0
    assert full.ring.maxlen * per_snapshot < 2_000_000  # the default 40 s ring: under 2 MB of arrays


def test_restoring_a_ring_entry_resumes_exactly():
    sim = Simulation(SimConfig(terrain="flat", sensing="realistic"))
    history = History()
    sim.listeners.append(history)
    for _ in range(2600):
        sim.step()
    snap = history.at(1.0)
    assert snap.time == pytest.approx(history.ring[-1].time - 1.0, abs=0.0015) and sim.time - snap.time < 1.11
    replay = Simulation(SimConfig(terrain="flat", sensing="realistic"))
    replay.restore(snap)
    expected = _trace(replay, 1500)
    sim.restore(snap)
    history.rewound(snap)
    assert _trace(sim, 1500) == expected
    assert history.ring[-1].time > snap.time and all(
        a.time < b.time for a, b in zip(list(history.ring)[:-1], list(history.ring)[1:], strict=True)
    )


def test_keyframe_round_trip_is_bit_identical():
    sim = Simulation(SimConfig(sensing="realistic"))
    for _ in range(2700):  # mid-push or in flight: a state with everything moving
        sim.step()
    saved = _state(sim)
    text = keyframes.to_json(keyframes.save(sim, "mid hop"))
    continuation = _trace(sim, 800)
    sim.reset()
    sim.set_gains(Gains(kp=900.0, ki=0.0, kd=40.0))
    assert _state(sim) != saved
    keyframe = keyframes.from_json(text, sim)
    keyframes.apply(sim, keyframe)
    assert keyframe.name == "mid hop" and sim.gains == Gains()
    assert _state(sim) == saved
    assert _trace(sim, 800) == continuation


def _strict(text: str) -> dict:
    """`text` read as jq and JavaScript's JSON.parse read it: Infinity, -Infinity and NaN are refused."""

    def refuse(constant: str) -> None:
        raise ValueError(f"{constant} is not JSON")

    return json.loads(text, parse_constant=refuse)


def test_an_exported_keyframe_is_strict_json_and_reads_back(flat_sim: Simulation) -> None:
    """A pending time that never comes (no pulse, no kick: inf) was written as the extension
    Infinity, which strict readers refuse; it is null now, and null reads back as never."""
    flat_sim.run(1)
    keyframe = keyframes.save(flat_sim, "k")
    pending = dataclasses.asdict(keyframe.snapshot.pending)
    assert pending["pulse_at"] == pending["kick_at"] == math.inf  # nothing scheduled
    doc = _strict(keyframes.to_json(keyframe))
    assert doc["version"] == 4 and doc["pending"]["pulse_at"] is None and doc["pending"]["kick_at"] is None
    back = keyframes.from_json(json.dumps(doc), flat_sim)
    assert dataclasses.asdict(back.snapshot.pending) == pending


def test_a_keyframe_exported_with_infinity_before_version_4_still_imports(flat_sim: Simulation) -> None:
    flat_sim.run(1)
    doc = _doc(flat_sim)
    doc["version"] = 3
    doc["pending"] = {k: math.inf if v is None else v for k, v in doc["pending"].items()}
    text = json.dumps(doc)  # as version 3 wrote it
    assert '"pulse_at": Infinity' in text
    pending = keyframes.from_json(text, flat_sim).snapshot.pending
    assert dataclasses.asdict(pending) == dataclasses.asdict(flat_sim.snapshot().pending)


@pytest.mark.parametrize(
    "name, taken, expected",
    [
        ("mid hop", set(), "mid hop"),
        ("mid hop", {"mid hop"}, "mid hop (2)"),
        ("mid hop", {"mid hop", "mid hop (2)"}, "mid hop (3)"),
        ("mid hop (2)", {"mid hop", "mid hop (2)"}, "mid hop (3)"),  # a copy of the copy
        ("x" * keyframes.MAX_NAME, {"x" * keyframes.MAX_NAME}, "x" * (keyframes.MAX_NAME - 4) + " (2)"),
    ],
)
def test_a_taken_keyframe_name_gets_the_next_free_number(name: str, taken: set[str], expected: str) -> None:
    assert keyframes.unique_name(name, taken) == expected
    assert keyframes.check_name(expected) == expected


def _doc(sim: Simulation) -> dict:
    return json.loads(keyframes.to_json(keyframes.save(sim, "k")))


@pytest.mark.parametrize(
    "damage, message",
    [
        (lambda d: "{ not json", "invalid JSON"),
        (lambda d: json.dumps(d)[:-40], "invalid JSON"),
        (lambda d: json.dumps({**d, "format": "x"}), "not a keyframe file"),
        (lambda d: json.dumps({**d, "version": 99}), "version"),
        (
            lambda d: json.dumps(_with_state(d, physics=d["state"]["physics"][:8] + "!!" + d["state"]["physics"][10:])),
            "base64",
        ),
        (lambda d: json.dumps(_with_state(d, physics=_flip(d["state"]["physics"]))), "checksum"),
        (lambda d: json.dumps(_resized(d)), "does not fit this model"),
        (lambda d: json.dumps({**d, "config": {**d["config"], "gravity": -3}}), "gravity"),
        (lambda d: json.dumps({**d, "name": ""}), "name"),
    ],
)
def test_bad_keyframe_files_are_refused_and_change_nothing(flat_sim, damage, message):
    for _ in range(300):
        flat_sim.step()
    text = damage(_doc(flat_sim))
    before = _state(flat_sim)
    with pytest.raises(keyframes.KeyframeError, match=message):
        keyframes.from_json(text, flat_sim)
    assert _state(flat_sim) == before


def _with_state(doc: dict, **state: object) -> dict:
    return {**doc, "state": {**doc["state"], **state}}


def _flip(text: str) -> str:
    raw = bytearray(base64.b64decode(text))
    raw[20] ^= 0x01
    return base64.b64encode(bytes(raw)).decode()


def _resized(doc: dict) -> dict:
    """A state one value longer, with a checksum that matches it: a keyframe from another model."""
    st = doc["state"]
    physics = base64.b64decode(st["physics"]) + np.float64(0.0).tobytes()
    sensors, memory = base64.b64decode(st["sensors"]), base64.b64decode(st["memory"])
    digest = keyframes._digest(physics, sensors, memory)
    return _with_state(doc, physics=base64.b64encode(physics).decode(), sha256=digest)
