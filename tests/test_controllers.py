"""The controller API in process: loading, params, the guard's every refusal, state in snapshots,
the observation's fields against physics, and the compiled PID against its Python twin."""

from __future__ import annotations

import dataclasses
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from hopper.config import WHEEL_NO_LOAD_SPEED, WHEEL_TORQUE_LIMIT, SimConfig
from hopper.control.wheel import WHEEL_DAMPING
from hopper.controllers import ControllerError, Observation, Param, build, with_controller
from hopper.controllers.law import BUDGET_WINDOW, WARM_UP_CALLS
from hopper.events import EventKind
from hopper.history import History, fly
from hopper.sim import Simulation

README = Path(__file__).resolve().parents[1] / "README.md"

CONTROLLERS = '''
import math, time
from hopper.controllers import Param
from hopper.laws.pid import PaperPID

class PythonPID(PaperPID):
    compiled = None  # the paper's law through the API, not the kernel

class Integrating:
    """A stateful law: PD plus its own integral, so that its state matters for a re-fly."""
    params = (Param("kp", 400.0, (0.0, 2000.0), "N m/rad"), ("kd", 30.0, (0.0, 100.0), "N m s/rad"))
    def reset(self, obs):
        self.integral = 0.0
    def __call__(self, obs):
        self.integral += obs.pitch * obs.dt
        return self.kp * obs.pitch + self.kd * obs.rate + 60.0 * self.integral

class Seen:
    seen = []
    def __call__(self, obs):
        Seen.seen.append(obs)
        return 400.0 * obs.pitch + 30.0 * obs.rate

class NaN:
    def __call__(self, obs): return math.nan
class Inf:
    def __call__(self, obs): return -math.inf
class Text:
    def __call__(self, obs): return "torque"
class Boom:
    def __call__(self, obs): raise RuntimeError("boom")
class BadReset:
    def reset(self, obs): raise KeyError("state")
    def __call__(self, obs): return 0.0
class Slow:
    def __call__(self, obs):
        end = time.perf_counter() + 0.0015
        while time.perf_counter() < end: pass
        return 0.0
class TwoArgs:
    def __call__(self, obs, extra): return 0.0
class NoCall:
    pass
class BadParams:
    params = (("kp", 5000.0, (0.0, 10.0), "N m/rad"),)
    def __call__(self, obs): return 0.0
class BrokenInit:
    def __init__(self): raise ValueError("no config file")
    def __call__(self, obs): return 0.0

class LateNaN:
    """Flies, then answers NaN in its second flight."""
    def __init__(self): self.flights = 0
    def reset(self, obs): self.flights += 1
    def __call__(self, obs): return math.nan if self.flights == 2 else 400.0 * obs.pitch + 30.0 * obs.rate
class Paused:
    """One call in its second flight stalls 0.2 s, as a descheduled thread or a garbage collection does."""
    def __init__(self): self.flights, self.stalled = 0, False
    def reset(self, obs): self.flights += 1
    def __call__(self, obs):
        if self.flights == 2 and not self.stalled:
            self.stalled = True
            time.sleep(0.2)
        return 400.0 * obs.pitch + 30.0 * obs.rate
class LateSlow:
    """Flies, then spends 2 ms a call from its second flight."""
    def __init__(self): self.flights = 0
    def reset(self, obs): self.flights += 1
    def __call__(self, obs):
        if self.flights >= 2:
            end = time.perf_counter() + 0.002
            while time.perf_counter() < end: pass
        return 400.0 * obs.pitch + 30.0 * obs.rate
'''


@pytest.fixture(scope="module")
def laws(tmp_path_factory: pytest.TempPathFactory) -> str:
    """A file of controllers outside the package; its path, for specs FILE.py:Class."""
    path = tmp_path_factory.mktemp("laws") / "laws.py"
    path.write_text(CONTROLLERS)
    return str(path)


def readme_example() -> str:
    """The README's complete example controller, as a user copies it."""
    text = README.read_text(encoding="utf-8")
    section = text[text.index("## Bring your own controller") :]
    start = section.index("```python\n") + len("```python\n")
    return section[start : section.index("```", start)]


def flown(config: SimConfig, hops: int = 3) -> Simulation:
    sim = Simulation(config)
    sim.run(hops)
    return sim


# -- the PID, compiled and through the API -------------------------------------------------------


@pytest.mark.parametrize("sensing", ["ideal", "realistic"])
def test_the_pid_through_the_api_flies_bit_identical_to_the_compiled_kernel(laws: str, sensing: str) -> None:
    config = SimConfig(seed=4, sensing=sensing)
    compiled = flown(config, 4)
    python = flown(with_controller(config, f"{laws}:PythonPID"), 4)
    assert python.law.compiled is None and python.law.calls > 1000
    assert compiled.hops == python.hops and compiled.time == python.time
    assert compiled.data.qpos.tobytes() == python.data.qpos.tobytes()


# -- loading --------------------------------------------------------------------------------------


def test_the_readme_example_loads_from_a_file_outside_the_package(tmp_path: Path) -> None:
    path = tmp_path / "my_controller.py"
    path.write_text(readme_example())
    sim = flown(with_controller(SimConfig(), f"{path}:LandLevel", {"boost": 2.0}), 3)
    assert not sim.fallen and len(sim.hops) == 3 and sim.controller_fault is None
    assert sim.law.name == "LandLevel" and sim.law.values == {"kp": 300.0, "kd": 25.0, "boost": 2.0}
    assert sim.law.controller.flights >= 3  # reset at each liftoff (the probe's reset is undone)
    assert max(abs(h.landing_pitch_deg) for h in sim.hops) < 3.5


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("nope", "unknown controller 'nope'; choose pid, lqr"),
        ("/nowhere/laws.py:X", "controller file /nowhere/laws.py does not exist"),
        ("hopper.laws.pid:Nope", "hopper.laws.pid has no class 'Nope' (classes there: PaperPID)"),
        ("no_such_package.laws:X", "no module 'no_such_package.laws'"),
        ("LAWS:TwoArgs", "TwoArgs.__call__ must take (self, obs); it takes (obs, extra)"),
        ("LAWS:NoCall", "has no __call__(self, obs) -> float"),
        ("LAWS:BadParams", "BadParams.params must be Param(name, default, (low, high), unit) entries"),
        ("LAWS:BrokenInit", "BrokenInit() failed: ValueError: no config file"),
        ("LAWS:NaN", "NaN returned nan N m, not a finite torque"),
        ("LAWS:Inf", "Inf returned -inf N m, not a finite torque"),
        ("LAWS:Text", "Text returned str 'torque', not a torque in N m"),
        ("LAWS:Boom", "Boom raised RuntimeError: boom"),
        ("LAWS:BadReset", "BadReset.reset raised KeyError: 'state'"),
        ("LAWS:Slow", "us a call, over the budget of 1000 us"),
    ],
)
def test_a_controller_that_cannot_fly_is_refused_before_the_run_with_one_line(
    laws: str, spec: str, message: str
) -> None:
    with pytest.raises(ControllerError) as caught:
        Simulation(with_controller(SimConfig(), spec.replace("LAWS", laws)))
    text = str(caught.value)
    assert message in text and "\n" not in text, text


def test_params_are_checked_by_name_and_range(laws: str) -> None:
    spec = f"{laws}:Integrating"
    with pytest.raises(ControllerError, match=r"Integrating has no parameter ki \(its parameters: kp, kd\)"):
        build(spec, {"ki": 1.0})
    with pytest.raises(ControllerError, match=r"parameter kp = 3000 is outside \[0, 2000\] N m/rad"):
        build(spec, {"kp": 3000.0})
    with pytest.raises(ControllerError, match="PaperPID has no parameter boost"):
        with_controller(SimConfig(), "pid", {"boost": 1.0})
    assert with_controller(SimConfig(), "pid", {"kp": 300.0}).gains.kp == 300.0  # the PID's params are the gains
    assert build(spec, {"kp": 100.0}).kp == 100.0 and build(spec).kd == 30.0


def test_an_installed_package_registers_a_controller_by_entry_point(tmp_path: Path, monkeypatch) -> None:
    package = tmp_path / "myhopperlaws"
    package.mkdir()
    (package / "__init__.py").write_text(
        "class Gentle:\n    def __call__(self, obs):\n        return 300.0 * obs.pitch\n"
    )
    info = tmp_path / "myhopperlaws-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: myhopperlaws\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[hopper.controllers]\ngentle = myhopperlaws:Gentle\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    sim = flown(with_controller(SimConfig(terrain="flat"), "gentle"), 2)
    assert type(sim.law.controller).__name__ == "Gentle" and not sim.fallen
    monkeypatch.delitem(sys.modules, "myhopperlaws")


# -- the guard in flight ----------------------------------------------------------------------------


@pytest.mark.parametrize(("name", "cause"), [("LateNaN", "returned nan N m"), ("LateSlow", "over its budget")])
def test_a_controller_failing_in_flight_hands_over_to_the_pid_and_says_why(laws: str, name: str, cause: str) -> None:
    sim = flown(with_controller(SimConfig(terrain="flat"), f"{laws}:{name}"), 4)
    assert not sim.fallen and len(sim.hops) == 4  # the PID flew the rest
    failed = [e for e in sim.events if e.kind is EventKind.CONTROLLER_FAILED]
    assert len(failed) == 1 and cause in failed[0].payload.cause, sim.controller_fault
    assert sim.config.controller == "pid" and sim.failed_law.name == name
    assert sim.events[sim.events.index(failed[0]) + 1].kind is EventKind.CONTROLLER  # the PID, announced
    if name == "LateSlow":  # within the window of calls it is averaged over, after its second liftoff
        liftoffs = [e.time for e in sim.events if e.kind is EventKind.LIFTOFF]
        assert 0 < failed[0].time - liftoffs[1] <= (WARM_UP_CALLS + 2 * BUDGET_WINDOW) * 1e-3 + 1e-9


def test_one_stalled_call_is_not_the_controllers_cost(laws: str) -> None:
    sim = flown(with_controller(SimConfig(terrain="flat"), f"{laws}:Paused"), 3)
    assert sim.law.controller.stalled and sim.controller_fault is None and sim.config.controller.endswith(":Paused")


def test_a_batch_marks_the_episode_failed_with_the_cause(laws: str) -> None:
    from hopper.experiments.spec import Episode
    from hopper.experiments.worker import Worker

    worker = Worker()
    base = {"kp": 450.0, "ki": 50.0, "kd": 30.0, "gravity": 1.625, "seed": 0, "hops_target": 3, "terrain": "flat",
            "wheel": True, "sensing": "ideal"}  # fmt: skip
    late = worker.run(Episode(**base, controller=f"{laws}:LateNaN"))
    refused = worker.run(Episode(**base, controller=f"{laws}:Boom"))
    fine = worker.run(Episode(**base))
    assert "returned nan N m" in late.controller_fault and late.row()["controller_fault"] == late.controller_fault
    assert "Boom raised RuntimeError: boom" in refused.controller_fault and refused.hops == ()
    assert fine.controller_fault == "" and len(fine.hops) == 3


# -- the observation -------------------------------------------------------------------------------


@pytest.fixture
def seen(laws: str):
    from hopper.controllers.loading import load_class

    cls = load_class(f"{laws}:Seen")
    cls.seen.clear()
    return cls


def test_the_observation_holds_what_the_contract_says(laws: str, seen) -> None:
    sim = Simulation(with_controller(SimConfig(terrain="flat"), f"{laws}:Seen"))
    seen.seen.clear()  # the pre-run check's calls
    touchdowns = []
    while len(sim.hops) < 2:
        if sim.step() & 2:  # EV_TOUCHDOWN
            touchdowns.append(sim.time - sim.config.timestep)
    obs: list[Observation] = list(seen.seen)
    first = obs[0]
    with pytest.raises(AttributeError):
        first.pitch = 0.0  # type: ignore[misc]
    assert first.time_since_liftoff == 0.0 and first.dt == sim.config.timestep and first.gravity == 1.625
    # The ballistic prediction at liftoff and at the apex, against the touchdown the flight had.
    flight = [o for o in obs if o.time < touchdowns[0]]
    predicted = flight[0].time + flight[0].time_to_touchdown
    assert abs(predicted - touchdowns[0]) < 0.03, (predicted, touchdowns[0])
    late = flight[-1]
    assert late.time_to_touchdown < 0.03
    for o in obs[::97]:
        spin = o.wheel_inertia
        assert o.momentum_headroom == pytest.approx((spin * (WHEEL_NO_LOAD_SPEED - o.wheel_speed),
                                                     spin * (WHEEL_NO_LOAD_SPEED + o.wheel_speed)))  # fmt: skip
        back = WHEEL_DAMPING * o.wheel_speed
        assert o.torque_bounds == (max(-WHEEL_TORQUE_LIMIT, -WHEEL_TORQUE_LIMIT - back),
                                   min(WHEEL_TORQUE_LIMIT, WHEEL_TORQUE_LIMIT - back))  # fmt: skip
    assert 0.035 < first.wheel_inertia < 0.04  # 0.03375 kg m^2 disc + 0.0045 armature (models/hopper.xml)


# -- determinism: state in snapshots --------------------------------------------------------------


def test_a_stateful_controller_refly_is_bit_identical(laws: str) -> None:
    sim = Simulation(with_controller(SimConfig(seed=2, sensing="realistic"), f"{laws}:Integrating"))
    history = History()
    sim.listeners.append(history)
    sim.run(3)
    recorded = history.last_flight
    assert recorded is not None and recorded.controller.endswith(":Integrating")
    again = fly(recorded.start)
    assert again.pitch.tobytes() == recorded.pitch.tobytes() and again.torque.tobytes() == recorded.torque.tobytes()
    assert dataclasses.replace(again.hop, index=recorded.hop.index) == recorded.hop  # the start holds no hops


def test_a_restore_mid_flight_continues_the_controller_exactly(laws: str) -> None:
    sim = Simulation(with_controller(SimConfig(seed=5), f"{laws}:Integrating"))
    while not sim.law.calls > 300:  # well into a flight: the integral is not zero
        sim.step()
    snap = sim.snapshot()
    sim.run(2)
    end, hops = sim.data.qpos.copy(), list(sim.hops)
    sim.restore(snap)
    assert sim.law.controller.integral != 0.0
    sim.run(2)
    assert sim.data.qpos.tobytes() == end.tobytes() and sim.hops == hops


def test_refly_with_another_controller_flies_the_same_flight(laws: str) -> None:
    sim = Simulation(SimConfig(seed=1))
    history = History()
    sim.listeners.append(history)
    sim.run(2)
    recorded = history.last_flight
    other = fly(recorded.start, with_controller(sim.config, "lqr"))
    same = fly(recorded.start)
    assert other.controller == "lqr" and same.controller == "pid" and other.label == "lqr"
    assert other.start is recorded.start and other.hop is not None and other.hop.completed
    assert other.pitch.tobytes() != same.pitch.tobytes() and same.pitch.tobytes() == recorded.pitch.tobytes()


# -- the built-in LQR ------------------------------------------------------------------------------


@pytest.mark.parametrize("gravity", [0.28, 1.625, 3.72, 9.81])
def test_lqr_flies_at_every_gravity_and_designs_for_it(gravity: float) -> None:
    sim = flown(dataclasses.replace(with_controller(SimConfig(seed=7, sensing="realistic"), "lqr"), gravity=gravity), 3)
    assert not sim.fallen and len(sim.hops) == 3 and sim.controller_fault is None
    k = sim.law.controller.state_feedback()
    assert k[0] > 0 and k[1] > 0 and k[2] < 0  # PD-like on the torso, and it spends the wheel's speed
    assert max(abs(h.landing_pitch_deg) for h in sim.hops) < 3.5
    radius = np.abs(np.linalg.eigvals(sim.law.controller.model.a + np.outer(sim.law.controller.model.b, k))).max()
    assert radius < 1.0


def test_an_lqr_whose_gain_was_read_before_its_first_flight_flies_it() -> None:
    """The dashboard reads K for its loop analysis before any flight. The LQR then flew zero torque (its
    per-tick copy of K was set only by its own first call) and fell at the end of every first hop."""
    sim = Simulation(with_controller(SimConfig(terrain="flat"), "lqr"))
    sim.law.controller.state_feedback()  # as the dashboard's analysis panel does at start
    sim.run(3)
    assert not sim.fallen and len(sim.hops) == 3
    assert max(h.peak_wheel_torque_nm for h in sim.hops) > 1.0  # the wheel flew: not the zero gain


def test_the_readme_example_is_valid_python_with_its_imports() -> None:
    source = readme_example()
    compile(source, "my_controller.py", "exec")
    assert "from hopper.controllers import Param" in source and "class LandLevel" in textwrap.dedent(source)


def test_param_tuples_are_accepted_as_params() -> None:
    assert Param("kp", 1.0, (0.0, 2.0)).check(1.5, "X") == 1.5
    with pytest.raises(ControllerError, match="must be a number"):
        Param("kp", 1.0, (0.0, 2.0)).check("fast", "X")
