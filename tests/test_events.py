"""Typed events: one kind and one description each, a run number, and falls that say why."""

from __future__ import annotations

import dataclasses

import pytest

from hopper import events as ev
from hopper.config import Gains, SimConfig
from hopper.control import FallCause
from hopper.schedule import KickSchedule
from hopper.sim import Simulation

SAMPLES = [
    ev.Liftoff(0.12),
    ev.Apex(1.3),
    ev.Touchdown(None),
    ev.Fall(FallCause.HIP_HEIGHT, 1.0, 0.3, None),
    ev.Reset("user"),
    ev.GainsChanged(Gains()),
    ev.WheelChanged(False),
    ev.SensingChanged("realistic"),
    ev.GravityChanged(3.72),
    ev.TerrainChanged("crater", 3),
    ev.Disturbance("torque_pulse", 15.0, "N m", 0.1),
    ev.DisturbanceArmed("torque_pulse", 15.0, "N m"),
    ev.Diverged("non-finite state"),
    ev.CommandFailed("Disturb", "ValueError: bad"),
    ev.Recording("started", "/tmp/a.rrd"),
    ev.OperatorChanged("client 2 (127.0.0.1)", "client 1", "handed over"),
    ev.ScheduleChanged(KickSchedule("pitch_kick", 0.3, 0.15, every=2)),
    ev.ScheduleChanged(None),
    ev.Disturbance("pitch_kick", 0.3, "N m s", after_liftoff_s=0.15),
    ev.ControllerChanged("lqr", "LQR", (("q_pitch", 1.0),)),
    ev.ControllerFailed("my.py:Law", "Law returned nan N m, not a finite torque"),
    ev.Restored("keyframe 'mid hop'"),
    ev.Resumed(),
    ev.Injected("a 3 s logarithmic chirp, 1-200 Hz, 2 N m", "input"),
    ev.Injected("a 3 s signal, peak 1 deg", "reference", 1.2, "the stand was reset (user)"),
    ev.Injected("a 3 s signal, peak 1 deg", "reference", 3.0),
]


def test_every_kind_has_a_payload_with_a_one_line_description() -> None:
    assert {payload.kind for payload in SAMPLES} == set(ev.EventKind)
    for payload in SAMPLES:
        text = payload.describe()
        assert text and "\n" not in text and "{" not in text
    assert "Kp 450 N m/rad, Ki 50 N m/(rad s), Kd 30 N m s/rad" in ev.GainsChanged(Gains()).describe()


def test_payloads_are_immutable() -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        SAMPLES[0].momentum = 1.0  # type: ignore[misc]


def test_a_fall_says_what_tripped_it() -> None:
    """Legs that give way fold under an upright torso: a pitch of about 1 deg explains nothing,
    the collapsed hip does. (Earth gravity did this on the first landing before the gait was
    derived from g; here the leg motors are switched off.)"""
    sim = Simulation(SimConfig(terrain="flat", gravity=3.72))
    sim.model.opt.disableactuator |= 1 << 0  # the leg motors' group
    sim.run(1, max_time=5.0)
    fall = sim.events[-1]
    assert fall.kind is ev.EventKind.FALL
    assert fall.payload.cause is FallCause.HIP_HEIGHT and fall.payload.hip_height_m < 0.35
    assert "hip lower than 0.35 m" in fall.describe()


def test_events_carry_the_run_they_belong_to(flat_sim: Simulation) -> None:
    flat_sim.run(1)
    flat_sim.reset()
    flat_sim.disturb("pitch_kick", 0.2)
    runs = [(e.kind, e.run) for e in flat_sim.events]
    assert runs[0] == (ev.EventKind.RESET, 0)
    assert (ev.EventKind.TOUCHDOWN, 0) in runs
    assert runs[-2:] == [(ev.EventKind.RESET, 1), (ev.EventKind.DISTURBANCE, 1)]
