"""A log's world (where it was recorded) written, read back, refused when bad, and replayed in by default."""

from __future__ import annotations

import json
import math
import zipfile
from pathlib import Path

import bad_logs
import numpy as np
import pytest
from hopper.app.dashboard.panels.logreplay import replay_log, summary_html
from hopper.app.dashboard.terrain_view import terrain_glb
from hopper.app.sim_cli import main

from hopper.config import SimConfig
from hopper.errors import ModelError
from hopper.logs import mcap_log, npz
from hopper.logs.capture import capture
from hopper.logs.io import read_log, write_log
from hopper.logs.schema import Log
from hopper.logs.world import World, motor_of, resolve
from hopper.model import terrain_window
from hopper.robot import PACKAGED

# realistic sensing: 3 ms late; the commands made for the packaged motor
WORLD = World(terrain="crater", seed=5, gravity=1.625, delay_ticks=3, wheel_motor=motor_of(PACKAGED))


@pytest.fixture(scope="module")
def cratered() -> Log:
    """Three hops on crater seed 5 (by the third the ground is far from flat), sensed as capture's CLI
    does: the replay's drive delays the commands as the realistic sensing's motor does."""
    got = capture(SimConfig(terrain="crater", seed=5, sensing="realistic"), 3)
    assert got.hops == 3
    return got.log


def test_capture_knows_its_world_and_npz_mcap_keep_it(cratered: Log, tmp_path: Path) -> None:
    assert cratered.world == WORLD
    for suffix in ("npz", "mcap"):
        assert read_log(write_log(cratered, tmp_path / f"log.{suffix}")).world == WORLD
    # A CSV has one header line, the columns: it names no world (the flags or the dashboard do).
    assert read_log(write_log(cratered, tmp_path / "log.csv")).world is None
    assert cratered.between(1.0, 2.0).world == WORLD


def test_a_bad_world_is_refused_in_one_line(cratered: Log, tmp_path: Path) -> None:
    good = write_log(cratered.between(0.0, 0.5), tmp_path / "good.npz")
    bad = tmp_path / "bad.npz"
    with zipfile.ZipFile(good) as src, zipfile.ZipFile(bad, "w") as dst:
        for item in src.namelist():
            if item != "world.npy":
                dst.writestr(item, src.read(item))
    with np.load(good) as archive:
        arrays = {k: archive[k] for k in archive.files}
    arrays["world"] = np.array(json.dumps({"terrain": "lava", "seed": "5", "gravity": "1.625"}))
    with bad.open("wb") as out:
        np.savez_compressed(out, **arrays)
    assert "terrain is 'lava', expected one of flat, crater" in bad_logs.refused(npz.read, bad)
    arrays["world"] = np.array(json.dumps({"terrain": "flat", "seed": "0", "gravity": "-3"}))
    with bad.open("wb") as out:
        np.savez_compressed(out, **arrays)
    assert "gravity > 0 m/s^2" in bad_logs.refused(npz.read, bad)
    wrong = Log(cratered.time[:100], {k: v[:100] for k, v in cratered.signals.items()}, "t", (), World(seed=2))
    path = mcap_log.write(wrong, tmp_path / "seed.mcap")
    assert mcap_log.read(path).world == World(seed=2)
    for delay in ("-1", "17", "3.5", "three"):  # the kernel's delay line holds 0..16 ticks
        arrays["world"] = np.array(json.dumps({"terrain": "flat", "seed": "0", "gravity": "1", "delay_ticks": delay}))
        with bad.open("wb") as out:
            np.savez_compressed(out, **arrays)
        assert f"delay_ticks must be a whole number 0..16, got {delay!r}" in bad_logs.refused(npz.read, bad)


def test_the_world_is_the_flags_then_the_logs_then_the_defaults() -> None:
    assert resolve(WORLD) == (WORLD, "the log's")
    world, origin = resolve(WORLD, terrain="flat", model="robot.xml")
    assert world == World(
        terrain="flat", seed=5, gravity=1.625, model="robot.xml", delay_ticks=3, wheel_motor=motor_of(PACKAGED)
    )
    assert origin == "as asked (terrain); the log's is crater seed 5, 1.625 m/s^2, wheel commands 3 ticks late"
    assert resolve(WORLD, delay_ticks=0)[0].command_delay == 0
    with pytest.raises(ValueError, match="0..16 ticks, got 20"):
        resolve(WORLD, delay_ticks=20)
    assert World().command_delay == 3  # a log that does not say: realistic sensing's
    assert resolve(None) == (World(), "the log names no world: the defaults")
    # The log's robot is the one compared with, never the model replayed; its motor is the drive's.
    truth = World(model="truth.xml", wheel_motor=(25.0, 0.5))
    assert resolve(truth)[0].model is None and resolve(truth)[0].drive.wheel_torque_limit == 25.0
    assert resolve(truth)[0].drive.wheel_damping == pytest.approx(0.5)
    # A log written before the motor was recorded: its robot's MJCF says, and must be there to.
    with pytest.raises(ModelError, match="the log's robot, whose wheel motor its commands were made for: .*truth.xml"):
        resolve(World(model="truth.xml"))
    assert resolve(World(model="truth.xml"), drive="packaged")[0].wheel_motor == motor_of(PACKAGED)


def test_the_cli_and_the_dashboard_replay_in_the_logs_world(cratered: Log, tmp_path: Path, capsys) -> None:  # noqa: ANN001
    path = write_log(cratered, tmp_path / "crater.npz")
    assert main(["replay", str(path)]) == 0
    out = capsys.readouterr().out
    assert "world: crater seed 5, 1.625 m/s^2, wheel commands 3 ticks late (the log's)" in out
    assert "all (3 replay(s)" in out and "pitch RMS 0.000 deg" in out.splitlines()[-1]
    assert main(["replay", str(path), "--terrain", "flat"]) == 0  # the wrong ground, asked for: it shows
    flat = capsys.readouterr().out.splitlines()[-1]
    assert float(flat.split("pitch RMS ")[1].split()[0]) > 1.0, flat
    # The dashboard stands on other ground; the log's world is used, and the same errors come out.
    done = replay_log(str(path), SimConfig(terrain="flat", seed=0))
    assert done.world == "crater seed 5, 1.625 m/s^2, wheel commands 3 ticks late (the log's)"
    assert math.degrees(done.errors.rms("pitch")) < 1e-3 and done.errors.rms("wheel_speed") < 1e-3
    # The ghosts are drawn on the log's ground: its field's tiles under the whole track, not the dashboard's.
    log_field = terrain_window(resolve(cratered.world)[0].config()).field
    tile = log_field.params.tile
    assert min(done.ground) * tile < done.track[:, 0].min() and done.track[:, 0].max() < (max(done.ground) + 1) * tile
    k = int(done.track[0, 0] // tile)
    assert done.ground[k] == terrain_glb(log_field, k) != terrain_glb(terrain_window(SimConfig(seed=0)).field, k)
    # A log that names no world (a CSV, a real robot's) replays in the dashboard's.
    csv = write_log(cratered, tmp_path / "crater.csv")
    here = replay_log(str(csv), SimConfig(terrain="crater", seed=5))
    assert (
        here.world == "crater seed 5, 1.625 m/s^2, wheel commands 3 ticks late (the log names none: this dashboard's)"
    )
    assert math.degrees(here.errors.rms("pitch")) < 1e-3
    # Re-anchored (the panel's checkbox): the same hops, in windows each from the log's state.
    windows = replay_log(str(path), SimConfig(), every=0.3)
    assert windows.shown == done.shown == 3 and len(windows.parts) > 3 * len(done.parts)
    assert windows.logged.shape == done.logged.shape == windows.simulated.shape
    assert "3 hop(s) re-anchored every 0.3 s" in summary_html(windows)


def test_a_log_carries_its_command_delay_and_a_replay_uses_it(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    """Ideal sensing sends the wheel's commands at once: its log says so, and replays exactly without
    --delay-ticks (it had replayed 3 ticks late, the realistic default, unless told)."""
    ideal = capture(SimConfig(terrain="flat", sensing="ideal"), 2).log
    assert ideal.world is not None and ideal.world.delay_ticks == 0
    path = write_log(ideal, tmp_path / "ideal.mcap")
    assert read_log(path).world == ideal.world
    assert main(["replay", str(path)]) == 0
    out = capsys.readouterr().out
    assert "wheel commands 0 ticks late (the log's)" in out.splitlines()[0], out
    exact = float(out.splitlines()[-1].split("pitch RMS ")[1].split()[0])
    assert main(["replay", str(path), "--delay-ticks", "3"]) == 0  # as it was replayed before
    out = capsys.readouterr().out
    assert "as asked (delay)" in out.splitlines()[0], out
    late = float(out.splitlines()[-1].split("pitch RMS ")[1].split()[0])
    assert exact < 1e-3 < late, (exact, late)
    with pytest.raises(SystemExit) as exit_:
        main(["replay", str(path), "--delay-ticks", "40"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err == "hopper-sim: error: --delay-ticks: the wheel command delay must be 0..16 ticks, got 40", err


def test_the_dashboard_leaves_a_hop_with_a_gap_out_and_says_so(cratered: Log, tmp_path: Path) -> None:
    """The dashboard's replay ran through a gap as the CLI did; now it leaves the hop out (whole) or
    re-anchors past the gap, names it in its summary, and keeps both ghosts on the same rows."""
    from hopper.logs.schema import find_gaps

    keep = np.ones(len(cratered.time), bool)
    keep[2000:2500] = False
    time = cratered.time[keep]
    holed = Log(time, {k: v[keep] for k, v in cratered.signals.items()}, "g", find_gaps(time), cratered.world)
    path = write_log(holed, tmp_path / "gap.npz")
    whole = replay_log(str(path), SimConfig())
    assert whole.shown == 2 and len(whole.notes) == 1 and whole.notes[0].startswith("hop 1 (")
    assert whole.notes[0].endswith("0.501 s without samples (1.999-2.500 s): not scored")
    assert "2 of 3 hops" in summary_html(whole) and "not scored" in summary_html(whole)
    assert whole.logged.shape == whole.simulated.shape and len(whole.logged_on) == whole.errors.time.size
    assert math.degrees(whole.errors.rms("pitch")) < 1e-3
    anchored = replay_log(str(path), SimConfig(), every=0.3)
    assert anchored.shown == 3 and anchored.notes[0].endswith("re-anchored on the log's state at its far side")
    assert anchored.logged.shape == anchored.simulated.shape and len(anchored.simulated_on) == anchored.errors.time.size
    assert math.degrees(anchored.errors.rms("pitch")) < 1e-3
