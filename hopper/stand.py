"""The gimbal test stand: the same simulation with the robot's translation held and its pitch free.

Derived from models/hopper.xml with mujoco.MjSpec (no second model to keep in step): the torso is
raised clear of the ground and held by a gimbal through the robot's CoM in the landing pose (a
connect equality: the torso turns about that point, and its slides follow), and with legs "locked"
the hips and knees are held in the landing pose by joint equalities. The kernel runs the flight's
attitude loop for as long as the stand runs (MEMORY.on_stand): no gait, no landing. With legs
"free" the flight's leg servos hold them, as in the air. A gimbal through the CoM leaves gravity no
torque to load the wheel with (both knees bend the same way: the CoM is 4 cm behind the torso's,
and a pivot there would ask the wheel for 0.3 N m for ever, filling it in seconds).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Literal

import mujoco
import numpy as np

from hopper.config import THIGH_LENGTH, InvalidConfig, SimConfig, require_finite
from hopper.events import Injected
from hopper.layout import LEG_JOINTS
from hopper.model import Derive
from hopper.sim import Simulation
from hopper.snapshot import Snapshot

Legs = Literal["locked", "free"]
LEGS: tuple[Legs, ...] = ("locked", "free")
PIVOT_HEIGHT = 3.0  # m, the torso's pivot above the terrain's zero: no foot (1.2 m below) reaches a rim
# The stand's joints held as stiffly as a 1 ms step allows (MuJoCo: time constant >= 2 timesteps).
HOLD_SOLREF = (0.002, 1.0)  # s, damping ratio
REFERENCE_LIMIT = math.radians(30.0)  # rad: a pitch reference the stand may be asked to hold


def landing_pose(config: SimConfig, thigh: float = THIGH_LENGTH) -> dict[str, float]:
    """Hip and knee angles (rad, LEG_JOINTS names) of the flight's landing pose with the torso
    level: each leg `flight_length` long (`thigh` m from hip to knee, as from knee to foot), the
    feet `foot_spread` apart under the hip."""
    gait = config.gait
    length = gait.flight_length
    knee = -2.0 * math.acos(min(length / (2.0 * thigh), 1.0))
    pose = {}
    for side, offset in (("L", gait.foot_spread / 2), ("R", -gait.foot_spread / 2)):
        angle = -math.asin(offset / length)  # the virtual leg's world angle, as the kernel's swing aims it
        pose[f"hip_{side}"], pose[f"knee_{side}"] = angle - knee / 2, knee
    return pose


PIVOT = "stand_pivot"  # the equality holding the robot's CoM (in the landing pose) still: the gimbal


def _hold(spec: mujoco.MjSpec, joint: str, value: float) -> None:
    """A joint equality holding `joint` at `value` (its qpos; MuJoCo measures from qpos0 = 0)."""
    eq = spec.add_equality()
    eq.name, eq.type, eq.objtype, eq.name1 = f"stand_{joint}", mujoco.mjtEq.mjEQ_JOINT, mujoco.mjtObj.mjOBJ_JOINT, joint
    eq.data[:5] = [value, 0.0, 0.0, 0.0, 0.0]
    eq.solref = list(HOLD_SOLREF)


def stand_model(config: SimConfig, legs: Legs) -> Derive:
    """The edit of the model's spec that puts the robot on the stand."""
    if legs not in LEGS:
        raise InvalidConfig(f"stand legs must be one of {', '.join(LEGS)}, got {legs!r}")

    def derive(spec: mujoco.MjSpec) -> None:
        pose = landing_pose(config, thigh=abs(float(spec.body("shank_L").pos[2])))  # the knee below the hip
        torso = spec.body("torso")
        torso.pos = [torso.pos[0], torso.pos[1], PIVOT_HEIGHT]
        # The gimbal: a point of the torso held still (a connect equality; its anchor, the robot's CoM
        # in the landing pose, is set once the model is compiled: StandSimulation.reset).
        pivot = spec.add_equality()
        pivot.name, pivot.type, pivot.objtype = PIVOT, mujoco.mjtEq.mjEQ_CONNECT, mujoco.mjtObj.mjOBJ_BODY
        pivot.name1, pivot.name2, pivot.solref = "torso", "world", list(HOLD_SOLREF)
        if legs == "locked":
            for joint in LEG_JOINTS:
                _hold(spec, joint, pose[joint])

    return derive


class StandSimulation(Simulation):
    """The robot on the stand: a Simulation of the derived model whose reset puts the torso level
    with the legs in the landing pose, the wheel at rest, and the kernel in its stand mode."""

    def __init__(self, config: SimConfig, legs: Legs = "locked") -> None:
        self.legs = legs
        self.injection: Injection | None = None  # the newest one played (inject)
        super().__init__(config, derive=stand_model(config, legs))

    def reset(self, reason: str = "user") -> None:
        self.stop_injection(f"the stand was reset ({reason})")
        super().reset(reason)
        mujoco.mj_resetData(self.model, self.data)  # translation and pitch at 0
        for joint, angle in self.landing_pose().items():
            self.data.joint(joint).qpos = angle
        mujoco.mj_forward(self.model, self.data)
        # The gimbal's point: the robot's CoM, in the torso's frame (level) and in the world.
        torso = self.layout.torso
        com = self.data.subtree_com[torso].copy()
        pivot = self.model.equality(PIVOT).id
        self.model.eq_data[pivot, 0:3] = com - self.data.xpos[torso]
        self.model.eq_data[pivot, 3:6] = com
        mujoco.mj_forward(self.model, self.data)
        m = self.controller.mem
        m["on_stand"], m["legs_locked"] = True, self.legs == "locked"
        m["pitch_ref"] = m["inject_ref"] = m["inject_torque"] = 0.0

    def landing_pose(self) -> dict[str, float]:
        """The legs' angles on the stand (rad): the landing pose of this robot's legs."""
        return landing_pose(self.config, self.robot.thigh)

    def start_over(self, config: SimConfig) -> None:
        raise InvalidConfig("the stand runs one configuration: build a new StandSimulation")

    @property
    def reference(self) -> float:
        """The pitch the attitude loop holds, rad."""
        return float(self.controller.mem["pitch_ref"][0])

    def set_reference(self, pitch: float) -> None:
        """Hold `pitch` (rad) from the next tick: a step of the reference."""
        limit = REFERENCE_LIMIT
        require_finite("pitch reference", pitch, -limit, limit, "rad")
        self.controller.mem["pitch_ref"] = pitch

    def restore(self, snap: Snapshot) -> None:
        self.stop_injection("a snapshot was restored")
        super().restore(snap)

    def inject(
        self,
        d: np.ndarray,
        at: Literal["input", "reference"],
        done: Callable[[Injection], None] | None = None,
        what: str = "",
    ) -> Injection:
        """Play `d` (one sample a tick: N m at the wheel torque at "input", rad at the pitch reference
        at "reference") from the next tick, as the loop runs (Injection); refused while another plays.
        A reset, a restore or stop_injection ends it early. An Injected event says `what` it is (by
        default its length and peak) as it starts and as it ends."""
        if self.injection is not None and self.injection.playing:
            played = self.injection
            raise InvalidConfig(
                f"an injection is playing ({played.played} of {len(played.d)} ticks): wait for it, or reset"
            )
        d = np.asarray(d, float)
        limit, unit = (self.robot.wheel_torque_limit, "N m") if at == "input" else (REFERENCE_LIMIT, "rad")
        if d.ndim != 1 or not len(d) or not np.isfinite(d).all() or np.abs(d).max() > limit:
            raise InvalidConfig(f"an injection is a non-empty series of finite samples within +-{limit:.3g} {unit}")
        if not what:
            peak = float(np.abs(d).max())
            size = f"{peak:.3g} N m" if at == "input" else f"{math.degrees(peak):.3g} deg"
            what = f"a {len(d) * self.model.opt.timestep:g} s signal, peak {size}"

        def ended(injection: Injection) -> None:
            self.emit(Injected(what, at, injection.played * self.model.opt.timestep, injection.stopped))
            if done is not None:
                done(injection)

        self.injection = Injection(self, d, at, ended, start=self.snapshot(with_hops=False))
        self.emit(Injected(what, at))
        return self.injection

    def stop_injection(self, why: str) -> None:
        """End the injection playing, if one is (its `done` hears `why`)."""
        if self.injection is not None:
            self.injection.stop(why)

    def settle(self, seconds: float) -> None:
        """Step `seconds` of simulation (the legs and the loop settle after a reset)."""
        for _ in range(round(seconds / self.model.opt.timestep)):
            self.step()


class Injection:
    """A signal played into the loop one sample a tick, and what the loop did: a listener of the
    simulation while it plays (it wants every tick, so they run one by one). Sample i is added in
    tick i (N m to the wheel torque at "input", rad to the pitch reference at "reference"), and what
    that tick sent and measured is read after its step. It ends by itself after the last sample, or
    by stop(why); then the injection is 0 again, it leaves the listeners, and `done(self)` is called
    (on the loop's thread)."""

    def __init__(
        self,
        sim: Simulation,
        d: np.ndarray,
        at: Literal["input", "reference"],
        done: Callable[[Injection], None] | None = None,
        start: Snapshot | None = None,
    ) -> None:
        if at not in ("input", "reference"):
            raise InvalidConfig(f"an injection point is input or reference, got {at!r}")
        m = sim.controller.mem
        self.sim, self.at, self.done = sim, at, done
        self.d = np.asarray(d, float)
        self.stopped = ""  # why it ended before its last sample ("" if it did not)
        self.played = 0  # samples stepped
        self.start = start  # where it began, if asked for: the model is linearized there
        self._inject = m["inject_torque" if at == "input" else "inject_ref"]
        self._read = (m["wheel_command"], m["law_command"], m["pitch_true"], m["saturated"], m["phase"])
        n = len(self.d)
        self._out = (np.empty(n), np.empty(n), np.empty(n), np.zeros(n, bool), np.zeros(n, np.int64))
        self.playing = n > 0
        if self.playing:
            self._inject[0] = self.d[0]
            sim.listeners.append(self)

    @property
    def length_s(self) -> float:
        return len(self.d) * self.sim.model.opt.timestep

    def records(self) -> dict[str, np.ndarray]:
        """The arrays hopper.analysis.frequency reads, as far as played, shape (played,): "d", "u"
        (the torque sent, N m), "uc" (the law's, N m), "pitch" (true, rad), "saturated" (bool: the
        envelope clamped the torque that tick) and "phase" (the kernel's)."""
        n = self.played
        u, uc, pitch, saturated, phase = (a[:n] for a in self._out)
        return {"d": self.d[:n], "u": u, "uc": uc, "pitch": pitch, "saturated": saturated, "phase": phase}

    def tick(self, sim: Simulation) -> None:
        i = self.played
        for source, out in zip(self._read, self._out, strict=True):
            out[i] = source[0]
        self.played = i + 1
        if self.played < len(self.d):
            self._inject[0] = self.d[self.played]
        else:
            self._end("")

    def event(self, sim: Simulation, event: object) -> None:
        pass

    def stop(self, why: str) -> None:
        """End it before its last sample (nothing if it has ended)."""
        if self.playing:
            self._end(why)

    def _end(self, why: str) -> None:
        self.playing, self.stopped = False, why
        self._inject[0] = 0.0
        # A new list, not remove(): this runs inside the simulation's loop over its listeners.
        self.sim.listeners = [listener for listener in self.sim.listeners if listener is not self]
        if self.done is not None:
            self.done(self)


def record(sim: Simulation, d: np.ndarray, at: Literal["input", "reference"]) -> dict[str, np.ndarray]:
    """Step `sim` one tick per sample of `d`, adding it at the plant input (N m on the wheel torque)
    or at the pitch reference (rad): Injection.records() of the whole of it."""
    injection = Injection(sim, d, at)
    try:
        for _ in range(len(injection.d)):
            sim.step()
    finally:
        injection.stop("interrupted")
    return injection.records()
