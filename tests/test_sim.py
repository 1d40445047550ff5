"""The whole simulation: hopping, determinism, commands, disturbances, recovery."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hopper import commands
from hopper.config import MOON_GRAVITY, Gains, SimConfig
from hopper.control import FallCause, Phase
from hopper.events import CommandFailed, Disturbance, EventKind, Fall, GainsChanged
from hopper.sim import Simulation


def test_hops_forward_upright_on_flat_ground(flat_sim: Simulation) -> None:
    hops = flat_sim.run(3)
    assert len(hops) == 3 and not flat_sim.fallen
    assert 0.4 < hops[0].distance_m < 1.0  # from a standing start
    for hop in hops:
        assert hop is hops[0] or 0.6 < hop.distance_m < 1.0  # the paper's ~0.8 m
        assert hop.landing_pitch_deg < 3.5
        assert hop.saturation_time_s < 0.9
        # Apex of the hop close to the commanded v_z^2 / 2g (0.25 m minus the push's shortfall).
        assert 0.15 < hop.apex_height_m < 0.3
        # Up to the apex and down again, landing up to 0.15 m lower (legs reach down to land).
        rise, fall = math.sqrt(2 * hop.apex_height_m / 1.625), math.sqrt(2 * (hop.apex_height_m + 0.15) / 1.625)
        assert 2 * rise <= hop.flight_time_s <= rise + fall


def test_same_seed_same_trajectory() -> None:
    config = SimConfig(seed=5, gains=Gains(kp=500, ki=10, kd=25))
    a, b = Simulation(config), Simulation(config)
    for _ in range(4000):
        a.step()
        b.step()
        assert np.array_equal(a.data.qpos, b.data.qpos)
    assert a.hops == b.hops
    c = Simulation(SimConfig(seed=6, gains=config.gains))
    for _ in range(4000):
        c.step()
    # The start pad is level and the same for every seed (the field's fixed scale): the paths part
    # once the feet meet the seed's own ground, beyond x = clear_radius.
    for sim in (a, c):
        for _ in range(6000):
            sim.step()
    assert not np.array_equal(a.data.qpos, c.data.qpos)  # another terrain, another path


def test_wheel_off_lets_the_pitch_run_away() -> None:
    on = Simulation(SimConfig(terrain="flat"))
    off = Simulation(SimConfig(terrain="flat", wheel=False))
    on.run(1)
    off.run(1)
    assert on.hops[0].peak_pitch_deg < 5.0
    assert off.hops[0].peak_pitch_deg > 3 * on.hops[0].peak_pitch_deg
    # Free, not locked: the torso tumbles about a wheel that keeps (most of) its spin in space, so
    # relative to the torso the wheel turns the other way (a locked wheel would read 0 rpm).
    assert off.hops[0].peak_wheel_rpm > 5.0
    assert np.sign(off.data.joint("wheel").qvel[0]) == -np.sign(off.data.joint("pitch").qvel[0]) != 0
    fall = off.events[-1].payload
    assert isinstance(fall, Fall) and fall.cause is FallCause.PITCH_LIMIT and abs(fall.pitch_deg) >= 60


def test_gain_change_applies_on_the_next_tick(flat_sim: Simulation) -> None:
    gains = Gains(kp=123.0, ki=1.0, kd=9.0)
    flat_sim.submit(commands.SetGains(gains))
    assert flat_sim.controller.mem["kp"][0] != 123.0  # queued, not applied from this thread
    flat_sim.step()
    assert flat_sim.gains == gains == flat_sim.config.gains and flat_sim.controller.mem["kp"][0] == 123.0
    assert flat_sim.events[-1].payload == GainsChanged(gains)


def test_the_live_config_follows_every_setting(flat_sim: Simulation) -> None:
    for command in (
        commands.SetGravity(3.72),
        commands.SetWheel(False),
        commands.SetSensing("realistic"),
        commands.SetTerrain("crater", 4),
    ):
        flat_sim.submit(command)
    flat_sim.step()
    c = flat_sim.config
    assert (c.gravity, c.wheel, c.sensing, c.terrain, c.seed) == (3.72, False, "realistic", "crater", 4)
    mem = flat_sim.controller.mem
    assert mem["gravity"][0] == 3.72 and not mem["wheel_on"][0] and mem["realistic"][0]


def test_impulses_change_the_velocities_they_should(flat_sim: Simulation) -> None:
    for _ in range(100):
        flat_sim.step()
    rate = flat_sim.data.joint("pitch").qvel[0]
    flat_sim.disturb("pitch_kick", 0.5)
    assert flat_sim.data.joint("pitch").qvel[0] - rate > 0.3  # rad/s from 0.5 N m s on ~0.5-1 kg m^2
    vx = flat_sim.data.joint("root_x").qvel[0]
    flat_sim.disturb("push_backward", 4.0)
    assert flat_sim.data.joint("root_x").qvel[0] - vx == pytest.approx(-4.0 / 8.2, rel=0.25)
    assert [e.payload for e in list(flat_sim.events)[-2:]] == [
        Disturbance("pitch_kick", 0.5, "N m s"),
        Disturbance("push_backward", 4.0, "N s"),
    ]


def test_a_torque_pulse_waits_for_the_flight(flat_sim: Simulation) -> None:
    flat_sim.disturb("torque_pulse", 5.0)  # on the ground: armed for the next flight
    assert flat_sim.events[-1].kind is EventKind.DISTURBANCE_ARMED
    while not any(e.kind is EventKind.DISTURBANCE for e in flat_sim.events):
        flat_sim.step()
        assert flat_sim.time < 5
    assert flat_sim.phase is Phase.FLIGHT
    assert flat_sim.data.xfrc_applied[flat_sim.model.body("torso").id, 4] == 5.0
    start = flat_sim.time
    while flat_sim.data.xfrc_applied[flat_sim.model.body("torso").id, 4] != 0.0:
        flat_sim.step()
    assert flat_sim.time - start == pytest.approx(0.1, abs=0.002)
    flat_sim.run(2)
    assert not flat_sim.fallen  # the wheel rejects it


@pytest.mark.parametrize("kind, magnitude", [("pitch_kick", float("nan")), ("push_forward", 1e6), ("spin", 1.0)])
def test_bad_disturbances_are_refused(flat_sim: Simulation, kind: str, magnitude: float) -> None:
    with pytest.raises(ValueError):
        flat_sim.disturb(kind, magnitude)  # type: ignore[arg-type]


def test_a_failing_command_is_reported_and_the_loop_goes_on(flat_sim: Simulation) -> None:
    flat_sim.submit(commands.Disturb("pitch_kick", float("inf")))
    flat_sim.step()
    flat_sim.step()
    failed = flat_sim.events[-1].payload
    assert isinstance(failed, CommandFailed) and failed.command == "Disturb" and "pitch_kick" in failed.message


def test_divergence_resets_with_an_event(flat_sim: Simulation) -> None:
    for _ in range(10):
        flat_sim.step()
    flat_sim.data.qvel[0] = np.nan
    for _ in range(60):
        flat_sim.step()
    assert any(e.kind is EventKind.DIVERGED for e in flat_sim.events)
    assert np.isfinite(flat_sim.data.qpos).all() and np.isfinite(flat_sim.data.qvel).all()


def test_terrain_hot_swap_keeps_the_model(flat_sim: Simulation) -> None:
    model = flat_sim.model
    flat_sim.set_terrain("crater", 7)
    assert flat_sim.model is model
    relief = np.ptp(model.hfield_data) * model.hfield_size[0, 2]  # m: data times the elevation
    assert relief > 0.15 and flat_sim.heights.min() < -0.03
    assert flat_sim.events[-1].kind is EventKind.RESET and flat_sim.events[-1].run == 1
    flat_sim.run(1)
    assert len(flat_sim.hops) == 1


def test_gravity_change_changes_the_hop() -> None:
    sim = Simulation(SimConfig(terrain="flat"))
    sim.set_gravity(3.72)  # Mars
    sim.run(1)
    assert sim.model.opt.gravity[2] == -3.72
    assert sim.hops[0].flight_time_s < 0.9  # 1.12 s on the Moon for the same apex


def test_a_gravity_the_legs_cannot_hold_the_robot_at_is_refused_and_changes_nothing(tmp_path: Path) -> None:
    from hopper.model import MODEL_XML

    weak = tmp_path / "weak.xml"  # 10 N m legs: enough on the Moon, not on Earth
    weak.write_text(MODEL_XML.read_text().replace('ctrlrange="-30 30"', 'ctrlrange="-10 10"'))
    sim = Simulation(SimConfig(terrain="flat", model=str(weak)))
    memory = sim.controller.mem.copy()
    sim.submit(commands.SetGravity(9.81))
    sim.step()
    (failed,) = [e.payload for e in sim.events if isinstance(e.payload, CommandFailed)]
    assert "the legs cannot hold the robot at 9.81 m/s^2" in failed.message
    assert sim.config.gravity == MOON_GRAVITY and sim.model.opt.gravity[2] == -MOON_GRAVITY
    for name in ("gravity", "kz", "apex", "vz_liftoff", "push_accel"):  # the controller's memory too
        assert sim.controller.mem[name][0] == memory[name][0], name
    sim.run(2)
    assert len(sim.hops) == 2 and not sim.fallen


def test_the_crater_strip_holds_twenty_hops() -> None:
    sim = Simulation(SimConfig(seed=2))
    sim.run(20)
    assert len(sim.hops) == 20 and not sim.fallen
    craters = sim.config.craters
    assert sim.state().x < craters.x0 + craters.length - 2.0  # still on the strip, with room to spare
    assert max(hop.landing_pitch_deg for hop in sim.hops) < 3.5


def test_the_event_record_keeps_the_newest_and_listeners_see_every_one(flat_sim: Simulation) -> None:
    """A run of days must not grow without end (benchmarks/soak_terrain.py: +8 % RSS in 10,000 hops)."""
    from hopper.events import Touchdown
    from hopper.sim import EVENT_RECORD

    seen = []

    class Count:
        def tick(self, sim: Simulation) -> None:
            pass

        def event(self, sim: Simulation, event: object) -> None:
            seen.append(event)

    flat_sim.listeners.append(Count())
    for _ in range(EVENT_RECORD + 5):
        flat_sim.emit(Touchdown(None))
    assert len(flat_sim.events) == EVENT_RECORD and len(seen) == EVENT_RECORD + 5
    assert flat_sim.events[-1] is seen[-1] and flat_sim.events[0] is seen[5]
