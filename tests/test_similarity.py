"""The robot sized for another gravity (hopper.similarity, `hopper-sim size`): what is scaled, what is
kept, the gait it gets, and the command's file flown with --model."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import mujoco
import pytest

from hopper.config import GRAVITY_PRESETS, MOON_GRAVITY, GaitParams, SimConfig
from hopper.control import gait
from hopper.model import MODEL_XML, robot_of
from hopper.robot import PACKAGED
from hopper.sim import Simulation
from hopper.similarity import PARTS, design_gravity, factor, size_for


def sized(tmp_path: Path, gravity: float, parts: tuple[str, ...] = PARTS) -> Path:
    spec = mujoco.MjSpec.from_string(MODEL_XML.read_text(encoding="utf-8"))
    size_for(spec, gravity, parts=parts)
    path = tmp_path / f"sized_{gravity:g}_{'_'.join(parts)}.xml"
    path.write_text(spec.to_xml())
    return path


@pytest.mark.parametrize("gravity", [GRAVITY_PRESETS["earth"], GRAVITY_PRESETS["ceres"], 24.79, 5.0])
def test_torques_grow_with_the_weight_and_the_wheels_capacity_with_its_square_root(tmp_path: Path, gravity: float):
    k = gravity / MOON_GRAVITY
    robot = robot_of(SimConfig(model=str(sized(tmp_path, gravity)), terrain="flat"))  # written and read back
    assert robot.leg_torque_limit == pytest.approx(k * PACKAGED.leg_torque_limit, rel=1e-5)
    assert robot.wheel_torque_limit == pytest.approx(k * PACKAGED.wheel_torque_limit, rel=1e-4)
    assert robot.momentum_capacity == pytest.approx(math.sqrt(k) * PACKAGED.momentum_capacity, rel=1e-4)
    assert robot.wheel_no_load_speed == pytest.approx(PACKAGED.wheel_no_load_speed, rel=1e-4)
    kept = ("mass", "wheel_gear", "thigh", "shank", "hip_z", "foot_y", "foot_radius")
    assert {n: getattr(robot, n) for n in kept} == pytest.approx({n: getattr(PACKAGED, n) for n in kept}, rel=1e-6)


def test_one_part_sized_keeps_the_other_as_the_paper_built_it(tmp_path: Path):
    """`--only legs` and `--only wheel`: which actuator a gravity overloads (README)."""
    earth = GRAVITY_PRESETS["earth"]
    k = earth / MOON_GRAVITY
    legs = robot_of(SimConfig(model=str(sized(tmp_path, earth, ("legs",))), terrain="flat"))
    wheel = robot_of(SimConfig(model=str(sized(tmp_path, earth, ("wheel",))), terrain="flat"))
    assert legs.leg_torque_limit == pytest.approx(k * PACKAGED.leg_torque_limit, rel=1e-5)
    assert (legs.wheel_torque_limit, legs.momentum_capacity) == pytest.approx(
        (PACKAGED.wheel_torque_limit, PACKAGED.momentum_capacity), rel=1e-6
    )
    assert wheel.leg_torque_limit == PACKAGED.leg_torque_limit
    assert wheel.wheel_torque_limit == pytest.approx(k * PACKAGED.wheel_torque_limit, rel=1e-4)
    assert wheel.momentum_capacity == pytest.approx(math.sqrt(k) * PACKAGED.momentum_capacity, rel=1e-4)


@pytest.mark.parametrize("parts", [(), ("tail",), ("legs", "tail")])
def test_parts_that_are_not_the_legs_or_the_wheel_are_refused(parts: tuple[str, ...]):
    spec = mujoco.MjSpec.from_string(MODEL_XML.read_text(encoding="utf-8"))
    with pytest.raises(ValueError, match="parts must be some of legs, wheel"):
        size_for(spec, GRAVITY_PRESETS["earth"], parts=parts)
    assert spec.actuator("knee_L").ctrlrange[1] == PACKAGED.leg_torque_limit  # nothing scaled


def test_sized_for_the_gravity_it_was_designed_for_it_is_the_same_robot(tmp_path: Path):
    assert robot_of(SimConfig(model=str(sized(tmp_path, MOON_GRAVITY)), terrain="flat")) == PACKAGED


def test_the_sized_robot_flies_the_moons_gait_carried_by_gravity_alone(tmp_path: Path):
    """The paper's robot at Earth hops low: its legs cap the apex. Sized for Earth it hops the
    Moon's 0.25 m, and the wheel waits as long for a spin-down as on the Moon (capacity over a
    ground moment that grew with the weight, both by similarity)."""
    earth = GRAVITY_PRESETS["earth"]
    robot = robot_of(SimConfig(model=str(sized(tmp_path, earth)), terrain="flat"))
    paper, own, moon = (
        gait.derive(earth, GaitParams()),
        gait.derive(earth, GaitParams(), robot),
        gait.derive(MOON_GRAVITY, GaitParams()),
    )
    assert paper.apex < 0.5 * GaitParams().apex_height  # capped by 30 N m legs
    assert own.apex == moon.apex == GaitParams().apex_height
    assert own.wheel_wait == pytest.approx(moon.wheel_wait / math.sqrt(earth / MOON_GRAVITY), rel=1e-4)


def test_the_sized_earth_robot_hops_on_crater_ground(tmp_path: Path):
    earth = GRAVITY_PRESETS["earth"]
    sim = Simulation(SimConfig(model=str(sized(tmp_path, earth)), gravity=earth, seed=0))
    hops = sim.run(10)
    assert len(hops) == 10 and all(h.completed for h in hops) and not sim.fallen


@pytest.mark.parametrize("bad", [0.0, -9.81, math.inf, math.nan])
def test_a_gravity_that_is_not_finite_and_positive_is_refused(bad: float):
    with pytest.raises(ValueError, match="finite and positive"):
        factor(bad)


def hopper_sim(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hopper.app.sim_cli", *args], capture_output=True, text=True, timeout=120
    )


@pytest.mark.integration  # processes
def test_hopper_sim_size_writes_a_model_that_run_flies(tmp_path: Path):
    out = tmp_path / "earth.xml"
    done = hopper_sim("size", "--gravity", "earth", "--out", str(out))
    assert done.returncode == 0, done.stderr
    assert "torques x 6.04" in done.stdout and "181.1 N m" in done.stdout and f"--model {out}" in done.stdout
    run = hopper_sim("run", "--model", str(out), "--gravity", "earth", "--hops", "3", "--terrain", "flat")
    assert run.returncode == 0, run.stderr
    assert "3 hops" in run.stdout and "FELL" not in run.stdout
    assert "note:" not in run.stdout  # its legs do not cap the hop
    legs = tmp_path / "legs.xml"
    done = hopper_sim("size", "--gravity", "earth", "--only", "legs", "--out", str(legs))
    assert done.returncode == 0 and "x 6.04; legs only" in done.stdout, done.stdout + done.stderr
    assert "wheel stall torque            29.5 ->      29.5 N m" in done.stdout


def test_a_sized_robot_records_its_design_gravity_so_sizing_it_again_is_idempotent(tmp_path: Path):
    earth = GRAVITY_PRESETS["earth"]
    once = mujoco.MjSpec.from_file(str(sized(tmp_path, earth)))  # written and read back
    assert design_gravity(once, "legs") == design_gravity(once, "wheel") == earth
    assert mujoco.MjModel.from_xml_string(once.to_xml()).numeric("hopper_design_gravity_legs").data[0] == earth
    assert size_for(once, earth) == 1.0  # was x 6.04 again: 36 times the Moon's torques
    again = tmp_path / "again.xml"
    again.write_text(once.to_xml())
    first = robot_of(SimConfig(model=str(sized(tmp_path, earth)), terrain="flat"))
    assert robot_of(SimConfig(model=str(again), terrain="flat")) == first
    legs = mujoco.MjSpec.from_file(str(sized(tmp_path, earth, ("legs",))))  # each part from its own design
    assert (design_gravity(legs, "legs"), design_gravity(legs, "wheel")) == (earth, None)
    size_for(legs, earth)
    assert robot_of(SimConfig(model=str(_written(tmp_path / "both.xml", legs)), terrain="flat")) == first


def _written(path: Path, spec: mujoco.MjSpec) -> Path:
    path.write_text(spec.to_xml())
    return path


@pytest.mark.integration  # processes
def test_hopper_sim_size_of_a_sized_model_keeps_it_and_refuses_its_own_file_as_out(tmp_path: Path):
    earth = tmp_path / "earth.xml"
    assert hopper_sim("size", "--gravity", "earth", "--out", str(earth)).returncode == 0
    again = hopper_sim("size", "--gravity", "earth", "--model", str(earth), "--out", str(tmp_path / "s2.xml"))
    assert again.returncode == 0 and "sized from 9.81 to 9.81 m/s^2 (torques x 1)" in again.stdout, again.stdout
    assert "leg motors                   181.1 ->     181.1 N m" in again.stdout
    before = earth.read_text()
    same = hopper_sim("size", "--gravity", "mars", "--model", str(earth), "--out", str(earth))
    assert same.returncode == 2 and same.stderr.count("\n") == 1 and "is --model's file" in same.stderr
    clash = hopper_sim(
        "size", "--gravity", "mars", "--model", str(earth), "--design", "moon", "--out", str(tmp_path / "x.xml")
    )
    assert clash.returncode == 2 and "records its legs for 9.81" in clash.stderr, clash.stderr
    assert earth.read_text() == before and not (tmp_path / "x.xml").exists()


@pytest.mark.integration  # processes
@pytest.mark.parametrize(("body", "capped"), [("earth", True), ("mars", False)])
def test_a_run_whose_legs_cap_the_hop_names_the_command_that_sizes_the_robot(body: str, capped: bool):
    run = hopper_sim("run", "--gravity", body, "--hops", "1", "--terrain", "flat")
    assert run.returncode in (0, 1), run.stderr
    note = [line for line in run.stdout.splitlines() if line.startswith("note:")]
    if capped:
        assert len(note) == 1 and "30 N m legs cap the hop at 0.09 m of the 0.25 m asked" in note[0], run.stdout
        assert "hopper-sim size --gravity 9.81" in note[0]
    else:
        assert note == [], run.stdout


@pytest.mark.integration
@pytest.mark.parametrize(
    ("args", "why"),
    [
        (["--gravity", "0"], "gravities must be positive"),
        (["--gravity", "venus"], "neither m/s^2 nor one of"),
        (["--gravity", "earth", "--design", "-1"], "gravities must be positive"),
        (["--gravity", "earth", "--only", "tail"], "invalid choice: 'tail'"),
    ],
)
def test_hopper_sim_size_refuses_bad_input_in_one_line_and_writes_nothing(tmp_path: Path, args: list[str], why: str):
    out = tmp_path / "x.xml"
    done = hopper_sim("size", *args, "--out", str(out))
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and why in done.stderr, done.stderr
    assert not out.exists()
