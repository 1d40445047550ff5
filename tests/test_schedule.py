"""The repeatable test: a kick scheduled after every (Nth) liftoff, and the per-hop response metrics."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from numba import njit
from test_sim_cli import hopper_sim
from test_telemetry import cells, read

from hopper.commands import SetSchedule
from hopper.config import Gains, InvalidConfig, SimConfig
from hopper.control import Phase
from hopper.control.kernel import respond
from hopper.control.memory import MEMORY
from hopper.events import Disturbance, EventKind, Liftoff, ScheduleChanged
from hopper.metrics import MetricsTracker
from hopper.schedule import KickSchedule, parse
from hopper.sim import Simulation
from hopper.telemetry import HOP_DECIMALS

DT = 0.001


# -- the schedule's text form and its checks ------------------------------------------------------
@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("pitch_kick:0.3@150ms", KickSchedule("pitch_kick", 0.3, 0.15, 1)),
        ("pitch_kick:-0.5", KickSchedule("pitch_kick", -0.5, 0.15, 1)),
        ("torque_pulse:10@every:3", KickSchedule("torque_pulse", 10.0, 0.15, 3)),
        ("push_forward:2@200ms,every:2", KickSchedule("push_forward", 2.0, 0.2, 2)),
        ("push_backward:1@every:2,0ms", KickSchedule("push_backward", 1.0, 0.0, 2)),
        ("pitch_kick:0.3,every:3", KickSchedule("pitch_kick", 0.3, 0.15, 3)),  # the delay left out of the form
    ],
)
def test_parse_reads_kind_magnitude_delay_and_every(text: str, expected: KickSchedule) -> None:
    assert parse(text) == expected
    assert parse(expected.spec()) == expected  # spec() writes what parse() reads


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("pitch_kick", "expected KIND:MAGNITUDE"),
        ("wobble:1@150ms", "unknown disturbance 'wobble'"),
        ("pitch_kick:lots", "bad schedule magnitude"),
        ("pitch_kick:9@150ms", "pitch_kick magnitude must be a finite number in [-5, 5] N m s"),
        ("pitch_kick:nan", "pitch_kick magnitude must be a finite number"),
        ("pitch_kick:0.3@5000ms", "schedule delay must be a finite number in [0, 2] s"),
        ("pitch_kick:0.3@-1ms", "schedule delay must be a finite number in [0, 2] s"),
        ("pitch_kick:0.3@infms", "bad schedule delay"),
        ("pitch_kick:0.3@every:0", "schedule 'every' must be a whole number of hops in [1, 1000]"),
        ("pitch_kick:0.3@every:x", "bad schedule 'every' 'x'"),
        ("pitch_kick:0.3@soon", "bad schedule part 'soon'"),
        ("pitch_kick:0.3,150ms", "expected KIND:MAGNITUDE"),  # a delay needs its "@"
        ("pitch_kick:0.3,every:2,150ms", "expected KIND:MAGNITUDE"),
    ],
)
def test_bad_schedules_fail_with_one_line(text: str, message: str) -> None:
    with pytest.raises(ValueError) as info:
        parse(text)
    assert message in str(info.value) and "\n" not in str(info.value)


def test_a_bad_schedule_command_is_refused_and_the_simulation_goes_on() -> None:
    with pytest.raises(InvalidConfig):
        KickSchedule("torque_pulse", 31.0)
    sim = Simulation(SimConfig(terrain="flat"))
    sim.submit(SetSchedule("pitch_kick:0.3"))  # type: ignore[arg-type]  # a string, not a KickSchedule
    sim.step()
    assert sim.events[-1].kind is EventKind.COMMAND_FAILED and sim.schedule is None
    sim.step()


# -- the response metrics on a known response ------------------------------------------------------
@njit  # not cached: numba would keep an old kernel.respond while this file is unchanged
def _feed(mem: np.ndarray, times: np.ndarray, pitches: np.ndarray, torques: np.ndarray, speeds: np.ndarray) -> None:
    m = mem[0]
    for i in range(times.size):
        m.pitch_true = pitches[i]
        respond(m, times[i], torques[i], speeds[i])


def test_metrics_of_a_damped_oscillation_match_their_definitions() -> None:
    """p(t) = A e^(-s t) sin(w t) after a kick at 0.2 s: the first peak, the overshoot beyond the
    first zero crossing (A e^(-s t2) sin(w t2) at the second extremum, analytically), the settling
    into 1 deg, the peaks of torque and wheel momentum, and the landing pitch."""
    mem = np.zeros(1, dtype=MEMORY)
    mem["dt"] = DT
    tracker = MetricsTracker(mem)
    tracker.liftoff(1.0, z=1.0, momentum=0.0)
    quiet = 1.0 + DT * np.arange(1, 200)  # before the kick: the residual wobble must not count
    _feed(mem, quiet, np.full(quiet.size, math.radians(2.0)), np.full(quiet.size, 29.5), np.full(quiet.size, 40.0))
    tracker.kicked(1.2)
    amplitude, sigma, omega = math.radians(8.0), 6.0, 20.0
    t = DT * np.arange(1, 700)
    pitch = amplitude * np.exp(-sigma * t) * np.sin(omega * t)
    torque = 12.0 * np.cos(omega * t) * np.exp(-sigma * t)
    speed = -20.0 * np.sin(omega * t)
    _feed(mem, 1.2 + t, pitch, torque, speed)
    hop = tracker.touchdown(1.2 + t[-1] + DT, x=0.8, pitch=float(pitch[-1]))

    def extremum(k: int) -> float:  # |p| at the k-th extremum, tan(w t) = w / s
        te = (math.atan2(omega, sigma) + (k - 1) * math.pi) / omega
        return abs(amplitude * math.exp(-sigma * te) * math.sin(omega * te))

    assert hop.kicked and hop.response_start_s == pytest.approx(0.2)
    assert hop.response_peak_deg == pytest.approx(math.degrees(extremum(1)), rel=1e-3)
    assert hop.overshoot_deg == pytest.approx(math.degrees(extremum(2)), rel=1e-3)
    outside = t[np.abs(pitch) > math.radians(1.0)]
    assert hop.settled and hop.settling_time_s == pytest.approx(outside[-1] + DT)
    assert 0.2 < hop.settling_time_s < 0.4  # the envelope 8 deg e^(-6 t) reaches 1 deg at 0.35 s
    assert hop.peak_wheel_torque_nm == pytest.approx(np.abs(torque).max())  # not the 29.5 before the kick
    capacity_speed = 400 * 2 * math.pi / 60  # the no-load speed: 100 % of the capacity
    assert hop.peak_momentum_pct == pytest.approx(100 * 20.0 / capacity_speed, rel=1e-3)
    assert hop.landing_error_deg == pytest.approx(math.degrees(pitch[-1]))


def test_a_response_still_outside_the_band_at_touchdown_is_not_settled() -> None:
    mem = np.zeros(1, dtype=MEMORY)
    mem["dt"] = DT
    tracker = MetricsTracker(mem)
    tracker.liftoff(0.0, z=1.0, momentum=0.0)  # no kick: measured from the liftoff
    t = DT * np.arange(1, 300)
    pitch = -math.radians(3.0) * t / t[-1]  # drifting away, never crossing zero
    _feed(mem, t, pitch, np.zeros(t.size), np.zeros(t.size))
    hop = tracker.touchdown(0.3, x=0.5, pitch=float(pitch[-1]))
    assert not hop.kicked and hop.response_start_s == 0.0
    assert not hop.settled and hop.settling_time_s == pytest.approx(0.3)  # a lower bound: the flight
    assert hop.overshoot_deg == 0.0 and hop.response_peak_deg == pytest.approx(3.0)
    assert hop.landing_error_deg == pytest.approx(-3.0)


# -- the schedule in the simulation ----------------------------------------------------------------
class Trace:
    """Every tick's true pitch (rad) and time (s), as the kernel saw them."""

    def __init__(self) -> None:
        self.rows: list[tuple[float, float, int]] = []

    def tick(self, sim: Simulation) -> None:
        mem = sim.controller.mem
        self.rows.append((float(mem["clock"][0]) - DT, float(mem["pitch_true"][0]), int(mem["phase"][0])))

    def event(self, sim: Simulation, event: object) -> None:
        pass


def test_the_kick_lands_on_the_tick_delay_after_each_liftoff_and_the_metrics_follow_the_trace() -> None:
    sim = Simulation(SimConfig(terrain="flat", gains=Gains(kp=150.0, ki=0.0, kd=3.0)))  # under-damped
    trace = Trace()
    sim.listeners.append(trace)
    sim.submit(SetSchedule(KickSchedule("pitch_kick", 1.0, 0.15)))
    sim.run(3)
    assert any(isinstance(e.payload, ScheduleChanged) and e.payload.schedule for e in sim.events)
    liftoffs = [e.time for e in sim.events if isinstance(e.payload, Liftoff)]
    kicks = [e for e in sim.events if isinstance(e.payload, Disturbance)]
    assert len(sim.hops) == 3 and len(kicks) == 3 and all(h.kicked for h in sim.hops)
    for liftoff, kick in zip(liftoffs, kicks, strict=True):
        assert kick.time - liftoff == pytest.approx(0.15, abs=1e-9)  # exactly 150 ticks later
        assert kick.payload.after_liftoff_s == pytest.approx(0.15, abs=1e-9)
        assert "scheduled, 150 ms after liftoff" in kick.describe()
    times, pitch, phase = (np.array(c) for c in zip(*trace.rows, strict=True))
    for hop, kick in zip(sim.hops, kicks, strict=True):
        window = (times > kick.time) & (times < hop.touchdown_time_s) & (phase == int(Phase.FLIGHT))
        p = pitch[window]
        start = np.argmax(np.abs(p) > math.radians(0.25))  # the first excursion begins
        sign = np.sign(p[start])
        crossing = start + np.argmax(sign * p[start:] <= 0)
        assert hop.response_peak_deg == pytest.approx(math.degrees(np.max(sign * p[start:crossing])))
        assert hop.overshoot_deg == pytest.approx(math.degrees(np.max(-sign * p[crossing:])))
        assert hop.overshoot_deg > 1.0  # the low damping shows
        assert hop.settling_time_s == pytest.approx(times[window][np.abs(p) > math.radians(1.0)][-1] + DT - kick.time)
        # The kick (62 % of the capacity) and the under-damped swing fill most of the wheel.
        assert 85.0 < hop.peak_momentum_pct <= 100.0 and hop.peak_wheel_torque_nm == pytest.approx(29.5, abs=0.1)


def test_every_third_hop_is_kicked_and_clearing_stops_it() -> None:
    sim = Simulation(SimConfig(terrain="flat"))
    sim.set_schedule(KickSchedule("torque_pulse", 8.0, 0.1, every=3))
    sim.run(6)
    pulses = [e for e in sim.events if isinstance(e.payload, Disturbance)]
    assert [h.kicked for h in sim.hops] == [False, False, True, False, False, True]
    assert [h.response_start_s > 0 for h in sim.hops] == [False, False, True, False, False, True]
    assert len(pulses) == 2 and all(p.payload.duration_s == 0.1 for p in pulses)
    kicked = [h for h in sim.hops if h.kicked]
    for hop, pulse in zip(kicked, pulses, strict=True):
        assert pulse.time < hop.touchdown_time_s and hop.response_start_s == pytest.approx(0.1, abs=1e-9)
    sim.submit(SetSchedule(None))
    sim.run(9)
    assert sim.events[-1].kind is not EventKind.SCHEDULE  # the clear came first, hops after it
    assert any(isinstance(e.payload, ScheduleChanged) and e.payload.schedule is None for e in sim.events)
    assert len([e for e in sim.events if isinstance(e.payload, Disturbance)]) == 2  # hop 9 unkicked
    assert not sim.hops[8].kicked and sim.schedule is None


# -- hopper-sim and its recording ------------------------------------------------------------------
def test_hopper_sim_runs_the_schedule_prints_the_response_and_records_it(tmp_path: Path) -> None:
    out, rrd = tmp_path / "run.json", tmp_path / "run.rrd"
    flags = ["--hops", "3", "--terrain", "flat", "--schedule", "pitch_kick:1@150ms,every:2"]
    result = hopper_sim("run", *flags, "--json", str(out), "--rrd", str(rrd))
    assert result.returncode == 0, result.stderr
    assert "over deg" in result.stdout and "settle s" in result.stdout
    assert "response from the kick (pitch_kick:1@150ms,every:2)" in result.stdout
    data = json.loads(out.read_text())
    assert data["settings"]["schedule"] == "pitch_kick:1@150ms,every:2"
    hops = data["hops"]
    assert [h["kicked"] for h in hops] == [False, True, False]
    kicked = hops[1]
    # 1 N m s swings the torso about 2.8 deg before the wheel and the hips at their limits stop it
    assert kicked["response_start_s"] == pytest.approx(0.15) and kicked["response_peak_deg"] > 2.0
    assert 0.05 < kicked["settling_time_s"] < 0.5 and kicked["settled"] and kicked["peak_momentum_pct"] > 50.0
    assert hops[0]["response_start_s"] == 0.0 and hops[0]["peak_momentum_pct"] < kicked["peak_momentum_pct"]

    tables = read(rrd)  # rerun's own reader
    columns = ("kicked", "response_start_s", "overshoot_deg", "settling_time_s", "settled")
    columns += ("peak_wheel_torque_nm", "peak_momentum_pct", "landing_error_deg", "response_peak_deg")
    for name in columns:
        recorded = cells(tables["hops"], name)
        assert len(recorded) == 3
        expected = [h[name] for h in hops]
        if isinstance(expected[0], bool):
            assert recorded == expected, name
        else:
            assert recorded == pytest.approx(expected, abs=0.5 * 10.0 ** -HOP_DECIMALS[name]), name
    texts = [t for t in cells(tables["events"], "TextLog:text")]
    assert any("schedule: pitch kick +1 N m s, 150 ms after the liftoff of hops 2, 4, 6" in t for t in texts)
    assert any("scheduled, 150 ms after liftoff" in t for t in texts)


def test_hopper_sim_refuses_a_bad_schedule_on_one_line() -> None:
    result = hopper_sim("run", "--schedule", "pitch_kick:0.3@every:0")
    assert result.returncode == 2 and result.stdout == ""
    assert result.stderr.strip().splitlines() == [
        "hopper-sim: error: argument --schedule: schedule 'every' must be a whole number of hops in [1, 1000], got 0"
    ]
