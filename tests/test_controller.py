"""The control kernel's pieces: PID sign and anti-windup, the torque-speed envelope, contacts, legs."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from hopper.config import WHEEL_NO_LOAD_SPEED, WHEEL_TORQUE_LIMIT, Gains, GaitParams, InvalidConfig, SimConfig
from hopper.control import HopController, control_tick
from hopper.control.contact import debounce
from hopper.control.gait import BOOST_SPEED
from hopper.control.kernel import PUSH_ATTEMPTS, STALL_HOPS
from hopper.control.legs import RIGID_KNEE, leg_state
from hopper.control.memory import MEMORY
from hopper.control.phases import Phase
from hopper.control.wheel import WHEEL_DAMPING, wheel_ctrl, wheel_pid
from hopper.layout import ModelLayout
from hopper.model import MODEL_XML, build_model
from hopper.sim import Simulation


def _memory(gains: Gains) -> np.ndarray:
    model = build_model(SimConfig(terrain="flat"))
    return HopController(ModelLayout.of(model), SimConfig(terrain="flat", gains=gains)).mem


def test_the_memory_is_one_named_record() -> None:
    mem = _memory(Gains(kp=400, ki=10, kd=20))
    assert mem.dtype == MEMORY and mem.shape == (1,)
    assert (mem["kp"][0], mem["ki"][0], mem["kd"][0]) == (400, 10, 20)
    assert mem["phase"].dtype == np.int64 and mem["wheel_on"].dtype == np.bool_


def test_pid_pushes_the_torso_back_toward_upright() -> None:
    m = _memory(Gains(kp=400, ki=0, kd=20))[0]
    # Nose down (positive pitch): the motor spins the wheel positive, the torso takes the negative reaction.
    assert wheel_pid(m, 0.05, 0.0, 0.0) == pytest.approx(400 * 0.05)
    assert wheel_pid(m, 0.0, -0.5, 0.0) == pytest.approx(20 * -0.5)


def test_pid_clamps_to_the_envelope_and_stops_integrating_when_saturated() -> None:
    mem = _memory(Gains(kp=400, ki=100, kd=20))
    m = mem[0]
    torque = wheel_pid(m, 1.0, 0.0, 0.0)  # 400 N m asked
    assert torque == pytest.approx(WHEEL_TORQUE_LIMIT)
    assert mem["integral"][0] == 0.0 and mem["saturated"][0]
    wheel_pid(m, 0.01, 0.0, 0.0)  # 4 N m: inside the envelope, integrates
    assert mem["integral"][0] == pytest.approx(0.01 * 0.001) and not mem["saturated"][0]
    # At half the no-load speed only half the torque is left in the direction of motion.
    assert wheel_pid(m, 1.0, 0.0, WHEEL_NO_LOAD_SPEED / 2) == pytest.approx(WHEEL_TORQUE_LIMIT / 2)


def test_wheel_ctrl_inverts_the_motor_model() -> None:
    for speed in (-20.0, 0.0, 15.0):
        for torque in (-10.0, 0.0, 5.0):
            u = wheel_ctrl(_memory(Gains())[0], torque, speed)
            assert WHEEL_TORQUE_LIMIT * u - WHEEL_DAMPING * speed == pytest.approx(torque)


def test_contact_debounce_and_hysteresis() -> None:
    on, pending, seen = False, -1.0, []
    forces = [5, 5, 5, 0.5] + [0.1] * 10 + [5] + [0.1] * 16
    for i, force in enumerate(forces):
        on, pending = debounce(force, i * 0.001, on, pending, 1.0, 0.2)  # N: the Moon's thresholds
        seen.append(on)
    assert seen[:3] == [False, False, True]  # on after 2 ms above 1 N
    assert seen[3] is True  # 0.5 N is above the 0.2 N off threshold
    assert all(seen[4:15])  # a 10 ms gap, then a tap: the foot is still down
    assert seen[15:29] == [True] * 14 and seen[30] is False  # off after 15 ms below 0.2 N


def test_leg_jacobian_matches_finite_differences() -> None:
    pitch, hip, knee, eps = 0.1, 0.5, -1.1, 1e-6
    m = _memory(Gains())[0]
    leg = leg_state(m, pitch, hip, knee, 0.0, 0.0, False)
    by_hip = leg_state(m, pitch, hip + eps, knee, 0.0, 0.0, False)
    by_knee = leg_state(m, pitch, hip, knee + eps, 0.0, 0.0, False)
    assert (by_hip.px - leg.px) / eps == pytest.approx(leg.pz, abs=1e-5)
    assert (by_hip.pz - leg.pz) / eps == pytest.approx(-leg.px, abs=1e-5)
    assert (by_knee.px - leg.px) / eps == pytest.approx(leg.jx, abs=1e-5)
    assert (by_knee.pz - leg.pz) / eps == pytest.approx(leg.jz, abs=1e-5)


def test_the_knees_rigid_share_of_a_leg_turn_matches_mujocos_inertia() -> None:
    # The hip and knee torques that turn a leg as one body (knee acceleration zero) with the torso
    # free, from the model's joint-space inertia at the landing pose's knee bends.
    model = build_model(SimConfig(terrain="flat"))
    data = mujoco.MjData(model)
    hip, knee = (model.jnt_dofadr[model.joint(name).id] for name in ("hip_L", "knee_L"))
    for bend in (0.0, -0.3, -0.6):
        data.qpos[model.jnt_qposadr[model.joint("knee_L").id]] = bend
        data.qpos[model.jnt_qposadr[model.joint("hip_L").id]] = -bend / 2
        mujoco.mj_forward(model, data)
        inertia = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, inertia)
        inverse = np.linalg.inv(inertia)
        ratio = -inverse[knee, hip] / inverse[knee, knee]
        assert ratio == pytest.approx(RIGID_KNEE, abs=0.035)
        assert abs(ratio - 0.5) > 0.15  # the bisection's half is not it


def test_the_kernel_finds_its_sensors_by_name_in_any_order() -> None:
    """A model whose sensors and actuators are declared in another order gets the same commands."""
    xml = MODEL_XML.read_text()
    sensors = xml[xml.index("<sensor>") + len("<sensor>") : xml.index("</sensor>")]
    lines = [
        line for line in sensors.splitlines() if line.strip().startswith("<") and not line.strip().startswith("<!--")
    ]
    reordered = xml.replace(sensors, "\n" + "\n".join(reversed(lines)) + "\n")
    actuators = xml[xml.index("<actuator>") : xml.index("</actuator>")]
    motors = [line for line in actuators.splitlines() if line.strip().startswith("<motor")]
    reordered = reordered.replace("\n".join(motors), "\n".join(reversed(motors)))
    commands = []
    for text in (xml, reordered):
        model = mujoco.MjModel.from_xml_string(text)
        data = mujoco.MjData(model)
        data.qpos[model.joint("pitch").qposadr[0]] = 0.2  # airborne, tilted: the flight law and the swing act
        data.qvel[model.joint("pitch").dofadr[0]] = -0.3
        data.qvel[model.joint("root_x").dofadr[0]] = 0.4
        mujoco.mj_forward(model, data)
        controller = HopController(ModelLayout.of(model), SimConfig(terrain="flat"))
        controller.reset(standing=False)
        controller.mem["phase"] = 4  # FLIGHT
        control_tick(data.qpos, data.qvel, data.sensordata, data.ctrl, controller.mem)
        commands.append({model.actuator(i).name: data.ctrl[i] for i in range(model.nu)})
    assert model.sensor("imu_pitch").adr[0] != 0  # the reorder really moved things
    assert commands[0] == commands[1]
    assert commands[0]["wheel"] != 0 and commands[0]["hip_L"] != 0


@pytest.mark.parametrize("bad", [{"kp": -1.0}, {"ki": float("nan")}, {"kd": float("inf")}, {"kp": 1e9}])
def test_invalid_gains_raise_with_the_allowed_range(bad: dict) -> None:
    with pytest.raises(InvalidConfig, match=r"must be a finite number in \["):
        Gains(**bad)


def _step_until(sim: Simulation, done, limit_s: float = 10.0) -> None:  # noqa: ANN001 (a predicate on sim)
    end = sim.time + limit_s
    while not done(sim):
        assert sim.time < end, "the state never came"
        sim.step()


def test_a_push_that_loses_a_foot_is_counted_as_failed() -> None:
    """A push that ends with a foot still down (here the right one leaves early) is a failed attempt."""
    sim = Simulation(SimConfig(terrain="flat"))
    mem = sim.controller.mem
    _step_until(sim, lambda s: s.phase == Phase.PUSH)
    assert mem["failed_pushes"][0] == 0 and not mem["recovering"][0]
    sensors = sim.data.sensordata.copy()
    sensors[mem["s_foot_r"][0]] = 0.0  # the right foot's touch sensor reads nothing from now on
    d = sim.data
    for _ in range(40):  # longer than the contact's off debounce
        control_tick(d.qpos, d.qvel, sensors, d.ctrl, mem)
        if mem["phase"][0] != Phase.PUSH:
            break
    assert mem["phase"][0] == Phase.STANCE
    assert mem["failed_pushes"][0] == 1


def test_after_failed_pushes_the_next_push_is_a_recovery_hop_that_re_places_the_feet() -> None:
    """A foot that unloads as every push begins aborted each push from the same feet, for an hour of
    Ceres (seed 1 of the falls benchmark): after PUSH_ATTEMPTS failures the push is a recovery hop,
    which has no one-foot abort and lands the feet elsewhere; its liftoff clears the count."""
    sim = Simulation(SimConfig(terrain="flat"))
    mem = sim.controller.mem
    _step_until(sim, lambda s: s.phase == Phase.CROUCH)
    mem["failed_pushes"] = PUSH_ATTEMPTS - 1
    _step_until(sim, lambda s: s.phase == Phase.PUSH)
    assert not mem["recovering"][0]  # one failure short: the gait's own push
    _step_until(sim, lambda s: s.phase != Phase.PUSH)
    _step_until(sim, lambda s: s.phase == Phase.CROUCH)
    mem["failed_pushes"] = PUSH_ATTEMPTS
    _step_until(sim, lambda s: s.phase == Phase.PUSH)
    assert mem["recovering"][0]
    _step_until(sim, lambda s: s.phase == Phase.FLIGHT)
    assert mem["failed_pushes"][0] == 0


def _liftoff(sim: Simulation) -> tuple[float, float]:
    """Step to the next liftoff; the CoM's (vx, vz) there (m/s)."""
    _step_until(sim, lambda s: s.phase == Phase.PUSH)
    _step_until(sim, lambda s: s.phase == Phase.FLIGHT)
    s = sim.controller.mem["s_com_vel"][0]
    return float(sim.data.sensordata[s]), float(sim.data.sensordata[s + 2])


@pytest.mark.parametrize("forward", [0.4, 0.0])
def test_a_robot_that_keeps_landing_back_hops_out_harder_unless_it_hops_in_place(forward: float) -> None:
    """Mars seed 3 hopped 300 times in one crater: each hop landed on its far wall, the stance slid
    off it and a recovery hop took it back. After STALL_HOPS liftoffs that get no further than the
    furthest one, the next push goes twice as high and twice as fast; asked to hop in place, the
    robot does."""
    sim = Simulation(SimConfig(terrain="flat", gait=GaitParams(forward_speed=forward)))
    mem = sim.controller.mem
    vx, vz = _liftoff(sim)
    mem["progress_x"] = 100.0 if forward else 0.0  # far ahead: none of these liftoffs is progress
    mem["stalled"] = STALL_HOPS - 1
    assert _liftoff(sim)[1] == pytest.approx(vz, rel=0.1)  # the STALL_HOPS-th stall: still the gait's
    boosted_vx, boosted_vz = _liftoff(sim)
    if forward:
        assert mem["stalled"][0] == STALL_HOPS + 1
        assert boosted_vz > 1.3 * vz
        assert boosted_vz == pytest.approx(mem["vz_boost"][0], rel=0.15)
        assert 1.3 * vx < boosted_vx < 1.1 * BOOST_SPEED * forward
    else:
        assert boosted_vz == pytest.approx(vz, rel=0.1)
        assert boosted_vx == pytest.approx(vx, abs=0.03)  # the same hop as the first


def _foot_forces(mem: np.ndarray, qpos: np.ndarray, ctrl: np.ndarray) -> list[np.ndarray]:
    """The ground forces (fx, fz) (N) the leg torques in `ctrl` ask for at each foot: tau = -J^T f, solved."""
    m = mem[0]
    forces = []
    for side in ("l", "r"):
        leg = leg_state(m, qpos[m["q_pitch"]], qpos[m[f"q_hip_{side}"]], qpos[m[f"q_knee_{side}"]], 0.0, 0.0, True)
        jacobian_t = np.array([[-leg.pz, leg.px], [-leg.jx, -leg.jz]])  # (hip, knee) per (fx, fz)
        forces.append(np.linalg.solve(jacobian_t, [ctrl[m[f"a_hip_{side}"]], ctrl[m[f"a_knee_{side}"]]]))
    return forces


@pytest.mark.parametrize("slope_deg", [20.0, -20.0, 0.0])
def test_the_stance_keeps_each_foots_force_inside_its_friction_cone_turned_with_the_ground(slope_deg: float) -> None:
    """On a crater wall the stance asked for as much horizontal force as level ground holds
    (|fx| = mu fz in world axes), and the feet slid at the full friction ratio (Moon seed 1, Mars
    seed 2: falls on 25-35 deg walls). Standing on `slope_deg` ground and drifting downhill, each
    foot is asked for a force inside its cone about the ground's normal, at its edge."""
    sim = Simulation(SimConfig(terrain="flat"))
    mem = sim.controller.mem
    mu, slope = float(mem["friction"][0]), math.radians(slope_deg)
    mem["slope_l"] = mem["slope_r"] = slope
    d = sim.data
    qvel, ctrl = d.qvel.copy(), d.ctrl.copy()
    # Landing, drifting downhill (backwards on rising ground): the braking force points uphill, the
    # way the cone limits. (In STANCE that drift would start a recovery hop.)
    mem["phase"], mem["phase_start"] = Phase.LANDING, mem["clock"]
    qvel[mem["v_x"][0]] = -0.3 if slope_deg >= 0 else 0.3
    control_tick(d.qpos, qvel, d.sensordata, ctrl, mem)
    assert mem["phase"][0] == Phase.LANDING
    normal, tangent = np.array([-math.sin(slope), math.cos(slope)]), np.array([math.cos(slope), math.sin(slope)])
    for force in _foot_forces(mem, d.qpos, ctrl):
        along, across = float(force @ tangent), float(force @ normal)
        assert across > 0.0
        assert abs(along) <= mu * across * (1 + 1e-9)
        assert abs(along) == pytest.approx(mu * across, rel=1e-6)  # the demand is at the cone's edge


def test_a_push_with_one_foot_on_a_wall_pushes_each_foot_in_its_own_cone() -> None:
    """Mars seed 0 hopped 800 times in one crater: its front foot landed on the 35 deg wall out,
    whose cone holds next to no forward force (tan(atan(mu) - 35 deg) of the vertical), and both
    feet pushed in one direction inside both cones, so neither the stance nor the push could move
    the CoM forward, and a recovery hop took it back in. Pushing with the rear foot on level
    ground, each foot now pushes inside its own cone: more forward force than one direction
    allows, none outside a cone."""
    sim = Simulation(SimConfig(terrain="flat"))
    mem, d = sim.controller.mem, sim.data
    _step_until(sim, lambda s: s.phase == Phase.PUSH)
    mu, wall = float(mem["friction"][0]), math.radians(35.0)
    assert d.geom("foot_L").xpos[0] > d.geom("foot_R").xpos[0] + 0.2  # the wall is under the front foot
    mem["slope_l"], mem["slope_r"] = wall, 0.0
    ctrl = d.ctrl.copy()
    control_tick(d.qpos, d.qvel, d.sensordata, ctrl, mem)
    assert mem["phase"][0] == Phase.PUSH and mem["contact_l"][0] and mem["contact_r"][0]
    forces = _foot_forces(mem, d.qpos, ctrl)
    for force, slope in zip(forces, (wall, 0.0), strict=True):
        normal, tangent = np.array([-math.sin(slope), math.cos(slope)]), np.array([math.cos(slope), math.sin(slope)])
        along, across = float(force @ tangent), float(force @ normal)
        assert across > 0.0 and abs(along) <= mu * across * (1 + 1e-6)
    fx, fz = sum(f[0] for f in forces), sum(f[1] for f in forces)
    shared = max(math.tan(math.atan(mu) - wall), 0.0)  # fx / fz of one direction inside both cones, at most
    assert fx > (shared + 0.1) * fz


def test_a_rear_foot_on_a_falling_wall_leaves_the_moment_to_the_front_foots_cone() -> None:
    """Mars seed 27 fell landing with its rear foot on a wall falling at 37 deg, whose cone holds no
    backward force, and both feet ahead of the CoM: inside both cones one direction could not make
    the moment the robot's momentum asked, and it pitched back past the wheel. Each foot now pushes
    in its own cone when one direction misses the moment: the level front foot pushes back. More
    moment than one direction inside both cones makes, none outside a cone, no leg past its motors."""
    sim = Simulation(SimConfig(terrain="flat"))
    mem, d = sim.controller.mem, sim.data
    _step_until(sim, lambda s: s.phase == Phase.STANCE)
    mu, wall = float(mem["friction"][0]), math.radians(-37.0)
    front, rear = d.geom("foot_L").xpos.copy(), d.geom("foot_R").xpos.copy()
    assert front[0] > rear[0] + 0.2
    mem["slope_l"], mem["slope_r"] = 0.0, wall
    sensors, ctrl = d.sensordata.copy(), d.ctrl.copy()
    sensors[mem["s_angmom"][0]] = -2.0  # N m s, pitching back: the feet are asked for the opposite moment
    control_tick(d.qpos, d.qvel, sensors, ctrl, mem)
    assert mem["phase"][0] == Phase.STANCE and mem["contact_l"][0] and mem["contact_r"][0]
    forces = _foot_forces(mem, d.qpos, ctrl)
    for (fx, fz), slope in zip(forces, (0.0, wall), strict=True):
        # the cone about the ground's normal; on a wall steeper than it, the vertical is allowed too
        lo, hi = math.tan(-slope - math.atan(mu)), math.tan(-slope + math.atan(mu))
        assert fz > 0.0 and min(lo, 0.0) - 1e-6 <= fx / fz <= max(hi, 0.0) + 1e-6
    limit = float(mem["leg_limit"][0])
    legs = [mem[name][0] for name in ("a_hip_l", "a_knee_l", "a_hip_r", "a_knee_r")]
    assert np.all(np.abs(ctrl[legs]) <= limit * (1 + 1e-6))
    com = sensors[mem["s_com"][0] : mem["s_com"][0] + 3]
    r = [np.array([p[0] - com[0], p[2] - com[2]]) for p in (front, rear)]
    moment = sum(rz * f[0] - rx * f[1] for (rx, rz), f in zip(r, forces, strict=True))
    fz = sum(f[1] for f in forces)
    # One direction inside both cones pushes no foot back (the wall's cone), and a foot below the
    # CoM pushing forward only lowers this moment: at most the vertical forces', max(-rx) a newton.
    assert moment > (max(-r[0][0], -r[1][0]) + 0.03) * fz


def test_each_touchdown_reads_the_ground_slope_under_each_foot() -> None:
    """The kernel's slopes are the terrain's under the feet at touchdown (rad, rising along +x)."""
    sim = Simulation(SimConfig(seed=3))
    mem, r = sim.controller.mem, sim.robot.foot_radius
    steep = 0
    for _ in range(6):
        _step_until(sim, lambda s: s.phase == Phase.FLIGHT, limit_s=30.0)
        _step_until(sim, lambda s: s.phase == Phase.LANDING, limit_s=30.0)
        for side, y in (("L", sim.robot.foot_y), ("R", -sim.robot.foot_y)):
            x = float(sim.data.geom(f"foot_{side}").xpos[0])
            expected = math.atan((sim.terrain.height(x + r, y) - sim.terrain.height(x - r, y)) / (2 * r))
            assert mem[f"slope_{side.lower()}"][0] == pytest.approx(expected, abs=math.radians(0.1))
            steep += abs(expected) > math.radians(3.0)
    assert steep > 0  # crater ground, not the level start pad only


def test_a_foot_that_bounces_off_during_the_push_keeps_its_legs_pushing() -> None:
    """A one-foot push whose foot bounced off the ground every ~30 ms swung the legs toward the
    landing pose in each gap (Ceres seeds 13 and 17, Moon 15 and 37), so the push never finished.
    Between losing the ground and the liftoff's confirmation, the legs keep the push's torques."""
    sim = Simulation(SimConfig(terrain="flat"))
    mem, d = sim.controller.mem, sim.data
    _step_until(sim, lambda s: s.phase == Phase.PUSH)
    sensors = d.sensordata.copy()
    sensors[mem["s_foot_l"][0]] = sensors[mem["s_foot_r"][0]] = 0.0  # both feet off from now on
    legs = [mem[name][0] for name in ("a_hip_l", "a_knee_l", "a_hip_r", "a_knee_r")]
    pushing, gap = None, 0
    for _ in range(40):
        before = d.ctrl[legs].copy()
        control_tick(d.qpos, d.qvel, sensors, d.ctrl, mem)
        if mem["phase"][0] != Phase.PUSH:
            break
        if mem["contact_l"][0] or mem["contact_r"][0]:
            continue
        pushing = before if pushing is None else pushing
        np.testing.assert_array_equal(d.ctrl[legs], pushing)
        gap += 1
    assert gap >= 5  # ticks of PUSH with no foot down before the flight
    assert mem["phase"][0] == Phase.FLIGHT
    assert np.any(pushing != 0.0)


def test_a_recovery_push_from_one_foot_leaves_as_quickly_as_the_legs_allow() -> None:
    """A recovery hop from one foot spread its push over the whole stroke (0.3-0.45 s on Mars), the
    CoM falling away from the foot, and the wheel, taking the moment the foot could not, filled
    before the flight (Mars seeds 7, 12 and 47 fell so). From one foot the recovery push asks the
    push's full acceleration; from two, which can take a kick's momentum out as they push, the
    least that reaches its speed."""
    sim = Simulation(SimConfig(terrain="flat"))
    mem, d = sim.controller.mem, sim.data
    _step_until(sim, lambda s: s.phase == Phase.STANCE)
    asked = {}
    for feet in (2, 1):
        m, ctrl, sensors = mem.copy(), d.ctrl.copy(), d.sensordata.copy()
        m["phase"], m["phase_start"], m["push_done"], m["recovering"] = Phase.PUSH, m["clock"], False, True
        if feet == 1:  # the right foot has left the ground
            m["contact_r"], sensors[m["s_foot_r"][0]] = False, 0.0
        control_tick(d.qpos, d.qvel, sensors, ctrl, m)
        assert m["phase"][0] == Phase.PUSH and bool(m["contact_r"][0]) == (feet == 2)
        forces = _foot_forces(m, d.qpos, ctrl)
        asked[feet] = float(forces[0][1]) + (float(forces[1][1]) if feet == 2 else 0.0)
    quickest = float(mem["mass"][0] * (mem["gravity"][0] + mem["push_accel"][0]))
    assert asked[1] == pytest.approx(quickest, rel=1e-6)
    assert float(mem["mass"][0] * mem["gravity"][0]) < asked[2] < 0.8 * quickest
