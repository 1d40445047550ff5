"""hopper.logs.replay: a log's commands flown open loop from its state reproduce it on the robot that made it."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from hopper.config import SensingParams, SimConfig
from hopper.logs.capture import capture
from hopper.logs.replay import (
    REANCHOR_S,
    Errors,
    ReplayError,
    Trajectory,
    World,
    errors,
    flights,
    hops,
    poses,
    replay_hops,
    set_state,
    simulate,
    world_model,
)
from hopper.logs.schema import Log
from hopper.mismatch import Nominal

MISMATCH = (("torso_mass", 1.2), ("wheel_inertia", 0.85), ("motor_torque", 0.9))


@pytest.fixture(scope="module")
def log() -> Log:
    config = SimConfig(
        terrain="flat", sensing="realistic", seed=5, mismatch=MISMATCH, sensor=SensingParams(gyro_bias_fixed=0.3)
    )
    return capture(config, 3).log


def robot(mismatch: tuple = ()):  # noqa: ANN201
    model, window = world_model(World())
    Nominal.of(model).apply(model, mismatch)
    return model, window


def test_hops_are_found_from_the_feet(log: Log) -> None:
    found = flights(log)
    assert len(found) == 3
    for a, b in found:
        assert 0.5 < log.time[b] - log.time[a] < 2.0  # a lunar flight of a 0.25 m apex: about 1.1 s
        assert log.signals["foot_L_force"][a:b].max() == 0.0 and log.signals["foot_R_force"][a:b].max() == 0.0
    assert [a for a, _ in hops(log)] == [a for a, _ in found]


def test_the_robot_that_made_the_log_replays_it(log: Log) -> None:
    """From the log's state, the log's commands on the log's robot fly the same hops (bit-near): the
    drive's delay and voltage inversion, the state's reconstruction and the row timing are right."""
    model, window = robot(MISMATCH)
    for _, e in replay_hops(model, log, window=window):
        assert e.rms("pitch") < 1e-6 and e.rms("wheel_speed") < 1e-5
        assert np.abs(e.touchdown).max() == 0.0


def test_the_nominal_robot_does_not(log: Log) -> None:
    model, window = robot()
    a, b = flights(log)[0]
    e = errors(log, simulate(model, log, a, b, window=window))  # the flight alone: the wheel's mismatch
    assert e.rms("pitch") > math.radians(1.0) and e.rms("wheel_speed") > 0.5
    early = errors(log, simulate(model, log, a, a + 50, window=window))
    assert 0.0 < early.rms("pitch") < e.rms("pitch")  # open loop, the error grows


def test_a_replay_of_the_same_span_is_deterministic(log: Log) -> None:
    model, _ = robot()
    a, b = hops(log)[1]
    one, two = simulate(model, log, a, b), simulate(model, log, a, b)
    assert all(np.array_equal(one.signals[k], two.signals[k], equal_nan=True) for k in one.signals)


def test_what_cannot_be_replayed_is_refused(log: Log) -> None:
    model, _ = robot()
    with pytest.raises(ReplayError, match="outside its"):
        simulate(model, log, 10, len(log.time) + 5)
    stateless = Log(log.time, {k: v for k, v in log.signals.items() if k not in ("x", "vz")}, "no_state.csv")
    with pytest.raises(ReplayError, match="no_state.csv: .*has no x, vz column"):
        simulate(model, stateless, 0, 100)
    standing = log.between(0.0, 0.5)
    with pytest.raises(ReplayError, match="no hop"):
        replay_hops(model, standing)


def test_poses_place_the_robot_as_its_state_does(log: Log) -> None:
    """A ghost's qpos rows (every 7th sample) are where set_state puts the robot; a diverged sample
    holds the pose before it."""
    model, _ = robot()
    data = mujoco.MjData(model)
    got = poses(model, log.signals, 7)
    assert got.shape == (len(range(0, len(log.time), 7)), model.nq)
    for i in (0, 100, len(got) - 1):
        set_state(model, data, log, 7 * i)
        assert np.abs(got[i] - data.qpos).max() < 1e-12
    broken = {k: v.copy() for k, v in log.signals.items()}
    broken["pitch"][700:] = np.nan
    held = poses(model, broken, 7)
    assert np.array_equal(held[-1], held[99]) and np.isfinite(held).all()


def test_a_whole_hop_with_the_legs_held_to_the_log_measures_the_torso_and_the_wheel(log: Log) -> None:
    """On the log's torques alone a whole stance is chaotic (friction 0.1 % off: 0.16 deg, 1 %: 4 deg);
    with the legs also held to the log's angles it is not, and the torso and wheel still show whole."""
    pitch = lambda model, servo: math.degrees(  # noqa: E731
        Errors.concat([e for _, e in replay_hops(model, log, servo=servo)]).rms("pitch")
    )
    slightly, _ = robot((*MISMATCH, ("friction", 0.999)))
    percent, _ = robot((*MISMATCH, ("friction", 0.99)))
    heavier, _ = robot((("torso_mass", 1.2 * 1.01), *MISMATCH[1:]))  # the torso 1 % heavier than the log's
    nominal, _ = robot()
    assert pitch(slightly, True) < 0.01 * pitch(slightly, False), (pitch(slightly, True), pitch(slightly, False))
    assert pitch(percent, True) < 0.01 < 1.0 < pitch(percent, False), (pitch(percent, True), pitch(percent, False))
    assert pitch(heavier, True) > 100 * pitch(slightly, True), (pitch(heavier, True), pitch(slightly, True))
    assert pitch(nominal, True) > 1000 * pitch(slightly, True) and pitch(nominal, True) > 10.0
    # The log's own robot: held or not, the same replay to the last digit (the servo has nothing to do).
    own, _ = robot(MISMATCH)
    assert pitch(own, True) < 1e-6 and pitch(own, False) < 1e-6


def test_a_replay_re_anchored_on_the_log_measures_the_model_where_a_whole_stance_drifts_off(log: Log) -> None:
    """The log's own robot with its friction 0.1 % off: whole hops drift off in the open-loop stance,
    re-anchored every REANCHOR_S they stay near; the wrong wheel and torso are wrong either way."""
    whole = lambda model: Errors.concat([e for _, e in replay_hops(model, log)]).rms("pitch")  # noqa: E731
    anchored = lambda model: Errors.concat(  # noqa: E731
        [e for _, e in replay_hops(model, log, every=REANCHOR_S)]
    ).rms("pitch")
    slightly, _ = robot((*MISMATCH, ("friction", 0.999)))
    nominal, _ = robot()
    assert anchored(slightly) < 0.1 * whole(slightly), (anchored(slightly), whole(slightly))
    assert anchored(nominal) > 10 * anchored(slightly), (anchored(nominal), anchored(slightly))
    # Each window starts from the log's state: its first sample is the log's.
    parts = replay_hops(nominal, log, 1, every=REANCHOR_S)
    a, b = hops(log)[0]
    assert [p.first for p, _ in parts] == list(range(a, b, round(REANCHOR_S / log.period)))
    assert all(e.pitch[0] == 0.0 for _, e in parts)
    with pytest.raises(ReplayError, match="every positive number of seconds"):
        replay_hops(nominal, log, every=0.0)


def test_a_robot_with_its_own_wheel_motor_replays_its_own_log(tmp_path) -> None:  # noqa: ANN001
    """A --model robot's controller makes its commands for its own motor: the log's world records that
    motor and the replay's drive inverts it. It had inverted the packaged motor: 10 deg RMS re-anchored."""
    import variants

    from hopper.logs.world import resolve

    path = str(variants.motor_constant(tmp_path, 0.85))
    log = capture(SimConfig(terrain="flat", sensing="realistic", seed=5, model=path), 2).log
    assert log.world.drive.wheel_torque_limit == pytest.approx(0.85 * 29.5, rel=1e-4)
    world, _ = resolve(log.world, model=path)
    model, window = world_model(world)
    for every in (None, REANCHOR_S):
        parts = replay_hops(model, log, window=window, delay_ticks=world.command_delay, drive=world.drive, every=every)
        e = Errors.concat([e for _, e in parts])
        assert e.rms("pitch") < 1e-6 and e.rms("wheel_speed") < 1e-5, (every, e.rms("pitch"))
    # The packaged model, driven as this robot's drive was, is a motor 1/0.85 as strong: it shows.
    packaged, window = world_model(resolve(log.world)[0])
    a, b = flights(log)[0]
    flight = errors(log, simulate(packaged, log, a, b, window=window, drive=world.drive))
    assert flight.rms("pitch") > math.radians(1.0)


def gapped(log: Log, start: int = 2000, stop: int = 2500) -> Log:
    """`log` without rows start..stop-1 (in hop 1's flight), its gap marked as a reader marks it."""
    from hopper.logs.schema import find_gaps

    keep = np.ones(len(log.time), bool)
    keep[start:stop] = False
    time = log.time[keep]
    return Log(time, {k: v[keep] for k, v in log.signals.items()}, "gap.csv", find_gaps(time), log.world)


def test_a_replay_never_flies_across_a_gap(log: Log) -> None:
    """A log with 0.5 s missing in hop 1's flight replayed straight through it (32 deg RMS), silently."""
    from hopper.logs import gaps

    holed = gapped(log)
    assert len(holed.gaps) == 1
    model, window = robot(MISMATCH)
    hop = hops(holed)[0]
    with pytest.raises(
        ReplayError, match=r"gap.csv: a replay of .* reads across a gap \(1.999-2.500 s without samples\)"
    ):
        simulate(model, holed, *hop)
    cut = replay_hops(model, holed, every=REANCHOR_S, window=window)
    assert [p.first for p, _ in cut].count(2000 + gaps.LEAD) == 1  # a window starts again past the gap
    assert all(not gaps.crossed(holed, (p.first, p.first + len(p.time))) for p, _ in cut)
    assert Errors.concat([e for _, e in cut]).rms("pitch") < 1e-6
    whole = replay_hops(model, holed, window=window)  # the hop holding the gap is left out, the others scored
    assert [p.first for p, _ in whole] == [a for a, _ in hops(holed)[1:]]
    assert Errors.concat([e for _, e in whole]).rms("pitch") < 1e-6
    assert gaps.note(holed, "hop 1", hop, whole=True) == (
        f"hop 1 ({holed.time[hop[0]]:.3f}-{holed.time[hop[1] - 1]:.3f} s) holds a gap, 0.501 s without samples "
        "(1.999-2.500 s): not scored"
    )
    with pytest.raises(ReplayError, match="each hop asked holds a gap"):
        replay_hops(model, holed, 1)


def test_a_touchdown_the_replay_missed_is_counted_missed_not_matched_a_hop_away(log: Log) -> None:
    """Each logged touchdown took the nearest simulated one anywhere: a replay that stayed in the air
    through a stance matched that touchdown with the next hop's, and read over a second late."""
    (a1, b1), (a2, b2), (_, b3) = flights(log)
    k = slice(a1, len(log.time))
    signals = {name: log.signals[name][k].copy() for name in ("pitch", "wheel_speed", "foot_L_force", "foot_R_force")}
    for foot in ("foot_L_force", "foot_R_force"):
        signals[foot][b1 - a1 : a2 - a1] = 0.0  # the first stance missed: one long flight to the second touchdown
    e = errors(log, Trajectory(a1, log.time[k].copy(), signals))
    assert np.isnan(e.touchdown[0]) and e.touchdown[1:].tolist() == [0.0, 0.0], e.touchdown
    assert e.timing() == "0 ms mean |touchdown error| over 2 (1 missed)"
    assert log.time[b2] - log.time[b1] > 1.0  # what the old matching read for the first
    assert Errors.concat([e, e]).timing().endswith("over 4 (2 missed)") and b3 > b2
