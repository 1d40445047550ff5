"""The simulation: model, controller, phases and metrics stepped together at 1 kHz.

The headless runner and the dashboard both drive this class. Only its `step()` touches MjData;
other threads `submit()` commands (`Command`; hopper.commands names them) that the next step applies.
"""

from __future__ import annotations

import collections
import dataclasses
import logging
import math
from collections.abc import Callable
from typing import Literal, Protocol

import mujoco
import numpy as np

from hopper.ballistics import Ground, predict
from hopper.config import (
    GRAVITY_LIMITS,
    Gains,
    InvalidConfig,
    SimConfig,
    require_finite,
)
from hopper.control import EV_APEX, EV_FALL, EV_LIFTOFF, EV_TOUCHDOWN, HopController, Phase, control_tick
from hopper.control.kernel import EV_WHEEL, finish_wheel
from hopper.control.memory import MEMORY
from hopper.controllers import (
    ControllerContext,
    ControllerError,
    ControllerFault,
    FlightLaw,
    Observation,
    params_of,
    with_controller,
)
from hopper.disturbances import DISTURBANCE_LIMITS, DisturbanceKind
from hopper.errors import HopperError
from hopper.events import (
    Apex,
    CommandFailed,
    ControllerChanged,
    ControllerFailed,
    Disturbance,
    DisturbanceArmed,
    Diverged,
    Dragged,
    Event,
    Fall,
    GainsChanged,
    GravityChanged,
    Liftoff,
    Payload,
    Reset,
    ScheduleChanged,
    SensingChanged,
    TerrainChanged,
    Touchdown,
    WheelChanged,
)
from hopper.layout import ModelLayout
from hopper.metrics import HopMetrics, MetricsTracker
from hopper.mismatch import Nominal
from hopper.model import Derive, build_model, model_source, set_terrain, set_wheel_enabled, terrain_window
from hopper.mujoco_compat import address
from hopper.perturb import Pull
from hopper.robot import Robot
from hopper.schedule import KickSchedule
from hopper.snapshot import STATE_SPEC, Pending, Snapshot, SnapshotMismatch
from hopper.state import RobotState, angular_momentum, read_state
from hopper.stepping import burst

log = logging.getLogger(__name__)

TORQUE_PULSE_S = 0.1  # s, how long a torque pulse (hopper.disturbances.DISTURBANCE_LIMITS) acts
TORQUE_PULSE_DELAY_S = 0.15  # s after liftoff, when armed on the ground
PROBE_PITCH, PROBE_RATE = 0.02, 0.2  # rad, rad/s: the pre-run check's flight tick (hopper.controllers.law)
HEALTH_CHECK_TICKS = 50  # ticks between checks for a diverged state
STOP_POLL_TICKS = 100  # ticks between two asks of run()'s stop(): a Ctrl-C ends a run within 0.1 s simulated
# The newest events kept in sim.events (listeners see every one): ~3,300 hops, ~6 MB at the ~590 B
# an event that benchmarks/soak_terrain.py measured; unbounded, a 10,000-hop run grew 8 % by them.
EVENT_RECORD = 10_000


class Command(Protocol):
    """Anything with apply(sim): submit() queues it, the loop applies it (hopper.commands names the usual ones)."""

    def apply(self, sim: Simulation) -> None: ...


class Listener(Protocol):
    """Sees every tick (after mj_step) and every event; telemetry and the dashboard implement it.

    A listener whose tick() does nothing until some moment may also have `idle_until(sim) -> float`:
    the simulated time (s, data.time after a tick's step) before which its tick() does nothing. While
    every listener is idle, the ticks run compiled without calling them (Simulation.advance). One
    listener may ask those ticks to record two values each: `flight_trace()` (hopper.history.History).
    """

    def tick(self, sim: Simulation) -> None: ...

    def event(self, sim: Simulation, event: Event) -> None: ...


class Simulation:
    """One robot on one terrain, stepped one control tick at a time.

    `config` is the live configuration: gain, wheel, gravity and terrain changes replace it, so
    whatever reads it (recordings, run reports) sees what the robot runs now. The terrain is
    endless: `terrain` is the window of it in the model's heightfield, moved (in place, no
    recompile) at a flight's apex when the robot nears its edge, sooner if it must (_follow).
    """

    def __init__(self, config: SimConfig, derive: Derive | None = None) -> None:
        """`derive` edits the model's spec before it compiles (a variant: hopper.stand)."""
        self.config = config
        self.terrain = terrain_window(config)
        self.model = build_model(config, self.terrain, derive)
        # What the controller knows of the robot: its model's, as built (a mismatch is the real robot's).
        self.robot = Robot.of(self.model, model_source(config))
        self._nominal = Nominal.of(self.model)  # what a mismatch scales (hopper.mismatch)
        if config.mismatch:
            self._nominal.apply(self.model, config.mismatch)
        self.data = mujoco.MjData(self.model)
        self.layout = ModelLayout.of(self.model)
        self.controller = HopController(self.layout, config, self.robot)
        self.metrics = MetricsTracker(self.controller.mem, robot=self.robot)
        self.events: collections.deque[Event] = collections.deque(maxlen=EVENT_RECORD)  # the newest
        self.listeners: list[Listener] = []
        self.run_index = -1  # counts resets: the one at construction makes it 0
        self._commands: collections.deque[Command] = collections.deque()
        # MjData's array properties build a new numpy view per access: keep one of each.
        d = self.data
        self._qpos, self._qvel, self._sensors, self._ctrl = d.qpos, d.qvel, d.sensordata, d.ctrl
        self._mem, self._dt = self.controller.mem, self.model.opt.timestep
        self._raw = (address(self.model), address(d))  # the C structs, for compiled ticks (hopper.stepping)
        self._arrays = (self._qpos, self._qvel, self._sensors, self._ctrl, self._mem)
        # Views the observation reads each flight tick of an API controller (hopper.controllers).
        self._law_pitch, self._rate_est = self._mem["law_pitch"], self._mem["rate_est"]
        self._v_wheel = self.layout.v_wheel
        self._q_x = self.layout.q_x
        self.ticks = 0  # control ticks stepped since construction
        self.schedule: KickSchedule | None = None  # the repeatable test's kick (hopper.schedule)
        self.pending = Pending()  # the torque pulse and scheduled kick under way (hopper.snapshot)
        self.pull: Pull | None = None  # a mouse drag under way (hopper.perturb)
        self.law: FlightLaw | None = None  # the flight's wheel law (hopper.controllers); set below
        self.controller_fault: str | None = None  # why the controller was replaced by the PID, if it was
        self.failed_law: FlightLaw | None = None  # the controller that was replaced
        self._ground_profile: Ground | None = None  # for the obs' time_to_touchdown, built on first use
        wheel = self.model.body("wheel").id
        self._spin_inertia = float(self.model.body_inertia[wheel].max() + self.model.dof_armature[self.layout.v_wheel])
        r = self.robot  # the motor's envelope as the controller knows it, for the observation
        self._damping, self._limit, self._top = r.wheel_damping, r.wheel_torque_limit, r.wheel_no_load_speed
        self._bind_law(config)
        self.reset(reason="start")

    # -- reading ---------------------------------------------------------------------------
    @property
    def time(self) -> float:
        return self.data.time

    @property
    def phase(self) -> Phase:
        return self.controller.phase

    @property
    def hops(self) -> list[HopMetrics]:
        return self.metrics.hops

    @property
    def gains(self) -> Gains:
        return self.config.gains

    @property
    def fallen(self) -> bool:
        return self.controller.phase is Phase.FALLEN

    @property
    def heights(self) -> np.ndarray:
        """The terrain window's heights (m), shape (nrow, ncol), its column 0 at world x = terrain.x0.
        A new array each time the window moves: compare it with `is` to see a move."""
        return self.terrain.heights

    def ground_profile(self) -> Ground:
        """The terrain under the feet's lines in the window now (hopper.ballistics), built once per window."""
        if self._ground_profile is None or self._ground_profile.heights is not self.terrain.heights:
            self._ground_profile = Ground(self.terrain, self.robot)
        return self._ground_profile

    def state(self) -> RobotState:
        """The robot now (a snapshot; read it on the simulation's thread)."""
        return read_state(self.data, self.layout)

    # -- state -----------------------------------------------------------------------------
    def snapshot(self, *, with_hops: bool = True) -> Snapshot:
        """The simulation now, whole (call between ticks, on its thread); restore() takes it back."""
        physics = np.empty(mujoco.mj_stateSize(self.model, STATE_SPEC))
        mujoco.mj_getState(self.model, self.data, physics, STATE_SPEC)
        return Snapshot(
            time=float(self.data.time),
            physics=physics,
            sensors=self.data.sensordata.copy(),
            memory=self.controller.mem.copy(),
            pending=dataclasses.replace(self.pending),
            progress=dataclasses.replace(self.metrics.progress),
            hops=tuple(self.metrics.hops) if with_hops else None,
            config=self.config,
            schedule=self.schedule,
            law=self.law.state() if self._external else None,
            terrain_first=self.terrain.first,
        )

    def check_fits(self, snap: Snapshot) -> None:
        """Raise SnapshotMismatch unless the snapshot's arrays fit this model and controller."""
        size = mujoco.mj_stateSize(self.model, STATE_SPEC)
        if snap.physics.shape != (size,):
            raise SnapshotMismatch(f"state has {snap.physics.size} values, this model needs {size}")
        if snap.sensors.shape != self.data.sensordata.shape:
            raise SnapshotMismatch(f"{snap.sensors.size} sensor values, this model has {self.data.sensordata.size}")
        if snap.config.model != self.config.model:
            raise SnapshotMismatch(
                f"state of model {model_source(snap.config)}, this one flies {model_source(self.config)}"
            )
        if snap.memory.dtype != MEMORY or snap.memory.shape != (1,):
            raise SnapshotMismatch("the controller memory has another layout")
        for name in ("q_x", "q_pitch", "v_x", "s_gyro", "s_wheel_torque", "a_wheel"):
            if snap.memory[name][0] != self.controller.mem[name][0]:
                raise SnapshotMismatch(f"controller memory indexes another model ({name})")

    def restore(self, snap: Snapshot) -> None:
        """Put the simulation back into `snap` exactly (call between ticks, on its thread).

        The plant settings come first (a terrain change resets the robot), then the state. mj_forward
        refreshes the poses for display; the sensor values are then put back, because the kernel reads
        the ones mj_step computed before integrating, not those of the integrated state.
        """
        self.check_fits(snap)
        self.reconfigure(snap.config)
        self._place_terrain(self.terrain.start if snap.terrain_first is None else snap.terrain_first)
        mujoco.mj_setState(self.model, self.data, snap.physics, STATE_SPEC)
        mujoco.mj_forward(self.model, self.data)
        self.data.sensordata[:] = snap.sensors
        self.controller.mem[:] = snap.memory
        if self.schedule != snap.schedule:
            self.set_schedule(snap.schedule)
        self.pending = dataclasses.replace(snap.pending)
        self.metrics.progress = dataclasses.replace(snap.progress)
        if self._external:
            self.law.set_state(snap.law)
        if snap.hops is not None:
            self.metrics.hops[:] = snap.hops

    def reconfigure(self, config: SimConfig) -> None:
        """Bring the plant and gains to `config` through the setters (each emits its event); the
        rest of it (gait, sensor parameters) is taken as it is."""
        c = self.config
        if (c.terrain, c.seed) != (config.terrain, config.seed):
            self.set_terrain(config.terrain, config.seed)
        if c.gravity != config.gravity:
            self.set_gravity(config.gravity)
        if c.wheel != config.wheel:
            self.set_wheel(config.wheel)
        if c.sensing != config.sensing:
            self.set_sensing(config.sensing)
        if c.gains != config.gains:
            self.set_gains(config.gains, "restored")
        if c.mismatch != config.mismatch:
            self._nominal.apply(self.model, config.mismatch)
        if (c.controller, c.controller_params) != (config.controller, config.controller_params):
            self.set_controller(config.controller, config.controller_params)
        self.config = config
        self.controller.configure(config)

    def start_over(self, config: SimConfig) -> None:
        """Become what Simulation(config) builds, without a recompile: same model size, timestep
        and crater parameters (a new terrain or seed is written in place). A batch runs thousands
        of episodes this way on one model; each begins with empty events and a fresh controller."""
        c = self.config
        if config.timestep != c.timestep or config.craters != c.craters or config.model != c.model:
            raise InvalidConfig("episodes on one model share the model, the timestep and the crater parameters")
        if (config.terrain, config.seed) != (c.terrain, c.seed):
            self.terrain = terrain_window(config)
            set_terrain(self.model, self.terrain)
        self.model.opt.gravity[2] = -config.gravity
        set_wheel_enabled(self.model, config.wheel)
        if config.mismatch != c.mismatch:
            self._nominal.apply(self.model, config.mismatch)
        self.config = config
        self.controller.start_over(config)
        self._ground_profile = None
        self._bind_law(config)
        self.controller_fault = self.failed_law = None
        self.events.clear()
        self.ticks = 0  # the health check's phase, as in a new Simulation
        self.reset(reason="start")

    # -- stepping --------------------------------------------------------------------------
    def step(self) -> int:
        """One control tick: apply queued commands, control (kernel), mj_step, notify listeners.

        Returns the tick's event bits (hopper.control.EV_*), 0 on most ticks.
        """
        if self._commands:
            self._drain()
        return self._finish_tick(control_tick(self._qpos, self._qvel, self._sensors, self._ctrl, self._mem))

    def _finish_tick(self, events: int) -> int:
        """The tick after its kernel run (`events`, its bits): the events, pending actions, mj_step, listeners."""
        if events:
            if events & EV_WHEEL:  # a Python controller flies the wheel this tick
                events ^= EV_WHEEL
                if events:
                    self._controller_events(events)
                self._fly_wheel()
            else:
                self._controller_events(events)
        pending = self.pending
        if pending.pulse_at != math.inf and pending.pulse_at <= self.data.time:
            self._pulse_event()
        if pending.kick_at != math.inf and pending.kick_at <= self.data.time:
            self._scheduled_kick()
        mujoco.mj_step(self.model, self.data)
        self.ticks += 1
        if self.ticks % HEALTH_CHECK_TICKS == 0:
            self._check_health()
        for listener in self.listeners:
            listener.tick(self)
        return events

    def advance(self, count: int) -> tuple[int, int]:
        """Up to `count` ticks, exactly as many step() calls: (ticks taken, the last one's events). It
        stops after the first tick with events, and before a tick with queued commands (they apply at
        the next call). Ticks in which no Python is due (no event, no pending action, every listener
        idle: Listener.idle_until) run compiled, back to back (hopper.stepping); commands queued
        meanwhile wait for the end of the burst (at most HEALTH_CHECK_TICKS)."""
        taken = 0
        while taken < count:
            if self._commands:
                if taken:  # the caller sees what they did (a pause) before more ticks
                    return taken, 0
                self._drain()
            n = min(count - taken, HEALTH_CHECK_TICKS - self.ticks % HEALTH_CHECK_TICKS)
            stepped, events = self._burst(n)
            taken += stepped
            if stepped:
                self.ticks += stepped
                if self.ticks % HEALTH_CHECK_TICKS == 0:
                    self._check_health()  # the listeners were idle: nothing else of the tick is due
            if events:  # the next tick's kernel has run: Python finishes it
                return taken + 1, self._finish_tick(events)
            if stepped < n:  # Python is due in the next tick
                taken += 1
                events = self.step()
                if events:
                    return taken, events
        return taken, 0

    def _burst(self, count: int) -> tuple[int, int]:
        """hopper.stepping.burst up to the next moment Python is due; (0, 0) if a listener wants every tick."""
        after, trace = math.inf, None
        for listener in self.listeners:
            idle_until = getattr(listener, "idle_until", None)
            if idle_until is None:
                return 0, 0
            after = min(after, idle_until(self))
            flight = getattr(listener, "flight_trace", None)  # idle but for recording a flight (hopper.history)
            wanted = flight() if flight is not None else None
            if wanted is not None:
                if trace is not None:
                    return 0, 0  # one trace a burst
                trace = wanted
        pending = self.pending
        before = min(pending.pulse_at, pending.kick_at)
        return burst(count, before, after, self._arrays, *self._raw, trace)

    # -- the controller (hopper.controllers) -----------------------------------------------------
    def observation(self) -> Observation:
        """What an API controller sees this tick (its sensing: the estimate in realistic mode)."""
        w, t = float(self._qvel[self._v_wheel]), self.data.time
        back_emf, limit, top, spin = self._damping * w, self._limit, self._top, self._spin_inertia
        return Observation(
            float(self._law_pitch[0]),  # the estimate less the pitch reference
            float(self._rate_est[0]),
            w,
            t,
            t - self.pending.liftoff_at,
            max(self.pending.touchdown_at - t, 0.0),
            self.config.gravity,
            self._dt,
            (spin * (top - w), spin * (top + w)),
            (max(-limit, -limit - back_emf), min(limit, limit - back_emf)),
            spin,
            top,
        )  # positional: Observation's field order (hopper.controllers.api); ~1 us a tick less than by name

    def _fly_wheel(self) -> None:
        try:
            command = self.law(self.observation())
        except ControllerFault as fault:
            self._controller_failed(str(fault))
            command = 0.0  # this one tick; the compiled PID flies from the next
        finish_wheel(self._qvel, self._ctrl, self._mem, command)

    def _controller_failed(self, cause: str) -> None:
        """Fly on with the built-in PID (the config's gains) and say why."""
        log.warning("controller %s failed: %s", self.config.controller, cause)
        spec = self.config.controller
        self.controller_fault, self.failed_law = cause, self.law
        self._emit(ControllerFailed(spec, cause))
        self._bind_law(dataclasses.replace(self.config, controller="pid", controller_params=()), probe=False)
        self._emit(ControllerChanged("pid", self.law.name, self._law_values()))

    def _bind_law(self, config: SimConfig, probe: bool = True) -> None:
        """Build config's controller, configure it for this plant and check it on a flight tick
        (ControllerError, with nothing changed, if it cannot fly)."""
        law = FlightLaw(config)
        law.configure(ControllerContext(config, self.model))
        if law.compiled is None and probe:
            obs = self.observation()._replace(
                pitch=PROBE_PITCH, rate=PROBE_RATE, time_since_liftoff=0.1, time_to_touchdown=1.0, wheel_speed=0.0
            )
            momentum = self._spin_inertia * self._top
            obs = obs._replace(gravity=config.gravity, momentum_headroom=(momentum, momentum))
            law.probe(obs)
        self.law, self.config = law, config
        self._external = law.compiled is None
        self.controller.mem["external"] = self._external

    def set_controller(self, spec: str, values: object = ()) -> None:
        """Fly `spec` with param `values` from the next tick (reset first; ControllerError if it cannot)."""
        config = with_controller(self.config, spec, values)  # type: ignore[arg-type]
        self._bind_law(config)
        self.controller.configure(config)
        self.controller_fault = self.failed_law = None
        self._emit(ControllerChanged(config.controller, self.law.name, self._law_values()))

    def _law_values(self) -> tuple[tuple[str, float], ...]:
        """The flying controller's param values (the PID's are the config's gains)."""
        values = params_of(self.config) if self._external is False else self.law.values
        return tuple(values.items())

    def set_controller_param(self, name: str, value: float) -> None:
        """Change one param of the controller flying now (for the PID: a gain)."""
        if self.config.controller == "pid":
            if name not in ("kp", "ki", "kd"):
                raise ControllerError(f"PaperPID has no parameter {name} (its parameters: kp, ki, kd)")
            self.set_gains(dataclasses.replace(self.config.gains, **{name: value}))
            return
        self.law.set_param(name, value)
        self.config = dataclasses.replace(self.config, controller_params=tuple(sorted(self.law.values.items())))
        self._emit(ControllerChanged(self.config.controller, self.law.name, self._law_values()))

    def _predict_touchdown(self) -> None:
        """When the flight will end, from the CoM's parabola and the terrain under the planned feet."""
        s, lay, g = self.data.sensordata, self.layout, self.config.gravity
        com = (float(s[lay.s_com]), float(s[lay.s_com + 2]))
        vel = (float(s[lay.s_com_vel]), float(s[lay.s_com_vel + 2]))
        feet = self.controller.landing_feet(self.data, lay)
        arc = predict(self.time, com, vel, feet, g, self.ground_profile())
        # Off the strip (no ground found): back at the liftoff height, the parabola's own end.
        flight = arc.landing_s if arc.landing_s is not None else max(2.0 * vel[1] / g, 0.0)
        self.pending.touchdown_at = self.time + flight

    def time_limit(self, hops: int) -> float:
        """Simulated seconds a run of `hops` hops may take (twice the slowest hop the gait allows, and 5 s)."""
        return 5.0 + 2.0 * hops * self.controller.gait.hop_time_bound(self.config.gravity)

    def run(self, hops: int, max_time: float | None = None, stop: Callable[[], bool] | None = None) -> list[HopMetrics]:
        """Step until `hops` hops are done, the robot falls, `max_time` (s) of simulation (by default
        time_limit(hops)) or `stop()` is true (asked every STOP_POLL_TICKS ticks)."""
        if max_time is None:
            max_time = self.time_limit(hops)
        ticks_left = round((self.time + max_time - self.time) / self._dt)  # as the runs before this measured
        advance, done = self.advance, EV_TOUCHDOWN | EV_FALL
        poll = STOP_POLL_TICKS if stop is not None else ticks_left
        while len(self.hops) < hops and not self.fallen and ticks_left > 0:
            if stop is not None and stop():
                break
            burst = min(ticks_left, poll)
            ticks_left -= burst
            while burst > 0:  # the stop conditions only change on a touchdown or a fall
                taken, events = advance(burst)
                burst -= taken
                if events & done:
                    break
            ticks_left += burst  # what a touchdown left of the burst
        return self.hops

    def submit(self, command: Command) -> None:
        """Queue a command from any thread; the next step applies it (deque appends are atomic)."""
        self._commands.append(command)

    def apply_pending(self) -> None:
        """Apply queued commands now, without stepping (a paused front end shows them at once)."""
        if self._commands:
            self._drain()

    def _drain(self) -> None:
        while self._commands:
            command = self._commands.popleft()
            try:
                command.apply(self)
            except HopperError as exc:  # refused (a bad value, the wrong mode): its one line says why
                log.warning("command %r refused: %s", command, exc)
                self._emit(CommandFailed(type(command).__name__, str(exc)))
            except Exception as exc:  # a bad command must never stop the loop
                log.exception("command %r failed", command)
                self._emit(CommandFailed(type(command).__name__, f"{type(exc).__name__}: {exc}"))

    # -- events ----------------------------------------------------------------------------
    def emit(self, payload: Payload) -> Event:
        """Record an event now and tell every listener (also for front ends: recordings, ...)."""
        return self._emit(payload)

    def _emit(self, payload: Payload) -> Event:
        event = Event(self.time, self.run_index, payload)
        self.events.append(event)
        for listener in self.listeners:
            listener.event(self, event)
        return event

    def _controller_events(self, events: int) -> None:
        s = self.state()
        if events & EV_LIFTOFF:
            momentum = angular_momentum(self.model, self.data, self.layout)
            self.metrics.liftoff(s.time, s.z, momentum)
            self._emit(Liftoff(momentum))
            p = self.pending
            if p.pulse_armed:
                p.pulse_at, p.pulse_magnitude, p.pulse_armed = s.time + TORQUE_PULSE_DELAY_S, p.pulse_armed, 0.0
            p.liftoff_at = s.time
            if self._external:
                self.law.needs_reset = True  # reset(obs) at each liftoff
                self._predict_touchdown()
            if self.schedule is not None and self.schedule.due(len(self.hops) + 1):
                # Half a tick early: the kick lands on the tick delay_s after the liftoff's, not the next.
                self.pending.kick_at = s.time + self.schedule.delay_s - 0.5 * self._dt
        if events & EV_APEX:
            self._follow(s.x)  # the feet are highest now: the safest moment to move the ground
            self.controller.plan_landing(self.data, self.layout, self._ground)
            if self._external:
                self._predict_touchdown()  # the legs' reach is planned now
            self._emit(Apex(s.z))
        if events & (EV_TOUCHDOWN | EV_FALL):
            self.pending.kick_at = math.inf  # a flight shorter than the delay goes unkicked
        if events & EV_TOUCHDOWN:
            self.controller.feel_ground(self.data, self._ground)
            self._emit(Touchdown(self.metrics.touchdown(s.time, s.x, s.pitch)))
        if events & EV_FALL:
            hop = self.metrics.touchdown(s.time, s.x, s.pitch, completed=False)
            c = self.controller
            self._emit(Fall(c.fall_cause, math.degrees(s.pitch), c.fall_height, hop))

    def _ground(self, x: float, foot: int) -> float:
        """Terrain height (m) under the left (0) or right (1) foot at world x."""
        return self.terrain.height(x, self.robot.foot_y if foot == 0 else -self.robot.foot_y)

    # -- the terrain window ----------------------------------------------------------------
    def _follow(self, x: float, urgent: bool = False) -> None:
        """Move the terrain window if the torso at world x (m) nears its edge (hopper.terrain.window)."""
        if self.terrain.follow(x, urgent):
            set_terrain(self.model, self.terrain)

    def _place_terrain(self, first: int) -> None:
        if self.terrain.place(first):
            set_terrain(self.model, self.terrain)

    # -- commands (call from the loop, or submit() them) ----------------------------------
    def reset(self, reason: str = "user") -> None:
        """Stand the robot at the start of the terrain, at rest; a new run begins."""
        self._place_terrain(self.terrain.start)
        mujoco.mj_resetData(self.model, self.data)
        gait = self.config.gait
        stand = gait.stand_height
        for side, offset in (("L", gait.foot_spread / 2), ("R", -gait.foot_spread / 2)):
            knee = -2.0 * math.acos(min(math.hypot(offset, stand) / (2 * self.robot.thigh), 1.0))
            angle = math.atan2(-offset, stand)
            self.data.joint(f"hip_{side}").qpos = angle - knee / 2
            self.data.joint(f"knee_{side}").qpos = knee
        torso_z = self.model.body("torso").pos[2]
        self.data.joint("root_z").qpos = self.robot.foot_radius + stand - self.robot.hip_z - torso_z
        mujoco.mj_forward(self.model, self.data)
        self.pending = Pending(liftoff_at=self.pending.liftoff_at)
        if self.pull is not None:  # mj_resetData cleared its force; the drag ends unrecorded
            self.listeners.remove(self.pull)
            self.pull = None
        self._warnings = int(self.data.warning.number.sum())
        self.controller.reset(self.time, standing=True)
        self.metrics.reset(self.state().x, self.time)
        self.run_index += 1
        self._emit(Reset(reason))

    def _reconfigure(self, **changes: object) -> None:
        """The config with `changes`, taken by the controller; one it refuses changes nothing."""
        config = dataclasses.replace(self.config, **changes)  # validates
        self.controller.configure(config)
        self.config = config

    def set_gains(self, gains: Gains, source: str = "") -> None:
        self._reconfigure(gains=gains)
        self._emit(GainsChanged(gains, source))

    def set_wheel(self, enabled: bool) -> None:
        self._reconfigure(wheel=enabled)
        set_wheel_enabled(self.model, enabled)
        self._emit(WheelChanged(enabled))

    def set_sensing(self, sensing: Literal["ideal", "realistic"]) -> None:
        """Switch what the controller reads; a switch to realistic powers the IMU on at the next tick."""
        self._reconfigure(sensing=sensing)
        self.law.configure(ControllerContext(self.config, self.model))
        self._emit(SensingChanged(sensing))

    def set_gravity(self, gravity: float) -> None:
        require_finite("gravity", gravity, *GRAVITY_LIMITS, "m/s^2")
        self._reconfigure(gravity=gravity)
        self.model.opt.gravity[2] = -gravity
        self.law.configure(ControllerContext(self.config, self.model))
        self._emit(GravityChanged(gravity))

    def set_terrain(self, kind: Literal["crater", "flat"], seed: int) -> None:
        """Regenerate the heightfield in place (no recompile) and restart the robot on it."""
        self._reconfigure(terrain=kind, seed=seed)
        self.terrain = terrain_window(self.config)
        set_terrain(self.model, self.terrain)
        self._emit(TerrainChanged(kind, seed))
        self.reset(reason="terrain")

    def set_schedule(self, schedule: KickSchedule | None) -> None:
        """Kick every (Nth) flight the same way from its next liftoff on; None stops it."""
        if schedule is not None and not isinstance(schedule, KickSchedule):
            raise TypeError(f"expected a KickSchedule or None, got {type(schedule).__name__}")
        self.schedule = schedule
        self.pending.kick_at = math.inf  # a flight under way is not kicked: each kick follows its own liftoff
        self._emit(ScheduleChanged(schedule))

    def _scheduled_kick(self) -> None:
        schedule, self.pending.kick_at = self.schedule, math.inf
        if schedule is None or self.controller.phase is not Phase.FLIGHT:
            return
        after = self.time - self.pending.liftoff_at
        self.metrics.kicked(self.time)
        if schedule.kind == "torque_pulse":
            self.pending.pulse_at, self.pending.pulse_magnitude = self.time, schedule.magnitude
            self._pulse_event(after)
        else:
            self._impulse(schedule.kind, schedule.magnitude, after)  # type: ignore[arg-type]

    def disturb(self, kind: DisturbanceKind, magnitude: float) -> None:
        """Apply a disturbance; impulses act at once, a torque pulse in (the next) flight."""
        if kind not in DISTURBANCE_LIMITS:
            raise ValueError(f"unknown disturbance {kind!r}; choose from {', '.join(DISTURBANCE_LIMITS)}")
        limit, unit = DISTURBANCE_LIMITS[kind]
        require_finite(f"{kind} magnitude", magnitude, -limit, limit, unit)
        if kind == "torque_pulse":
            if self.controller.phase is Phase.FLIGHT:
                self.pending.pulse_at, self.pending.pulse_magnitude = self.time, magnitude
            else:
                self.pending.pulse_armed = magnitude
                self._emit(DisturbanceArmed(kind, magnitude, unit))
            return
        self._impulse(kind, magnitude)

    def _impulse(self, kind: DisturbanceKind, magnitude: float, after_liftoff_s: float | None = None) -> None:
        """An angular (pitch_kick) or linear (push_*) impulse on the torso, now."""
        dof = self.layout.v_pitch if kind == "pitch_kick" else self.layout.v_x
        impulse = np.zeros(self.model.nv)
        impulse[dof] = -magnitude if kind == "push_backward" else magnitude
        dv = np.zeros(self.model.nv)
        mujoco.mj_solveM(self.model, self.data, dv.reshape(1, -1), impulse.reshape(1, -1))
        self.data.qvel += dv
        self._emit(Disturbance(kind, magnitude, DISTURBANCE_LIMITS[kind][1], after_liftoff_s=after_liftoff_s))

    def _pulse_event(self, after_liftoff_s: float | None = None) -> None:
        """Start a pending torque pulse (in flight only), or end the running one."""
        magnitude = self.pending.pulse_magnitude
        torso = self.layout.torso
        if magnitude and self.controller.phase is Phase.FLIGHT:
            self.data.xfrc_applied[torso, 4] = magnitude  # pitch torque about world y
            self.pending.pulse_at, self.pending.pulse_magnitude = self.time + TORQUE_PULSE_S, 0.0
            self._emit(Disturbance("torque_pulse", magnitude, "N m", TORQUE_PULSE_S, after_liftoff_s))
        else:
            self.data.xfrc_applied[torso, 4] = 0.0
            self.pending.pulse_at, self.pending.pulse_magnitude = math.inf, 0.0

    def grab(self, point: tuple[float, float]) -> None:
        """Grab the torso at world (x, z) `point` (m) with a spring (hopper.perturb), replacing any pull."""
        require_finite("grab x", point[0], -1e3, 1e3, "m")
        require_finite("grab z", point[1], -1e3, 1e3, "m")
        if self.pull is not None:
            self.release()
        self.pull = Pull.grab(self.model, self.data, self.layout.torso, point)
        # A listener: each tick sets the force for the next step, and a tick without a drag pays nothing.
        self.pull.apply(self.model, self.data)
        self.listeners.append(self.pull)

    def pull_to(self, target: tuple[float, float]) -> None:
        """Move the pull's target to world (x, z), m (ignored without a pull: it was released or reset)."""
        require_finite("pull x", target[0], -1e3, 1e3, "m")
        require_finite("pull z", target[1], -1e3, 1e3, "m")
        if self.pull is not None:
            self.pull.target = np.array(target, dtype=float)

    def release(self) -> None:
        """End the pull and record it as a disturbance (nothing if there is none)."""
        pull, self.pull = self.pull, None
        if pull is None:
            return
        self.listeners.remove(pull)
        pull.remove(self.data)
        ix, iz = pull.impulse.tolist()
        self._emit(Dragged(ix, iz, pull.peak_force, self.time - pull.started))

    # -- health ----------------------------------------------------------------------------
    def _check_health(self) -> None:
        """Reset on a non-finite state or a new MuJoCo warning (e.g. it auto-reset a bad qacc); move
        the terrain window now if the robot got near its edge without a flight (dragged, sliding)."""
        if not (np.isfinite(self._qpos).all() and np.isfinite(self._qvel).all()):
            self._diverged("non-finite state")
        elif int(self.data.warning.number.sum()) > self._warnings:
            self._diverged("MuJoCo warning")
        else:
            self._follow(float(self._qpos[self._q_x]), urgent=True)

    def _diverged(self, why: str) -> None:
        log.warning("simulation diverged (%s); resetting", why)
        self._emit(Diverged(why))
        self.reset(reason="diverged")
