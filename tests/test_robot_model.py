"""A user's model (`--model`): the robot's constants read from it, names checked, the packaged robot unchanged."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import mujoco
import pytest
import variants

from hopper import config as constants
from hopper.config import GaitParams, SimConfig
from hopper.control import gait
from hopper.errors import HopperError, ModelError
from hopper.layout import NAMES
from hopper.model import build_model, robot_of
from hopper.robot import PACKAGED, PACKAGED_TOLERANCE, Robot
from hopper.sim import Simulation


def test_the_packaged_models_constants_are_todays_config_values() -> None:
    robot = robot_of(SimConfig())
    assert robot == PACKAGED
    expected = {
        "mass": constants.TOTAL_MASS, "wheel_inertia": constants.WHEEL_INERTIA,
        "wheel_armature": constants.WHEEL_ARMATURE, "wheel_gear": constants.WHEEL_GEAR,
        "wheel_torque_limit": constants.WHEEL_TORQUE_LIMIT, "wheel_no_load_speed": constants.WHEEL_NO_LOAD_SPEED,
        "leg_torque_limit": constants.LEG_TORQUE_LIMIT, "thigh": constants.THIGH_LENGTH,
        "shank": constants.SHANK_LENGTH, "hip_z": constants.HIP_OFFSET_Z, "foot_radius": constants.FOOT_RADIUS,
    }  # fmt: skip
    assert {k: getattr(robot, k) for k in expected} == expected
    # The kernel's memory holds them, so the packaged robot flies as before (bit-identical runs).
    mem = Simulation(SimConfig(terrain="flat")).controller.mem
    assert (mem["mass"][0], mem["thigh"][0], mem["hip_z"][0]) == (8.2, 0.5, -0.18)
    assert (mem["wheel_limit"][0], mem["leg_limit"][0]) == (29.5, 30.0)
    assert mem["wheel_damping"][0] == constants.WHEEL_TORQUE_LIMIT / constants.WHEEL_NO_LOAD_SPEED


def test_only_the_xmls_rounded_motor_figures_are_snapped_to_the_packaged_ones() -> None:
    """The XML writes the wheel motor to 4 figures (29.499 N m, 41.887 rad/s); a change beyond that is read."""
    model = build_model(SimConfig(terrain="flat"))
    wheel = model.actuator("wheel").id
    assert 0 < abs(30 * model.actuator_gainprm[wheel, 0] - 29.5) <= PACKAGED_TOLERANCE * 29.5
    model.actuator_gainprm[wheel, 0] *= 1.01  # a 1 % stronger motor: no longer the packaged one
    model.actuator_forcerange[wheel] *= 1.01
    stronger = Robot.of(model)
    assert stronger.wheel_torque_limit == pytest.approx(29.5 * 1.01, rel=2e-4)
    assert stronger.wheel_no_load_speed == pytest.approx(PACKAGED.wheel_no_load_speed * 1.01, rel=2e-4)


def test_a_variants_constants_are_read_from_its_model(tmp_path: Path) -> None:
    robot = robot_of(SimConfig(model=str(variants.variant(tmp_path, wheel_inertia=1.3, legs=1.1))))
    assert robot.wheel_inertia == pytest.approx(1.3 * PACKAGED.wheel_inertia, rel=1e-12)
    assert robot.thigh == pytest.approx(0.55, rel=1e-12) and robot.shank == pytest.approx(0.55, rel=1e-12)
    assert robot.mass == pytest.approx(PACKAGED.mass)  # the variant moves no mass
    assert robot.momentum_capacity == pytest.approx(
        (1.3 * PACKAGED.wheel_inertia + PACKAGED.wheel_armature) * PACKAGED.wheel_no_load_speed
    )
    # The controller designs with them: a longer leg is stronger at the same crouch, the stance
    # taller, the wheel's wait for a spin-down longer.
    own, packaged = gait.derive(1.625, GaitParams(), robot), gait.derive(1.625, GaitParams())
    assert gait.leg_force_limit(0.68, robot) < gait.leg_force_limit(0.68)  # the knee bends more at 0.68 m
    assert own.wheel_wait == pytest.approx(packaged.wheel_wait * robot.momentum_capacity / PACKAGED.momentum_capacity)
    sim = Simulation(SimConfig(model=str(variants.variant(tmp_path)), terrain="flat"))
    assert sim.robot == robot and sim.controller.mem["thigh"][0] == robot.thigh
    # It stands on its longer legs: feet on the ground at the reset.
    feet = [sim.data.geom_xpos[sim.model.geom(f"foot_{s}").id][2] for s in "LR"]
    assert feet == pytest.approx([robot.foot_radius] * 2, abs=1e-3)


@pytest.mark.parametrize("seed", [0, 3])
def test_a_variant_hops_with_good_landings(tmp_path: Path, seed: int) -> None:
    sim = Simulation(SimConfig(model=str(variants.variant(tmp_path)), seed=seed))
    hops = sim.run(7)
    assert len(hops) == 7 and not sim.fallen
    assert max(abs(h.landing_pitch_deg) for h in hops) < 1.0


def test_a_renamed_actuator_is_refused_in_one_line_naming_it_and_the_list_expected(tmp_path: Path) -> None:
    path = variants.renamed_actuator(tmp_path)
    with pytest.raises(ModelError) as caught:
        Simulation(SimConfig(model=str(path)))
    message = str(caught.value)
    assert "\n" not in message and isinstance(caught.value, HopperError)
    assert "no actuator 'wheel'" in message and "'wheel_motor'" in message
    assert f"expected {', '.join(NAMES['actuator'])}" in message and str(path) in message


def test_every_missing_kind_is_named(tmp_path: Path) -> None:
    spec = variants.packaged()
    spec.sensor("foot_L").name = "left_foot"
    spec.body("shank_R").name = "right_shank"
    path = tmp_path / "two.xml"
    path.write_text(spec.to_xml(), encoding="utf-8")
    with pytest.raises(ModelError, match=r"no sensor 'foot_L' .*; no body 'shank_R' "):
        robot_of(SimConfig(model=str(path)))


@pytest.mark.parametrize(
    ("text", "why"),
    [
        (None, "no such file"),
        ("this is not XML", "not a valid MJCF file"),
        ("<mujoco><worldbody><body><joint type='bogus'/></body></worldbody></mujoco>", "not a valid MJCF file"),
    ],
)
def test_a_file_that_is_missing_or_not_mjcf_is_refused_in_one_line(tmp_path: Path, text: str | None, why: str) -> None:
    path = tmp_path / "robot.xml"
    if text is not None:
        path.write_text(text, encoding="utf-8")
    with pytest.raises(ModelError, match=why) as caught:
        robot_of(SimConfig(model=str(path)))
    assert "\n" not in str(caught.value)


def _edited(tmp_path: Path, edit) -> Path:  # noqa: ANN001 (a function of an MjSpec)
    spec = variants.packaged()
    edit(spec)
    path = tmp_path / "edited.xml"
    path.write_text(spec.to_xml(), encoding="utf-8")
    return path


def _shorter_shank(spec: mujoco.MjSpec) -> None:
    for side in "LR":
        spec.site(f"foot_{side}").pos = [0, 0, -0.45]


def _geared_hip(spec: mujoco.MjSpec) -> None:
    spec.actuator("hip_L").gear = [2, 0, 0, 0, 0, 0]


def _position_wheel(spec: mujoco.MjSpec) -> None:
    spec.actuator("wheel").biasprm = [0, -1, 0] + [0] * 7


@pytest.mark.parametrize(
    ("edit", "why"),
    [(_shorter_shank, "as long as the thigh"), (_geared_hip, "gear 1"), (_position_wheel, "DC motor")],
)
def test_a_robot_the_controller_does_not_describe_is_refused(tmp_path: Path, edit, why: str) -> None:  # noqa: ANN001
    with pytest.raises(ModelError, match=why):
        robot_of(SimConfig(model=str(_edited(tmp_path, edit))))


def test_the_model_path_travels_in_the_config() -> None:
    config = SimConfig(model="/somewhere/robot.xml")
    assert dataclasses.asdict(config)["model"] == "/somewhere/robot.xml"
    assert math.isfinite(hash(config))
    with pytest.raises(ValueError, match="model must be"):
        SimConfig(model="  ")


def test_a_snapshot_of_another_model_is_refused_and_episodes_do_not_share_a_model(tmp_path: Path) -> None:
    from hopper.config import InvalidConfig
    from hopper.snapshot import SnapshotMismatch

    path = str(variants.variant(tmp_path))
    other, packaged = Simulation(SimConfig(model=path, terrain="flat")), Simulation(SimConfig(terrain="flat"))
    with pytest.raises(SnapshotMismatch, match=f"state of model {path}, this one flies models/hopper.xml"):
        packaged.check_fits(other.snapshot())
    with pytest.raises(InvalidConfig, match="share the model"):
        packaged.start_over(SimConfig(model=path, terrain="flat"))


def test_the_model_based_laws_design_on_the_flown_robots_wheel(tmp_path: Path) -> None:
    from hopper.controllers import with_controller
    from hopper.laws.plant import attitude_model

    config = SimConfig(model=str(variants.stronger_motor(tmp_path, 1.2)), terrain="flat")
    robot = robot_of(config)
    assert robot.wheel_torque_limit == pytest.approx(1.2 * 29.499, rel=1e-9)
    assert robot.wheel_no_load_speed == pytest.approx(1.2 * 0.9833 / (0.0007825 * 30), rel=1e-9)
    assert attitude_model(config).full.robot == robot  # LQR's and MPC's plant: the flown model's
    assert attitude_model(SimConfig(terrain="flat")).full.robot == PACKAGED
    for law in ("lqr", "mpc"):
        sim = Simulation(with_controller(config, law, ()))
        hops = sim.run(2)
        assert len(hops) == 2 and not sim.fallen and sim.controller_fault is None
        assert sim.observation().torque_bounds[1] == pytest.approx(
            robot.wheel_torque_limit
        )  # at rest: the stall torque


def test_the_reports_torque_figure_draws_the_flown_motors_limit(tmp_path: Path) -> None:
    import numpy as np

    from hopper.report.run_figures import wheel_torque
    from hopper.report.runs import Run

    def limit_lines(model: str | None) -> set[float]:
        trace = {"t_s": np.array([0.0, 1.0]), "wheel_torque_nm": np.array([0.0, 5.0])}
        run = Run(label="x", wheel=True, fell=False, settings={"model": model}, hops=[], trace=trace, source="test")
        ax = wheel_torque(run).axes[0]
        return {round(float(line.get_ydata()[0]), 6) for line in ax.get_lines()[1:]}

    stronger = limit_lines(str(variants.stronger_motor(tmp_path, 1.2)))
    assert max(stronger) == pytest.approx(1.2 * 29.499, abs=1e-6)
    assert max(limit_lines(None)) == 29.5
    assert limit_lines(str(tmp_path / "gone.xml")) == set()  # a model no longer there: no limit drawn
