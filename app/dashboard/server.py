"""The dashboard: a viser server and the one thread that steps the simulation and publishes it.

Browser callbacks run on viser's thread pool and only queue commands (`sim.submit`) or set loop
flags; the loop thread alone touches MjData: it steps against a wall-clock budget, then sends
poses (inside `server.atomic()`), plots, the status and event-driven updates.
"""

from __future__ import annotations

import collections
import logging
import math
import socket
import threading
import time

import viser
from hopper.app.dashboard.access import Access, Gatekeeper, page_url
from hopper.app.dashboard.config import DashboardConfig
from hopper.app.dashboard.feedback import notify_all
from hopper.app.dashboard.layout import Layout, build_layout
from hopper.app.dashboard.loop_commands import Pause, Restore, SetMode, SetSpeed, StayFallen, Steps
from hopper.app.dashboard.pacing import Pacer, chart_scale
from hopper.app.dashboard.panels import PanelContext
from hopper.app.dashboard.panels.stand import MODES as MODE_LABELS
from hopper.app.dashboard.panels.status import Status
from hopper.app.dashboard.physics import PhysicsView, bind_drag
from hopper.app.dashboard.plots import PLOT_SAMPLE_S, PLOT_WINDOW_S
from hopper.app.dashboard.recording import Recorder
from hopper.app.dashboard.roles import Roles
from hopper.app.dashboard.scene import (
    CameraFollow,
    GhostRobot,
    RobotView,
    Trail,
    configure_lighting,
    saturation,
)
from hopper.app.dashboard.terrain_view import TerrainView
from hopper.app.dashboard.wire import guard_gui_updates
from hopper.app.recordings import FileLimits

from hopper import interrupts
from hopper.errors import HopperError
from hopper.events import Event, EventKind, Fall, Restored, Resumed
from hopper.history import History
from hopper.metrics import RAD_S_TO_RPM
from hopper.sim import Command, Simulation
from hopper.snapshot import Snapshot
from hopper.stand import StandSimulation
from hopper.state import RobotState

log = logging.getLogger(__name__)
PLANT_CHANGES = (EventKind.GRAVITY, EventKind.TERRAIN, EventKind.SENSING)

FRAME_S = 1 / 30  # s of wall time between pose updates
MAX_FRAME_S = 1 / 10  # s between them at Max: the scene keeps up at a third of the rate, the rest steps
CHART_WALL_S = 2.0  # s of wall time the charts' window spans at least when fast-forwarding (readable)
MAX_SLEEP_S = 0.005  # s; the loop wakes at least this often to step (5 steps a wake at 1x)
STATUS_S = 0.2  # s between status-strip updates
OFF_WORLD_Z_M = -3.0  # m; a torso below this has left the terrain (pushed off its side)
FALL_RESET_S = 2.0  # s of (running) wall time a fallen robot stays down before the auto reset
MODES = ("hop", "stand locked", "stand free")  # hop over the terrain, or on the test stand (hopper.stand)
OFF_WORLD_NOTICE_S = 30.0  # s of wall time between "off the terrain" notices (the event log has every one)


class PortInUse(HopperError, OSError):
    """The requested port is taken (viser itself would silently pick the next one)."""


def ensure_port_free(host: str, port: int) -> None:
    """Raise PortInUse with a one-line message if (host, port) cannot be bound."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        # Same option the server's own listener uses, so a lingering TIME_WAIT does not count as "in use".
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host, port))
        except OSError as exc:
            raise PortInUse(f"cannot serve on {host}:{port}: {exc.strerror or exc}") from None


class Dashboard:
    """Owns the simulation, the viser server and the loop thread. Use `start()`/`stop()` or `with`."""

    def __init__(self, config: DashboardConfig, *, verbose: bool = True) -> None:
        ensure_port_free(config.host, config.port)  # before the slow part: fail fast
        self.config = config
        self.sim = Simulation(config.sim_config())
        self.pacer = Pacer(self.sim.model.opt.timestep, config.speed)
        self.stay_fallen = False
        self._single_steps = 0  # ticks asked by Steps, stepped in the next round (loop thread only)
        self._events: collections.deque[Event] = collections.deque()
        self._stopping = threading.Event()
        self._stopped = False
        self._fallen_since: float | None = None
        self._off_notified = -math.inf  # wall s of the last "off the terrain" notice
        self._next_sample = 0.0
        self.chart_scale = chart_scale(self.pacer.pace, CHART_WALL_S, PLOT_WINDOW_S)  # the charts' window / 10 s
        self._pending_restore: Snapshot | None = None  # a Restore drained, applied at the next round's top
        self._restore_what = ""  # what it is, for the event log
        self._held: Snapshot | None = None  # a moment restored while paused, until the loop steps on
        self._pending_mode: str | None = None  # a SetMode drained, applied at the next round's top
        self.mode = "hop"
        self.frames = 0  # pose frames published, for tests and the benchmark

        limits = FileLimits(max_mb=config.rrd_max_mb, max_min=config.rrd_max_min, flush_s=config.rrd_flush_s)
        self.recorder = Recorder(self.submit, config.sessions_dir, limits)
        self._recording_behind = False  # a "Recording behind" notice is out: say when it caught up
        if config.rrd is not None or config.rerun_viewer != "off":  # fails here, before any server starts
            self.recorder.start_now(self.sim, config.rrd, config.rerun_viewer, name="hopper-dashboard")
        try:
            self.server = viser.ViserServer(host=config.host, port=config.port, verbose=verbose)
        except BaseException:
            self.recorder.close_now(self.sim)
            raise
        try:
            # First: a client without the token must get nothing of what _build sends.
            self.gatekeeper = Gatekeeper(self.server, Access(config.token, config.public_view))
            if self.server.get_port() != config.port:  # lost a race for the port after the check
                raise PortInUse(f"cannot serve on {config.host}:{config.port}: port taken while starting")
            self._build()
        except BaseException:
            self.server.stop()
            self.recorder.close_now(self.sim)
            raise
        self._thread = threading.Thread(target=self._run, name="sim-loop", daemon=True)

    def _build(self) -> None:
        sim, config = self.sim, self.config
        start = sim.state()
        self.camera = CameraFollow(self.server.scene, start.x, start.z)  # the parent frame first
        self.camera.configure_initial(self.server)
        configure_lighting(self.server.scene, config.lighting)
        self.terrain = TerrainView(self.server.scene, sim)
        self.robot = RobotView(self.server.scene, sim.model)
        self.trail = Trail(self.server.scene)
        self.history = History()  # replay: liftoff states and a ring of recent ones
        self.ghost = GhostRobot(self.server.scene, sim.model)
        self.physics = PhysicsView(self.server.scene, sim)
        bind_drag(self.robot, self.camera, self.submit)
        self.layout: Layout = build_layout(
            self.server,
            PanelContext(self.server, self.submit, self),
            gains=sim.gains,
            sensing=sim.config.sensing == "realistic",
            seed=config.seed,
            terrain=config.terrain,
            gravity=sim.config.gravity,
            speed=config.speed,
            recorder=self.recorder,
            camera=self.camera,
            trail=self.trail,
            robot=self.robot,
            replay_host=self,
            ghost=self.ghost,
            physics=self.physics,
            controller=sim.config.controller,
            controller_choices=config.controller_choice,
            flown=sim.robot,
            gait=sim.config.gait,
            lighting=config.lighting,
        )
        self.layout.controller.show(sim.law)
        self.layout.analysis.show_law(sim.law, sim.config)  # a controller given at start: its analysis, or why none
        self.recorder.listeners.append(self._recording_changed)
        guard_gui_updates(self.server)  # malformed browser updates never reach a setting
        sim.listeners.append(self)
        sim.listeners.append(self.history)
        self.layout.analysis.update_plant(sim.config)
        self.roles = Roles(  # after every shared input exists: it greys them for viewers
            self.server,
            self.submit,
            folder=self.layout.control,
            viewer_safe=self.layout.viewer_safe,
            gatekeeper=self.gatekeeper,
            idle_timeout_s=config.idle_timeout,
        )

    @property
    def url(self) -> str:
        return f"http://{self.config.host}:{self.server.get_port()}"

    @property
    def page_url(self) -> str:
        """The address to open, with the access token if there is one (never log it)."""
        return page_url(self.config.host, self.server.get_port(), self.config.token)

    # -- lifecycle -------------------------------------------------------------------------
    def start(self) -> Dashboard:
        """Start the loop thread."""
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop the loop, finalize any recording, stop the server (frees the port). Idempotent.

        A second Ctrl-C (or SIGTERM) while it runs waits for it, and comes after (held): one that
        came while the loop was being joined skipped the rest, and left the recording unfinished
        and the port taken."""
        with interrupts.held():  # the check too: a signal between it and the hold skipped the stop for good
            if self._stopped:
                return
            self._stopped = True
            self._stopping.set()
            self.layout.analysis.close()
            if self.layout.stand is not None:
                self.layout.stand.inject.close()
            if self._thread.is_alive():
                self._thread.join(timeout=5.0)
            try:
                self.recorder.close_now(self.sim)
            finally:
                self.server.stop()

    def __enter__(self) -> Dashboard:
        return self.start()

    def __exit__(self, *_: object) -> None:
        self.stop()

    def wait(self, timeout: float | None = None) -> bool:
        """Block until stop() is called (or `timeout` s); True if stopped. A stop signal interrupts it."""
        return interrupts.wait(self._stopping, timeout)

    def submit(self, command: Command) -> None:
        """Queue a command for the simulation the loop runs now (a mode change replaces it)."""
        self.sim.submit(command)

    # -- LoopControls (called from any thread: each is a command on the simulation's queue) ----
    def set_mode(self, mode: str) -> None:
        if mode not in MODES:  # refused in the caller's thread, with its notice
            raise HopperError(f"unknown mode {mode!r}; choose from {', '.join(MODES)}")
        self.submit(SetMode(self, mode))

    def set_paused(self, paused: bool) -> None:
        self.submit(Pause(self, bool(paused)))

    def request_steps(self, count: int) -> None:
        self.submit(Steps(self, max(int(count), 0)))

    def set_speed(self, speed: float) -> None:
        self.pacer.check_speed(speed)  # a bad speed is refused here, in the caller's thread
        self.submit(SetSpeed(self, speed))

    def set_stay_fallen(self, stay: bool) -> None:
        self.submit(StayFallen(self, bool(stay)))

    # -- ReplayHost (panels/replay.py) ------------------------------------------------------
    def pause(self, paused: bool) -> None:
        self.layout.simulation.set_paused(paused)

    def request_restore(self, snapshot: Snapshot, what: str) -> None:
        self.submit(Restore(self, snapshot, what))

    # -- loop_commands.Loop (on the loop thread, as the queue is drained) ---------------------
    def apply_paused(self, paused: bool) -> None:
        self.pacer.paused = paused
        self.pacer.restart_window()

    def apply_speed(self, speed: float) -> None:
        self.pacer.set_speed(speed)
        self.pacer.restart_window()
        self._rescale_charts()

    def _rescale_charts(self) -> None:
        """Stretch the charts' window with the pace (at Max, the delivered one) so that it stays readable:
        the samples are spaced chart_scale times PLOT_SAMPLE_S apart, the window holds as many."""
        self.chart_scale = chart_scale(self.pacer.pace, CHART_WALL_S, PLOT_WINDOW_S)

    def apply_steps(self, count: int) -> None:
        self._single_steps += count

    def apply_stay_fallen(self, stay: bool) -> None:
        self.stay_fallen = stay

    def apply_restore(self, snapshot: Snapshot, what: str) -> None:
        """Restore `snapshot` at the top of the next round, never inside a tick (the queue may be
        drained by sim.step mid-batch; the batch stops there)."""
        self._pending_restore, self._restore_what = snapshot, what

    def apply_mode(self, mode: str) -> None:
        """Switch at the top of the next round, never inside a tick (as a restore)."""
        self._pending_mode = mode

    def _switch_mode(self) -> None:
        """Replace the simulation by the one `mode` asks for, built from the live configuration (gains,
        gravity, terrain, controller); the listeners (charts, recording, history) follow it."""
        mode, self._pending_mode = self._pending_mode, None
        old = self.sim
        try:
            config = old.config
            new = (
                Simulation(config)
                if mode == "hop"
                else StandSimulation(config, "locked" if mode == "stand locked" else "free")
            )
        except Exception as exc:
            log.exception("switching to %s failed", mode)
            notify_all(self.server, "Mode change failed", f"{type(exc).__name__}: {exc}; still {self.mode}", "error")
            return
        old.apply_pending()  # what came in meanwhile acts on the old one; the next goes to the new
        if isinstance(old, StandSimulation):
            label = next(k for k, v in MODE_LABELS.items() if v == mode)  # as the Mode menu says it
            old.stop_injection(f"the mode changed to {label}")  # it would play into the old one's memory
        new.listeners[:] = old.listeners
        new.run_index = old.run_index  # one session, one numbering: the event log's "run N" goes on
        self.sim, self.mode, self._held = new, mode, None
        self.physics.terrain_changed(new)
        new.reset(reason=mode.split()[0])  # its listeners hear the reset: the charts and tables start over
        notify_all(
            self.server,
            "Mode",
            {"hop": "Hopping", "stand locked": "On the stand, legs locked", "stand free": "On the stand, legs free"}[
                mode
            ],
            "info",
        )

    def _restore_now(self) -> None:
        """Restore the pending snapshot; no steps in this round: the restored moment must be the one shown."""
        snapshot, self._pending_restore = self._pending_restore, None
        assert snapshot is not None
        try:
            self.sim.restore(snapshot)
        except Exception as exc:
            log.exception("restoring a snapshot failed")
            notify_all(self.server, "Restore failed", f"{type(exc).__name__}: {exc}", "error")
            return
        self.sim.emit(Restored(self._restore_what))  # after the settings' own events: the log's newest line
        self._held = snapshot if self.pacer.paused else None  # a restore while running goes on at once
        self.history.rewound(snapshot)
        self._next_sample = snapshot.time
        self.layout.plots.drop_after(snapshot.time)
        torso = self.sim.state()
        self.trail.rewind(snapshot.time, torso.x, torso.z)  # no path ahead of the robot shown
        if snapshot.hops is not None:  # the hop table shows the hops of the moment restored
            self.layout.hops.show(list(snapshot.hops))

    # -- Listener (called on the loop thread by sim.step) -------------------------------------
    def idle_until(self, sim: Simulation) -> float:
        return self._next_sample

    def tick(self, sim: Simulation) -> None:
        # Cheap on most ticks: read the state only when a plot sample is due.
        if sim.data.time < self._next_sample:
            return
        self._next_sample = sim.data.time + PLOT_SAMPLE_S * self.chart_scale
        s = sim.state()
        self.layout.plots.sample(s.time, s.pitch, s.wheel_speed, s.wheel_torque, sim.controller.wheel_command)
        self.trail.sample(s.time, s.x, s.z)

    def event(self, sim: Simulation, event: Event) -> None:
        self._events.append(event)

    # -- the loop --------------------------------------------------------------------------
    def _run(self) -> None:
        next_frame = last_status = time.perf_counter()
        last_frame = next_frame
        while not self._stopping.is_set():
            now = time.perf_counter()
            # At most two frames' worth of steps between publishes: fast-forward keeps the scene and
            # the charts moving together even when the machine cannot deliver the asked speed.
            self._apply_commands()  # the one way in: simulation and loop commands, in order
            restored = self._pending_restore is not None
            if restored:
                self._restore_now()
            if self._pending_mode is not None:
                self._switch_mode()
            pacer = self.pacer
            most = None if pacer.flat_out else math.ceil(2 * FRAME_S * pacer.speed / pacer.timestep)
            budgeted = pacer.due(now, most)
            if restored:
                budgeted = 0  # the restored moment must be the one shown
            extra, self._single_steps = self._single_steps, 0
            if self._held is not None and budgeted + extra > 0:
                self._resume_held()
            taken = self._step(budgeted + extra)
            self.pacer.done(min(budgeted, taken), now, max(taken - budgeted, 0))
            self._watchdog(now)
            if now >= next_frame:
                try:
                    self._publish(now, now - last_frame, now - last_status >= STATUS_S)
                except Exception:
                    log.exception("publishing a frame failed")
                if now - last_status >= STATUS_S:
                    last_status = now
                    if pacer.flat_out:
                        self._rescale_charts()  # the delivered pace moves with the machine's load
                last_frame = now
                frame_s = MAX_FRAME_S if pacer.flat_out else FRAME_S
                next_frame = max(next_frame + frame_s, now - frame_s)  # catch up one frame at most
            if pacer.flat_out and not pacer.paused:
                continue  # no sleep at Max: the next round steps at once
            self._stopping.wait(max(0.0, min(next_frame - time.perf_counter(), MAX_SLEEP_S)))

    def _resume_held(self) -> None:
        """The loop steps on from a moment restored while paused (Resume from here, Resume, a step)."""
        held, self._held = self._held, None
        assert held is not None
        if self.sim.time == held.time:  # not after a reset meanwhile: that says so itself
            self.sim.emit(Resumed())

    def _apply_commands(self) -> None:
        """Apply queued commands before this round's steps (paused, a reset or new gains show at once)."""
        try:
            self.sim.apply_pending()
        except Exception:
            log.exception("applying commands while paused failed")

    def _step(self, count: int) -> int:
        """Step `count` ticks, fewer if a pause or a restore arrives mid-batch; the ticks stepped."""
        sim, pacer, paused = self.sim, self.pacer, self.pacer.paused
        taken = 0
        try:
            while taken < count:  # compiled bursts between the ticks Python takes part in (Simulation.advance)
                taken += sim.advance(count - taken)[0]
                if self._pending_restore is not None or (pacer.paused and not paused):
                    break
        except Exception as exc:  # a bug below must not stop the dashboard: report, reset, go on
            log.exception("simulation step failed")
            notify_all(self.server, "Simulation error", f"{type(exc).__name__}: {exc}; the robot was reset", "error")
            self.sim.reset(reason="error")
        return taken

    def _watchdog(self, now: float) -> None:
        """Keep a dashboard that runs for hours going: restart after a fall (unless asked not to)
        and when the robot has left the terrain (pushed off its side: the core does not watch that).
        The terrain has no end: the simulation moves its window along (hopper.terrain.window)."""
        sim = self.sim
        if sim.fallen and not self.stay_fallen and not self.pacer.paused:
            if self._fallen_since is None:
                self._fallen_since = now
            elif now - self._fallen_since >= FALL_RESET_S:
                self._fallen_since = None
                sim.reset(reason="after fall")
            return
        self._fallen_since = None
        if sim.state().z < OFF_WORLD_Z_M:
            sim.reset(reason="off the terrain")
            if now - self._off_notified >= OFF_WORLD_NOTICE_S:  # at fast-forward, a push off it repeats quickly
                self._off_notified = now
                notify_all(self.server, "Off the terrain", "The robot fell off the terrain and went back to the start.")

    def _publish(self, now: float, dt: float, with_status: bool) -> None:
        sim, s = self.sim, self.sim.state()
        while self._events:
            self._handle(self._events.popleft())
        self.terrain.sync(sim)  # the window moved (or a new terrain): its new tiles, before the poses on them
        level = saturation(s.wheel_torque, s.wheel_speed, sim.robot)
        # One read of the phase for the label over the robot and the status badge, sent in the same
        # window. The label goes with every frame, the strip every STATUS_S: a phase change re-sends the
        # strip at once, or the badge would show the phase before it for up to STATUS_S (a landing lasts
        # 0.2 s at 1x; at 64x the phase changes from one frame to the next).
        phase = sim.phase.label
        status = self._status(s, phase, level) if with_status or phase != self.layout.status.phase else None
        with self.server.atomic():
            self.robot.update(sim.model, sim.data, level, phase)
            if status is not None:
                self.layout.status.show(status)
            # Smoothing in simulated time: at 64x the camera keeps up with a robot 64 times as fast.
            watched = None if self.layout.logreplay is None else self.layout.logreplay.watched()
            self.camera.update(s.x, s.z, dt * max(self.pacer.pace, 1.0), watched)
            self.ghost.update(now)
            if self.layout.logreplay is not None:
                self.layout.logreplay.update(now)
            self.physics.update(sim, now)
        self.trail.publish(now)
        self.layout.plots.publish(now)
        self.frames += 1
        if with_status and self.layout.replay is not None:
            self.layout.replay.show_span(self.pacer.paused)
        if with_status:
            self.roles.poll()  # an idle operator's control passes on
            self.layout.record.refresh()  # the recording's current file and size

    def _status(self, s: RobotState, phase: str, level: float) -> Status:
        """What the status strip shows now; `phase` is the frame's one read, the label's too."""
        sim = self.sim
        return Status(
            phase=phase,
            time=s.time,
            rtf=self.pacer.real_time_factor(),
            speed=self.pacer.speed,
            paused=self.pacer.paused,
            behind=self.pacer.behind,
            hops=sum(h.completed for h in sim.hops),
            pitch_deg=math.degrees(s.pitch),
            wheel_rpm=s.wheel_speed * RAD_S_TO_RPM,
            saturation=level,
            capacity=s.wheel_speed / sim.robot.wheel_no_load_speed,
            capacity_nms=sim.robot.momentum_capacity,
            gravity=sim.config.gravity,
            recording=self.recorder.active,
        )

    def _handle(self, event: Event) -> None:
        """React to one simulation event (on the loop thread)."""
        layout, kind, payload = self.layout, event.kind, event.payload
        layout.events.add(event)
        hop = getattr(payload, "hop", None)
        if hop is not None:
            layout.hops.add(hop)
        if isinstance(payload, Fall):
            then = "stays down (Stay fallen is ticked)" if self.stay_fallen else f"resets in {FALL_RESET_S:g} s"
            body = f"{payload.describe()} at t = {event.time:.2f} s; it {then}"
            notify_all(self.server, "The robot fell", body, "warning")
        elif kind == EventKind.DIVERGED:
            notify_all(self.server, "Simulation diverged", f"{payload.describe()}: the robot was reset", "warning")
        elif kind == EventKind.COMMAND_FAILED and payload.command == "SetControllerParam":
            # A value the controller refused (its range, or its own word): why, and the values in use again.
            notify_all(self.server, "Value refused", payload.message, "warning")
            layout.controller.resync(self.sim.law)
        elif kind == EventKind.COMMAND_FAILED:
            notify_all(self.server, "Command failed", payload.describe(), "error")
            if payload.command == "SetController":  # the selector shows what flies again
                layout.controller.refused(self.sim.law)
            elif payload.command == "SetGravity":  # so does the Gravity control
                layout.terrain.show_gravity(self.sim.config.gravity)
        elif kind == EventKind.CONTROLLER_FAILED:
            notify_all(self.server, "Controller failed", payload.describe(), "error")
        elif kind == EventKind.CONTROLLER:
            layout.controller.show(self.sim.law, self.sim.controller_fault)
            layout.analysis.show_law(self.sim.law, self.sim.config)
        elif kind == EventKind.TERRAIN:
            self.physics.terrain_changed(self.sim)
        if kind == EventKind.SCHEDULE:
            layout.disturbances.schedule.show(payload.schedule)
        elif kind == EventKind.GAINS and self.sim.config.controller == "pid":
            layout.analysis.show_gains(payload.gains)
        elif kind in PLANT_CHANGES:  # the flight the analysis linearizes is another one now
            layout.analysis.update_plant(self.sim.config)
        elif kind == EventKind.RESET:
            self._next_sample = 0.0
            layout.plots.clear()
            layout.hops.clear()
            self.trail.clear()

    def _recording_changed(self, state: str, path: object, message: str) -> None:
        if state == "saved" and path is not None:
            notify_all(self.server, "Recording saved", str(path))
        elif state == "failed":
            notify_all(self.server, "Recording failed", message, "error")
        elif state == "behind":
            notify_all(self.server, "Recording behind", message, "warning")
            self._recording_behind = True
        elif state == "recording" and self._recording_behind:
            notify_all(self.server, "Recording caught up", "the file has everything the recording sent so far")
            self._recording_behind = False
