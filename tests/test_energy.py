"""The motors' electrical energy: the kernel's accumulation against the DC motor formula, and a real run."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from hopper.config import LEG_MOTOR_GEAR, MOTOR_RESISTANCE, MOTOR_TORQUE_CONSTANT, TOTAL_MASS, SimConfig
from hopper.control.controller import HopController
from hopper.control.energy import motor_power, spend
from hopper.layout import ModelLayout
from hopper.model import MODEL_XML, robot_of
from hopper.sim import Simulation
from hopper.similarity import size_for

DT = 0.001  # s
WHEEL_GEAR = 30.0  # models/hopper.xml


def copper(joint_torque: float, gear: float) -> float:
    """W: I^2 R with I = joint torque / (gear k_t), the formula written out once more."""
    current = joint_torque / (gear * MOTOR_TORQUE_CONSTANT)
    return current * current * MOTOR_RESISTANCE


@pytest.fixture
def kernel() -> tuple[ModelLayout, np.ndarray, tuple[int, int]]:
    model = mujoco.MjModel.from_xml_path(str(MODEL_XML))
    layout = ModelLayout.of(model)
    mem = HopController(layout, SimConfig(terrain="flat")).mem
    return layout, mem, (model.nv, model.nsensordata)


def drive(kernel, seconds: float, wheel, legs) -> None:  # noqa: ANN001
    """Feed spend() a synthetic profile: wheel(t) and legs(t) give (joint torque N m, joint speed rad/s),
    the legs' as four pairs in LEG_JOINTS order, sampled at each tick's time."""
    layout, mem, (nv, nsensordata) = kernel
    qvel, sensors = np.zeros(nv), np.zeros(nsensordata)
    for k in range(round(seconds / DT)):
        t = k * DT
        torque, speed = wheel(t)
        sensors[layout.s_wheel_torque], qvel[layout.v_wheel] = torque / layout.wheel_gear, speed
        for (torque, speed), s, v in zip(legs(t), layout.s_leg_torques, layout.v_legs, strict=True):
            sensors[s], qvel[v] = torque / layout.leg_gear, speed
        spend(mem[0], qvel, sensors)


def test_a_known_torque_and_speed_profile_costs_what_the_formula_says(kernel) -> None:
    layout, mem, _ = kernel
    assert layout.wheel_gear == WHEEL_GEAR and layout.leg_gear == 1.0
    a, b, f, seconds = 6.0, 20.0, 2.0, 1.0  # N m, rad/s, Hz: two whole periods
    # The wheel: torque and speed in phase, a sin(2 pi f t) and b sin(2 pi f t): the power never goes
    # negative, and over whole periods sin^2 averages 1/2, so E = T (copper(a) + a b) / 2.
    # The knees hold 3 N m and -2 N m still (copper loss only); the hips brake: -4 N m against 5 rad/s
    # is 20 W absorbed against 6.2 W of copper loss: a generator, and this drive does not recover it.
    holds = ((-4.0, 5.0), (3.0, 0.0), (-4.0, 5.0), (-2.0, 0.0))
    wave = lambda t: math.sin(2 * math.pi * f * t)  # noqa: E731
    drive(kernel, seconds, lambda t: (a * wave(t), b * wave(t)), lambda t: holds)
    wheel = seconds * (copper(a, WHEEL_GEAR) + a * b) / 2
    legs = seconds * (copper(3.0, LEG_MOTOR_GEAR) + copper(-2.0, LEG_MOTOR_GEAR))
    assert mem["acc_wheel_energy"][0] == pytest.approx(wheel, rel=1e-9)
    assert mem["acc_leg_energy"][0] == pytest.approx(legs, rel=1e-12)
    assert copper(3.0, LEG_MOTOR_GEAR) == pytest.approx(3.511, abs=1e-3)  # 2.475 A in 0.573 ohm


def test_a_drive_that_regenerates_counts_the_braking_energy_negative(kernel) -> None:
    _, mem, _ = kernel
    mem["regenerate"] = True
    still = ((0.0, 0.0),) * 4
    drive(kernel, 0.5, lambda t: (-3.0, 20.0), lambda t: still)  # the wheel brakes: 60 W absorbed
    recovered = 0.5 * (copper(-3.0, WHEEL_GEAR) - 60.0)  # J, negative: 3.5 W of copper loss against 60 W
    assert recovered < 0 and mem["acc_wheel_energy"][0] == pytest.approx(recovered, rel=1e-12)
    assert motor_power(-3.0, 20.0, WHEEL_GEAR, MOTOR_TORQUE_CONSTANT, MOTOR_RESISTANCE, False) == 0.0


class Reference:
    """Each hop's energy from MjData after every step (actuator_force, qvel), by the formula in Python."""

    def __init__(self, sim: Simulation) -> None:
        lay = sim.layout
        self.motors = [(lay.a_wheel, lay.v_wheel, lay.wheel_gear, lay.wheel_gear)]
        self.motors += [(a, v, lay.leg_gear, LEG_MOTOR_GEAR) for a, v in zip(lay.a_legs, lay.v_legs, strict=True)]
        self.running = [0.0, 0.0]  # wheel, legs (J)
        self.hops: list[tuple[float, float]] = []

    def tick(self, sim: Simulation) -> None:
        for i, (actuator, dof, to_joint, gear) in enumerate(self.motors):
            torque, speed = sim.data.actuator_force[actuator] * to_joint, sim.data.qvel[dof]
            self.running[min(i, 1)] += DT * max(copper(torque, gear) + torque * speed, 0.0)

    def event(self, sim: Simulation, event: object) -> None:
        if getattr(getattr(event, "payload", event), "hop", None) is not None:
            self.hops.append((self.running[0], self.running[1]))
            self.running = [0.0, 0.0]


def test_a_run_reports_each_hops_energy_ground_and_flight_and_a_plausible_cost_of_transport() -> None:
    sim = Simulation(SimConfig())  # the Moon, crater seed 0
    reference = Reference(sim)
    sim.listeners.append(reference)
    hops = sim.run(2)
    assert len(hops) == 2 and all(h.completed for h in hops)
    for hop, (wheel, legs) in zip(hops, reference.hops, strict=True):
        assert hop.wheel_energy_j == pytest.approx(wheel, rel=1e-9)
        assert hop.leg_energy_j == pytest.approx(legs, rel=1e-9)
        # A few W on average over a hop of about 3 s: positive, neither nothing nor a motor at stall.
        duration = hop.stance_time_s + hop.flight_time_s
        assert 1.0 < hop.wheel_energy_j / duration < 100.0 and 1.0 < hop.leg_energy_j / duration < 100.0
        transport = (hop.wheel_energy_j + hop.leg_energy_j) / (TOTAL_MASS * 1.625 * hop.distance_m)
        assert hop.cost_of_transport == pytest.approx(transport) and 0.5 < hop.cost_of_transport < 50.0


def test_a_motor_torque_mismatch_is_the_simulated_wheel_motors_torque_constant(kernel) -> None:
    layout, mem, sizes = kernel
    weak = HopController(layout, SimConfig(terrain="flat", mismatch=(("motor_torque", 0.5),))).mem
    assert weak["wheel_kt"][0] == 0.5 * MOTOR_TORQUE_CONSTANT and weak["leg_kt"][0] == MOTOR_TORQUE_CONSTANT
    still = ((0.0, 0.0),) * 4
    for record in (mem, weak):
        drive((layout, record, sizes), 0.2, lambda t: (6.0, 0.0), lambda t: still)  # 6 N m held
    # Half the torque per ampere: twice the current for the same torque, four times the copper loss.
    assert weak["acc_wheel_energy"][0] == pytest.approx(4.0 * mem["acc_wheel_energy"][0], rel=1e-12)
    assert mem["acc_wheel_energy"][0] == pytest.approx(0.2 * copper(6.0, WHEEL_GEAR), rel=1e-12)


def test_a_motor_k_times_the_datasheets_is_k_of_them_in_parallel(kernel, tmp_path) -> None:  # noqa: ANN001
    """hopper-sim size's Earth robot: the same torque through k motors in parallel, each carrying 1/k
    of the current, burns 1/k of one motor's copper loss (I^2 R / k); the mechanical power is the same.
    (The written MJCF keeps 6 significant digits: k read back is within 1e-4 of g / g_moon.)"""
    layout, mem, sizes = kernel
    spec = mujoco.MjSpec.from_string(MODEL_XML.read_text(encoding="utf-8"))
    k = size_for(spec, 9.81)
    path = tmp_path / "earth.xml"
    path.write_text(spec.to_xml())
    config = SimConfig(terrain="flat", model=str(path))
    sized = HopController(layout, config, robot_of(config)).mem
    assert sized["wheel_resistance"][0] == pytest.approx(MOTOR_RESISTANCE / k, rel=1e-4)
    assert sized["leg_resistance"][0] == pytest.approx(MOTOR_RESISTANCE / k, rel=1e-4)
    assert mem["wheel_resistance"][0] == mem["leg_resistance"][0] == MOTOR_RESISTANCE  # the datasheet's, exactly
    holds = ((-4.0, 5.0), (3.0, 0.0), (-4.0, 5.0), (-2.0, 0.0))
    for record in (mem, sized):
        drive((layout, record, sizes), 0.2, lambda t: (6.0, 0.0), lambda t: holds)
    assert sized["acc_wheel_energy"][0] == pytest.approx(mem["acc_wheel_energy"][0] / k, rel=1e-4)
    hips = 2 * 0.2 * max(copper(-4.0, LEG_MOTOR_GEAR) / k - 20.0, 0.0)  # braking, not recovered: zero
    knees = 0.2 * (copper(3.0, LEG_MOTOR_GEAR) + copper(-2.0, LEG_MOTOR_GEAR)) / k
    assert sized["acc_leg_energy"][0] == pytest.approx(hips + knees, rel=1e-4)
