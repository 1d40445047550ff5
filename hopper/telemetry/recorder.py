"""The Telemetry listener: buffers a Simulation's ticks and events, sends them in batches, closes the file."""

from __future__ import annotations

import atexit
import bisect
import collections
import contextlib
import dataclasses
import json
import logging
import math
import threading
import time
import weakref
from collections.abc import Callable, Sequence
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa
import rerun as rr

from hopper.control import Phase
from hopper.events import EventKind
from hopper.interrupts import held
from hopper.layout import LEG_JOINTS
from hopper.meshes import body_meshes
from hopper.metrics import RAD_S_TO_RPM
from hopper.telemetry import rerun_compat
from hopper.telemetry.blueprint import RED, BlueprintSource
from hopper.telemetry.columns import (
    CHILD_FRAME,
    LEVEL,
    QUATERNION,
    SCALARS,
    STATE,
    STRIPS,
    TEXT,
    TRANSLATION,
    Column,
    time_columns,
    vectors,
)
from hopper.telemetry.files import check_writable, part_path
from hopper.telemetry.scene import TerrainLog, log_robot
from hopper.telemetry.schema import APPLICATION_ID, SIGNALS, SIGNALS_F32, hop_values
from hopper.telemetry.writer import FOOTER_BYTES_PER_CHUNK, MIN_RESERVE, PipedFile, Reserve, reserve_path

if TYPE_CHECKING:
    from rerun.sinks import LogSinkLike

    from hopper.sim import Event, Simulation

log = logging.getLogger(__name__)

# A batch goes out when it holds BATCH_TICKS ticks or FLUSH_WALL_S after the last one, whichever
# comes first: faster than real time the ticks decide (a send costs ~1 ms whatever its size, each
# chunk ~1 kB of schema), at real time the clock does (a live viewer lags by at most a second).
# FLUSH_WALL_S is also the flush policy: each batch is encoded and handed to the file at once
# (hopper.telemetry.writer), so a process killed outright loses at most that much wall time of data.
BATCH_TICKS = 4000
FLUSH_WALL_S = 1.0
SINK_TIMEOUT_S = 60.0  # s a flush may wait for the sinks before it is reported as failed
# The recording is behind when the file's writer has not found rerun's pipe empty for BEHIND_S of
# wall time (the disk takes the bytes slower than they come), or the disk was busy more than
# BEHIND_SHARE of the last BEHIND_S: for a file alone, the writer thread's time in its writes; with
# a live viewer, the loop's time waiting in rerun's send and flush (rerun's channel to the file is
# full: the disk holds the simulation to its pace). Nothing is lost either way. A batch is written
# in milliseconds on a disk that keeps up and its send costs ~1 ms. Caught up once, over a whole
# BEHIND_S, the pipe was never full for a quarter of it and that share was under CAUGHT_UP_SHARE:
# a slow disk's bursts are no flapping.
BEHIND_S, BEHIND_SHARE, CAUGHT_UP_SHARE = 5.0, 0.5, 0.1
LIMIT_EVERY_BATCHES = 5  # the torque limit lines only need a point now and then
POSE_EVERY_TICKS = 20  # 50 Hz body poses
# The kernel memory's fields kept every tick beside MjData's, each as (its signal, scale from SI): the
# controller's pitch and rate estimate, beside the truth (hopper.control.sensing); the injected
# excitations (hopper.analysis.bench: the wheel torque's, N m; the reference's, rad); the wheel torque
# asked (N m), the command a log's replay or a fit starts from.
KERNEL_SIGNALS = {
    "pitch_est": ("pitch_est_deg", math.degrees(1.0)),
    "rate_est": ("pitch_rate_est_deg_s", math.degrees(1.0)),
    "inject_torque": ("inject_torque_nm", 1.0),
    "inject_ref": ("inject_ref_deg", math.degrees(1.0)),
    "wheel_command": ("wheel_cmd_nm", 1.0),
}
KERNEL_FIELDS = tuple(KERNEL_SIGNALS)
EVENT_LEVELS = {
    EventKind.FALL: "ERROR",
    EventKind.COMMAND_FAILED: "ERROR",
    EventKind.CONTROLLER_FAILED: "ERROR",
    EventKind.DIVERGED: "WARN",
    EventKind.DISTURBANCE: "WARN",
}
HOP_ARCHETYPE = "hopper.HopMetrics"  # names the hop table's columns
SETTING_EVENTS = (
    EventKind.GAINS, EventKind.WHEEL, EventKind.SENSING, EventKind.GRAVITY, EventKind.TERRAIN, EventKind.CONTROLLER
)  # fmt: skip

_open: weakref.WeakSet[Telemetry] = weakref.WeakSet()


@atexit.register
def _close_all() -> None:  # a forgotten close() must not cost the file its footer
    for telemetry in list(_open):
        telemetry.close()


class Telemetry:
    """Records one Simulation to rerun; adds itself to `sim.listeners` until `close()`.

    Timelines: `sim_time` (duration: simulation time, kept monotonic across resets) and `hop`
    (sequence: hops completed in this recording, still counting after a reset). Entities:

    - `signals`: a row per control tick, one struct component `signals` with the fields of
      SIGNALS (pitch, rate, wheel speed and torque as float32; leg angles and torques and foot
      forces as float16, 0.05 % resolution). One struct, not an entity per channel: every entity
      row costs a row id, a time and an offset (~14 B compressed) and every chunk ~1 kB of schema,
      so fourteen float32 entities take ~14 MB per simulated minute and this ~3 MB. The blueprint
      plots the fields through component mappings (selector `.pitch_deg`, ...).
    - `limits/wheel_torque`: +- the flown robot's wheel torque limit (hopper.robot), reference lines.
    - `phase`: StateChange at each change, exact to the tick. `events`: TextLog and a `kind`.
    - `hops`: a row per touchdown (or fall in flight), a component per HopMetrics field, the
      floats rounded to schema.HOP_DECIMALS (1 mm, 1 ms, 0.01 deg, ...) for a readable table.
    - `world/terrain/<k>`, `world/robot/<body>`: static meshes (the terrain's tiles as the window
      takes them in, scene.TerrainLog), bodies in named frames posed by `world/tf` (Transform3D
      rows with `child_frame`) at 50 Hz; `world/trail`: the torso path, in world x.

    A row is the state at the start of its tick, as that tick's forward pass saw it: sensors,
    applied actuator forces and body poses come from MjData after mj_step (the integrator leaves
    them), joint angles from the qpos of one tick earlier (it advances qpos). MjData is read
    directly: the simulation no longer refreshes `sim.physics` every tick.

    tick() appends six byte views to a bytearray (~0.5 us); every `batch_ticks` ticks (or
    FLUSH_WALL_S) the batch is read back with numpy and sent with rr.send_columns. Call
    close() (or use `with`) from the thread that steps the simulation, or while it is not stepping
    (e.g. through `sim.submit`). Sends and closing hold Ctrl-C and SIGTERM until they are done: a
    CLI whose SIGTERM handler raises (so `with` unwinds) leaves a file `rerun rrd verify` accepts.

    Sinks: the file `path` if given (written by hopper.telemetry.writer), and `sinks` (e.g. a
    viewer's rr.GrpcSink or rr.GrpcServerSink, from hopper.app.rerun_viewer). `on_close` runs once,
    when close() has disconnected the sinks or if construction fails: e.g. to stop a viewer.

    Rollover: with `max_bytes` (bytes on disk) or `max_seconds` (simulation seconds) the file is
    written in numbered parts, `path` stem + `-001.rrd`, `-002.rrd`, ... (files.part_path), a new
    one when the current one reaches a limit (checked at each batch: a part ends up to one batch
    and its footer past the limit). Each part carries its own blueprint, recording name, config,
    robot and terrain, so it opens and verifies alone; all share one recording id, so parts
    opened together join up. `on_part(finished, started)` runs after each switch. A viewer's
    sinks cannot follow a switch (re-attaching a gRPC server sink shuts it down): no rollover then.

    Full disk: the file keeps a Reserve beside it; at the first "no room" error the reserve is
    released, the batch in flight and the footer go into its space, and the recording stops by
    itself (queued on the simulation, which goes on): `on_stop(message)` then says why. A write
    that fails for good also stops it, with the file cut short (`failure` is set in both cases).

    A slow disk: the bytes wait in rerun's memory, and once its channel to the file is full its
    sends wait for room, so the disk holds the simulation to its pace (nothing is lost). When the
    file has been `behind_s` behind, or the loop waited more than BEHIND_SHARE of the last
    `behind_s`, `behind` says so and `on_lag(message)` is called; once caught up, `behind` is None
    again and `on_lag(None)`. Both come from the recording's watchdog thread (the loop's may be
    the one waiting).
    """

    def __init__(
        self,
        sim: Simulation,
        *,
        path: str | Path | None = None,
        sinks: Sequence[LogSinkLike] = (),
        on_close: Callable[[], None] | None = None,
        recording_name: str | None = None,
        batch_ticks: int = BATCH_TICKS,
        max_bytes: int | None = None,
        max_seconds: float | None = None,
        flush_s: float = FLUSH_WALL_S,
        on_part: Callable[[Path, Path], None] | None = None,
        on_stop: Callable[[str], None] | None = None,
        on_lag: Callable[[str | None], None] | None = None,
        behind_s: float = BEHIND_S,
    ) -> None:
        self._on_close = on_close
        self._on_part, self._on_stop = on_part, on_stop
        self._on_lag, self._behind_s = on_lag, behind_s
        self.behind: str | None = None  # why the file is behind what was sent, while it is
        self._file: PipedFile | None = None
        self._reserve: Reserve | None = None
        self.rec: rr.RecordingStream | None = None
        self._ready = False  # every part of _setup done: close() can finish the file
        try:
            # Held: a stop signal during set-up is raised once the file is open and whole, and
            # then closes it below, since the caller never gets the object to close.
            with held():
                self._limits(path, sinks, max_bytes, max_seconds, flush_s)
                self._setup(sim, path, sinks, recording_name, batch_ticks)
        except BaseException:
            self._abandon()
            raise

    # -- setup -----------------------------------------------------------------------------
    def _limits(
        self,
        path: str | Path | None,
        sinks: Sequence[LogSinkLike],
        max_bytes: int | None,
        max_seconds: float | None,
        flush_s: float,
    ) -> None:
        if max_bytes is not None and max_bytes <= 0:
            raise ValueError(f"max_bytes must be positive, got {max_bytes}")
        if max_seconds is not None and not max_seconds > 0:
            raise ValueError(f"max_seconds must be positive, got {max_seconds}")
        if not 0 < flush_s <= 60:
            raise ValueError(f"flush_s must be in (0, 60] s, got {flush_s}")
        self._rolls = max_bytes is not None or max_seconds is not None
        if self._rolls and path is None:
            raise ValueError("a size or duration limit needs a file to roll over")
        if self._rolls and sinks:
            raise ValueError("a size or duration limit (rollover) cannot be combined with a live rerun viewer")
        self._max_bytes = max_bytes if max_bytes is not None else math.inf
        # A file-only recording waits for each batch to be written (~1 ms a batch on a disk that
        # keeps up; a 40-hop headless run took 3.9 s either way). Without the wait, a disk slower
        # than the data let rerun queue it in memory out of our sight: under a busy loop per core,
        # 57 MB piled up over 64 s before the lag showed (the pipe kept emptying between rerun's
        # writes), then the loop stalled for over a minute in one flush. With it, the loop runs at
        # the disk's pace from the first slow batch. A size limit needs it too: it is checked
        # against the bytes on disk (a 2 MB part grew to 3.1 MB without). A live viewer must not
        # pace the simulation: with one, batches are not waited on.
        self._wait_each_batch = path is not None and not sinks
        self._max_ns = round(max_seconds * 1e9) if max_seconds is not None else math.inf
        self._flush_s = flush_s

    def _setup(
        self,
        sim: Simulation,
        path: str | Path | None,
        sinks: Sequence[LogSinkLike],
        recording_name: str | None,
        batch_ticks: int,
    ) -> None:
        if path is None and not sinks:
            raise ValueError("nothing to record to: give a path or sinks")
        if batch_ticks < POSE_EVERY_TICKS or batch_ticks % POSE_EVERY_TICKS:
            raise ValueError(f"batch_ticks must be a positive multiple of {POSE_EVERY_TICKS}, got {batch_ticks}")
        self.sim = sim
        self.base = check_writable(path) if path is not None else None
        self.path: Path | None = None  # the part being written
        self.parts: list[Path] = []  # every part so far, the current one last
        self.failure: str | None = None  # why the recording stopped by itself
        self.switch_s: list[float] = []  # wall s each rollover held the flushing thread (the loop)
        self._stopping = False
        self._stop_lock = threading.Lock()
        self._sinks = tuple(sinks)
        self._name = recording_name or f"hopper {sim.config.terrain} seed {sim.config.seed}"
        self._batch = batch_ticks
        self._lock = threading.Lock()
        self._closed = False
        self._warned = False

        data = sim.data
        self._data = data
        # Byte views of MjData's arrays, made once: appending a memoryview to a bytearray copies the
        # live values with no call at all (~0.05 us, against ~0.5 us for tobytes() in the loop).
        self._qpos = data.qpos
        self._sensor_view, self._force_view, self._qpos_view = (
            memoryview(a).cast("B") for a in (data.sensordata, data.actuator_force, data.qpos)
        )
        self._xpos_view, self._xquat_view = memoryview(data.xpos).cast("B"), memoryview(data.xquat).cast("B")
        self._dt_ns = round(sim.model.opt.timestep * 1e9)
        self._meshes = body_meshes(sim.model)
        self._terrain = TerrainLog()  # the window's tiles, as it moves and again in each part
        self._layout(sim)
        # Raw float64 bytes, one row a tick: sensordata | actuator_force | qpos | phase code; numpy
        # reads them back without conversion (lists of floats cost ~3x more to fill, ~4x to convert).
        self._n = 0  # ticks buffered
        self._ticks = bytearray()
        self._pose_rows: list[int] = []
        self._poses = bytearray()  # xpos | xquat of every body, one row a pose sample
        self._events: list[tuple[int, int, str, str, str]] = []  # (time ns, hop, kind, level, text)
        self._phases: list[tuple[int, int, str]] = []  # (time ns, hop, label)
        self._hop_rows: list[tuple[int, int, dict[str, float | int | bool]]] = []
        self._carry_qpos = self._qpos.copy()  # qpos at the next row's time (module docstring)
        self._offset_ns = 0  # sim_time minus data.time; grows at each reset
        self._next_ns = self._start_ns = self._data_ns()  # sim_time of the next row, of the first
        self._last_torso: list[float] | None = None
        self._batches = 0
        self._flush_due = time.monotonic() + self._flush_s
        self._frames: dict[int, pa.Array] = {}  # child_frame columns by pose count
        self._hops = 0
        # The kernel's phase slot, appended to every row: phases exact to the tick at no cost.
        self._phase_view = memoryview(sim.controller.field("phase")).cast("B")  # int64
        self._est_views = [memoryview(sim.controller.field(f)).cast("B") for f in KERNEL_FIELDS]
        self._phase = int(sim.phase)

        self.rec = rr.RecordingStream(APPLICATION_ID)
        self.rec.set_log_tick_enabled(False)  # only our two timelines
        self.rec.set_log_time_enabled(False)
        self._blueprints = BlueprintSource(APPLICATION_ID)
        if self.base is not None:
            first = part_path(self.base, 1) if self._rolls else self.base
            self._reserve = Reserve(reserve_path(first), MIN_RESERVE)
        self._unwatched = threading.Event()  # set at close: the lag watchdog ends
        self._sending: float | None = None  # perf_counter at the start of the send in progress
        self._waited = 0.0  # s the loop spent in sends and flushes, in all
        self._open_part()
        threading.Thread(target=self._watch_lag, name="rrd-lag", daemon=True).start()
        sim.listeners.append(self)
        _open.add(self)
        self._ready = True

    def _open_part(self) -> None:
        """Attach the next file (replacing the previous one, which gets its footer) and send what
        a part needs to stand alone: blueprint, name, config, robot, terrain, limits, the phase."""
        files = []
        if self.base is not None:
            assert self._reserve is not None
            path = part_path(self.base, len(self.parts) + 1) if self._rolls else self.base
            self._file = PipedFile(path, self._reserve, on_full=self._request_stop)
            self.path = path
            self.parts.append(path)
            files = [self._file.sink]
        # rr.set_sinks, with the blueprint from one stream (BlueprintSource: rerun leaks one a call)
        rerun_compat.set_sinks([*files, *self._sinks], default_blueprint=self._blueprints.storage(), recording=self.rec)
        if self._file is not None:
            self._file.attached()
        sim = self.sim
        self.rec.send_recording_name(self._name)
        if self._rolls:
            self.rec.send_property("part", rr.AnyValues(index=len(self.parts), start_s=self._next_ns / 1e9))
        log_robot(self.rec, sim, self._meshes)
        self._terrain.new_part()
        tiles = self._terrain.sync(self.rec, sim)
        self.rec.log("limits/wheel_torque", rr.SeriesLines(names=["+limit", "-limit"], colors=[RED, RED]), static=True)
        self._chunks = 2 * len(self._meshes) + tiles + 8  # chunks in this part, for the footer's reserve
        self._send_config(sim)
        self._send_limits([self._next_ns])
        self._phases.append((self._next_ns, self._hops, Phase(self._phase).label))
        self._part_start_ns = self._next_ns

    def _rollover(self) -> None:
        """Finish the current part and start the next (on the thread that flushes)."""
        old, began = self._file, time.perf_counter()
        assert old is not None
        self._open_part()  # set_sinks drops the old FileSink: it writes its footer into its pipe
        if not old.join():
            log.error("recording: %s was not finished in time", old.path.name)
        self.switch_s.append(time.perf_counter() - began)
        if old.error is not None:
            self._request_stop(old.error)
        elif self._on_part is not None:
            try:
                self._on_part(old.path, self._file.path if self._file else old.path)
            except Exception:
                log.exception("recording: on_part failed")

    def _check_file(self) -> None:
        """After a send: stop on a full disk, keep the footer's reserve ahead, roll over at a limit."""
        f = self._file
        if f is None or self._stopping:
            return
        problem = f.error or f.full
        reserve = MIN_RESERVE + FOOTER_BYTES_PER_CHUNK * self._chunks
        if problem is None and self._reserve is not None and not self._reserve.grow(reserve):
            problem = "the disk is full (no room to keep the footer's reserve)"
        if problem is not None:
            self._request_stop(problem)
        elif self._rolls and (f.written >= self._max_bytes or self._next_ns - self._part_start_ns >= self._max_ns):
            self._rollover()

    def _watch_lag(self) -> None:
        """The lag watchdog's thread: the loop's own cannot say it, since on a slow disk it waits in
        rerun's send or flush. Samples the disk's busy time, judged over the last `behind_s`: the
        file's writes when each batch is waited on (the loop's waits then include encoding, which a
        busy CPU stretches), else the loop's waits."""
        every = min(1.0, self._behind_s / 10)
        samples: collections.deque[tuple[float, float, float]] = collections.deque()
        while not self._unwatched.wait(every):
            now, sending, f = time.perf_counter(), self._sending, self._file
            if self._wait_each_batch and f is not None:
                waited = f.busy_s
            else:
                waited = self._waited + (now - sending if sending is not None else 0.0)
            samples.append((now, waited, f.lag_s() if f is not None else 0.0))
            while samples[0][0] < now - self._behind_s:
                samples.popleft()
            span = now - samples[0][0]
            if span < 0.8 * self._behind_s or self._stopping:
                continue
            share = (waited - samples[0][1]) / span
            self._check_lag(samples[-1][2], max(lag for _, _, lag in samples), share)

    def _check_lag(self, lag: float, worst: float, share: float) -> None:
        """Say once when the file falls behind (`lag` s since it held all that was sent, or the loop
        waited on it `share` of the last `behind_s`), and once it has caught up: its `worst` lag and
        the loop's waiting small over that whole window (between rerun's messages the pipe can be
        empty for a moment while a queue still waits)."""
        if self.behind is None and (lag > self._behind_s or share > BEHIND_SHARE):
            busy = "the disk was busy" if self._wait_each_batch else "the simulation waited on it"
            why = (
                f"the file is {lag:.0f} s behind" if lag > self._behind_s
                else f"{busy} {share:.0%} of the last {self._behind_s:g} s"
            )  # fmt: skip
            pace = "the simulation runs at the disk's pace"
            if not self._wait_each_batch:  # with a live viewer rerun queues what the disk has not taken
                pace = f"the rest waits in memory and, once rerun's queue is full, {pace}"
            self.behind = (
                f"the disk takes the recording's data slower than it comes: {why} ({self.written / 1e6:.1f} MB "
                f"written). Nothing is lost: {pace}"
            )
        elif self.behind is not None and worst < self._behind_s / 4 and share < CAUGHT_UP_SHARE:
            self.behind = None
        else:
            return
        log.warning("recording: %s", self.behind or "the file has caught up")
        if self._on_lag is not None:
            try:
                self._on_lag(self.behind)
            except Exception:
                log.exception("recording: on_lag failed")

    def _request_stop(self, problem: str) -> None:
        """Stop recording soon: queued on the simulation, so that no listener list changes mid-step.

        Also called by the file's thread at a full disk: from then on batches are dropped."""
        with self._stop_lock:
            if self._stopping:
                return
            self._stopping = True
        where = f" in {self.path.parent}" if self.path is not None else ""
        self.failure = f"{problem}{where}; recording stopped"
        log.warning("recording: %s", self.failure)
        self.sim.submit(_StopRecording(self))

    def _stop(self) -> None:
        """Close now (the simulation applies _StopRecording); close() tells on_stop why."""
        self.close()

    def _report_failure(self) -> None:
        """After closing a recording cut short: say why, and whether the file is whole, once."""
        if self.failure is None or self._on_stop is None:
            return
        if self._file is not None and self._file.error is None:
            size = self._file.path.stat().st_size / 1e6
            self.failure += f"; {self._file.path.name} is complete ({size:.1f} MB)"
        on_stop, self._on_stop = self._on_stop, None
        try:
            on_stop(self.failure)
        except Exception:
            log.exception("recording: on_stop failed")

    def _layout(self, sim: Simulation) -> None:
        """Columns of each signal in a buffered row, from the simulation's model layout."""
        m, lay = sim.model, sim.layout
        self._nsens, self._nu, self._nq = m.nsensordata, m.nu, m.nq
        # Each signal as (column of [sensordata | actuator_force | qpos], scale from SI).
        sources = {
            "pitch_deg": (lay.s_pitch, math.degrees(1.0)),
            "pitch_rate_deg_s": (lay.s_gyro_pitch, math.degrees(1.0)),
            "wheel_rpm": (lay.s_wheel_speed, RAD_S_TO_RPM),
            "wheel_capacity_pct": (lay.s_wheel_speed, 100.0 / sim.robot.wheel_no_load_speed),
            "wheel_torque_nm": (self._nsens + lay.a_wheel, lay.wheel_gear),
            "foot_L_n": (lay.s_foot_l, 1.0),
            "foot_R_n": (lay.s_foot_r, 1.0),
        }
        after = self._nsens + self._nu + self._nq  # the kernel's fields follow MjData's in a row
        for i, (signal, scale) in enumerate(KERNEL_SIGNALS.values()):
            sources[signal] = (after + i, scale)
        for j, qi, fi in zip(LEG_JOINTS, lay.q_legs, lay.a_legs, strict=True):
            sources[f"{j}_deg"] = (self._nsens + self._nu + qi, math.degrees(1.0))
            sources[f"{j}_torque_nm"] = (self._nsens + fi, 1.0)
        self._signal_source = np.array([sources[name][0] for name in SIGNALS])
        self._signal_scale = np.array([sources[name][1] for name in SIGNALS])
        self._body_ids = [mesh.body_id for mesh in self._meshes]
        self._torso = self._body_ids[[mesh.name for mesh in self._meshes].index("torso")]
        self._nbody = m.nbody

    def _send_config(self, sim: Simulation) -> None:
        """The live settings (sim.config) as the recording's `config` property; re-sent at each change."""
        c, g = sim.config, sim.config.gains
        self.rec.send_property(
            "config",
            rr.AnyValues(
                terrain=c.terrain,
                seed=c.seed,
                gravity=c.gravity,
                model=c.model or "",  # the robot's MJCF path, "" for the packaged one
                wheel=c.wheel,
                timestep=c.timestep,
                sensing=c.sensing,
                kp=g.kp,
                ki=g.ki,
                kd=g.kd,
                controller=c.controller,  # hopper.controllers spec, and its param values as JSON
                controller_params=json.dumps(sim.law.values),
                # The wheel commands' way to the motor (wheel_cmd_nm): ticks late, and the motor they
                # were made for (stall torque N m, back-EMF slope N m s/rad at the wheel).
                delay_ticks=c.command_delay_ticks,
                wheel_torque_limit=sim.robot.wheel_torque_limit,
                wheel_damping=sim.robot.wheel_damping,
            ),
        )

    # -- Listener --------------------------------------------------------------------------
    def tick(self, sim: Simulation) -> None:
        """Buffer one tick. The hot path: nine byte-view appends (unrolled: one per KERNEL_FIELDS among
        them) and a counter."""
        b = self._ticks
        b += self._sensor_view
        b += self._force_view
        b += self._qpos_view
        b += self._est_views[0]
        b += self._est_views[1]
        b += self._est_views[2]
        b += self._est_views[3]
        b += self._est_views[4]
        b += self._phase_view
        n = self._n = self._n + 1
        if n % POSE_EVERY_TICKS == 0:
            self._pose_rows.append(n - 1)
            p = self._poses
            p += self._xpos_view
            p += self._xquat_view
            if n >= self._batch or time.monotonic() >= self._flush_due:
                self._flush(wait=self._wait_each_batch)

    def event(self, sim: Simulation, event: Event) -> None:
        """Buffer an event's text (and a finished hop's metrics); a reset sends the ticks before it."""
        if self._closed:
            return
        if event.kind == EventKind.TERRAIN:
            self._chunks += self._terrain.sync(self.rec, sim)
        if event.kind in SETTING_EVENTS:
            self._send_config(sim)
        if event.kind == EventKind.RESET:
            self._flush(wait=False, check_clock=False)  # rows before the reset keep their times
            self._offset_ns = self._next_ns - self._data_ns()
            self._carry_qpos = self._qpos.copy()
            self._last_torso = None
        t_ns = round(event.time * 1e9) + self._offset_ns
        hop = getattr(event.payload, "hop", None)
        if hop is not None:
            self._hops += 1
            self._hop_rows.append((t_ns, self._hops, hop_values(hop)))
        text = f"{event.kind}: {event.describe()}"
        self._events.append((t_ns, self._hops, str(event.kind), EVENT_LEVELS.get(event.kind, "INFO"), text))

    # -- sending ---------------------------------------------------------------------------
    def flush(self, wait: bool = True) -> None:
        """Send everything buffered now; `wait` until the sinks have written it."""
        self._flush(wait)

    def _flush(self, wait: bool, check_clock: bool = True) -> None:
        with held(), self._lock:
            if self._closed:
                return
            self._sending = time.perf_counter()  # the lag watchdog counts a wait in progress too
            try:
                self._send(check_clock)
                if wait:
                    self._wait_for_sinks()
                else:
                    self._start_flush()
            finally:
                self._waited += time.perf_counter() - self._sending
                self._sending = None
            self._check_file()

    def _start_flush(self) -> None:
        """Have rerun encode what was sent and hand it to the file now, without waiting for it."""
        try:
            self.rec.flush(timeout_sec=0.0)
        except RuntimeError as exc:
            log.warning("rerun: starting a flush failed (%s)", exc)

    def _send(self, check_clock: bool) -> None:
        self._flush_due = time.monotonic() + self._flush_s
        if self._stopping and self._file is not None and self._file.full:
            self._drop_buffers()  # the reserve holds the footer, not more data
            return
        self._chunks += self._terrain.sync(self.rec, self.sim)  # tiles the window took in since the last batch
        # Take the buffers before sending (an exception mid-send must not make the next flush send
        # them twice) and copy them out: a numpy view would pin a bytearray that tick() may still
        # append to if close() runs on another thread.
        ticks, rows, poses = bytes(self._ticks), self._pose_rows, bytes(self._poses)
        count, events, phases, hop_rows = self._n, self._events, self._phases, self._hop_rows
        self._drop_buffers()
        extra = len(KERNEL_FIELDS) + 1  # ... | KERNEL_FIELDS | phase
        width = self._nsens + self._nu + self._nq + extra
        ticks, poses = np.frombuffer(ticks, dtype=np.float64), np.frombuffer(poses, dtype=np.float64)
        n = min(count, len(ticks) // width)  # an interrupt may cut a tick's appends short
        k = min(len(rows), len(poses) // (7 * self._nbody))
        if n:
            times = self._next_ns + np.arange(n, dtype=np.int64) * self._dt_ns
            self._next_ns += n * self._dt_ns
            table = ticks[: n * width].reshape(n, width)
            self._send_signals(times, table[:, :-extra], table[:, -extra:-1])
            codes = table[:, -1].view(np.int64)  # the phase field is an int64 in the kernel memory
            phases = sorted(phases + self._phase_changes(times, codes, hop_rows))
            self._batches += 1
            if self._batches % LIMIT_EVERY_BATCHES == 0:
                self._send_limits(times[-1:])
            k = sum(1 for r in rows[:k] if r < n)
            if k:
                self._send_poses(times[rows[:k]], poses[: k * 7 * self._nbody].reshape(k, 7 * self._nbody))
        if events:
            t, h, kinds, levels, texts = zip(*events, strict=True)
            columns = [
                Column(TEXT, pa.array(texts)),
                Column(LEVEL, pa.array(levels)),
                Column("kind", pa.array(kinds)),
            ]
            self._chunks += 1
            rr.send_columns("events", time_columns(t, h), columns, recording=self.rec)
        if phases:
            t, h, labels = zip(*phases, strict=True)
            self._chunks += 1
            rr.send_columns("phase", time_columns(t, h), [Column(STATE, pa.array(labels))], recording=self.rec)
        if hop_rows:
            t, h, metrics = zip(*hop_rows, strict=True)
            columns = [
                Column(rr.ComponentDescriptor(name, archetype=HOP_ARCHETYPE), pa.array([m[name] for m in metrics]))
                for name in metrics[0]
            ]
            self._chunks += 1
            rr.send_columns("hops", time_columns(t, h), columns, recording=self.rec)
        expected = self._data_ns() + self._offset_ns
        if check_clock and n and expected != self._next_ns:
            # Steps without tick() (or a time jump): re-anchor rather than drift, and say so once. A
            # clock that went back is a restore (History, a keyframe), which loses no tick: no warning.
            if not self._warned and expected > self._next_ns:
                log.warning(
                    "telemetry missed %d ticks; re-anchoring sim_time", (expected - self._next_ns) // self._dt_ns
                )
                self._warned = True
            self._next_ns = expected

    def _drop_buffers(self) -> None:
        self._ticks, self._poses, self._n, self._pose_rows = bytearray(), bytearray(), 0, []
        self._events, self._phases, self._hop_rows = [], [], []

    def _phase_changes(
        self, times: np.ndarray, codes: np.ndarray, hop_rows: list[tuple[int, int, dict[str, Any]]]
    ) -> list[tuple[int, int, str]]:
        """(time, hop, label) where the phase column differs from the row before it."""
        previous = np.concatenate([[self._phase], codes[:-1]])
        changed = np.flatnonzero(codes != previous)
        self._phase = int(codes[-1])
        hops_before = self._hops - len(hop_rows)  # hop rows of this batch are already counted
        hop_times = [t for t, _, _ in hop_rows]
        return [
            (int(times[i]), hops_before + bisect.bisect_right(hop_times, int(times[i])), Phase(int(codes[i])).label)
            for i in changed
        ]

    def _send_signals(self, times: np.ndarray, rows: np.ndarray, estimates: np.ndarray) -> None:
        """rows: (n, nsensordata + nu + nq) as buffered by tick(); estimates: (n, len(KERNEL_FIELDS)),
        the kernel's fields in that order."""
        s, f = rows[:, : self._nsens], rows[:, self._nsens : self._nsens + self._nu]
        after = rows[:, self._nsens + self._nu :]  # qpos after each step: the next row's state
        q = np.vstack([self._carry_qpos, after[:-1]])
        self._carry_qpos = after[-1].copy()
        values = (
            np.hstack([s, f, q, estimates])[:, self._signal_source] * self._signal_scale
        )  # (n, len(SIGNALS)), SI -> units
        n32 = len(SIGNALS_F32)
        rows32 = np.ascontiguousarray(values[:, :n32].T, dtype=np.float32)  # one contiguous row per field
        rows16 = np.ascontiguousarray(values[:, n32:].T, dtype=np.float16)
        struct = pa.StructArray.from_arrays([pa.array(r) for r in (*rows32, *rows16)], names=list(SIGNALS))
        self._chunks += 1
        rr.send_columns("signals", time_columns(times), [Column("signals", struct)], recording=self.rec)

    def _send_poses(self, times: np.ndarray, rows: np.ndarray) -> None:
        """rows: (k, 7 nbody), every body's xpos then every body's xquat, as buffered by tick()."""
        ids, k = self._body_ids, len(rows)
        p = rows[:, : 3 * self._nbody].reshape(k, self._nbody, 3)
        q = rows[:, 3 * self._nbody :].reshape(k, self._nbody, 4)[:, ids][..., [1, 2, 3, 0]]  # wxyz -> xyzw
        nb = len(ids)
        frames = self._frames.get(k) or self._frames.setdefault(k, pa.array([m.name for m in self._meshes] * k))
        self._chunks += 1
        rr.send_columns(  # one row per body and sample: one chunk for all bodies
            "world/tf",
            time_columns(np.repeat(times, nb)),
            [
                Column(TRANSLATION, vectors(p[:, ids].reshape(-1, 3))),
                Column(QUATERNION, vectors(q.reshape(-1, 4))),
                Column(CHILD_FRAME, frames),
            ],
            recording=self.rec,
        )
        torso = p[:, self._torso]
        trail = torso if self._last_torso is None else np.vstack([self._last_torso, torso])
        self._last_torso = torso[-1].tolist()
        points = vectors(trail)
        strip = pa.ListArray.from_arrays(
            pa.array([0, len(trail)], pa.int32()), points, type=pa.list_(pa.field("item", points.type, False))
        )
        self._chunks += 1
        rr.send_columns("world/trail", time_columns(times[-1:]), [Column(STRIPS, strip)], recording=self.rec)

    def _send_limits(self, times: np.ndarray | list[int]) -> None:
        limit = self.sim.robot.wheel_torque_limit
        limits = pa.array(np.tile([limit, -limit], len(times)))
        self._chunks += 1
        rr.send_columns("limits/wheel_torque", time_columns(times), [Column(SCALARS, limits, 2)], recording=self.rec)

    def _wait_for_sinks(self) -> None:
        """rec.flush(), but a viewer that went away (its window closed) must not fail the file."""
        try:
            self.rec.flush(timeout_sec=SINK_TIMEOUT_S)
        except RuntimeError as exc:
            log.warning("rerun: a sink failed (%s); the file is still written", exc)

    def _data_ns(self) -> int:
        return round(self._data.time * 1e9)

    # -- closing ---------------------------------------------------------------------------
    def close(self) -> None:
        """Send what is buffered, finalise the file (its footer), then run `on_close`; idempotent."""
        with held(), self._lock:
            if self._closed:
                return
            with contextlib.suppress(ValueError):
                self.sim.listeners.remove(self)
            self._closed = True
            try:
                self._send(check_clock=False)  # an interrupt may have cut a step short of its tick()
                if not (self._file is not None and self._file.full):
                    self._send_limits([max(self._start_ns, self._next_ns - self._dt_ns)])
                self._wait_for_sinks()
            finally:
                self._unwatched.set()
                self.rec.disconnect()  # writes the .rrd footer, stops a gRPC server sink
                self._blueprints.close()
                self._finish_file()
                _open.discard(self)
                self._closed_callback()
        self._report_failure()  # outside the lock: the owner may look at this recording

    def _finish_file(self) -> None:
        """Wait for the writer to store the footer, then give back the reserve."""
        if self._file is not None and not self._file.join():
            log.error("recording: %s was not finished in time", self._file.path.name)
        if self._reserve is not None:
            self._reserve.discard()
        if self._file is not None and self._file.error is not None and self.failure is None:
            self.failure = self._file.error

    def _abandon(self) -> None:
        """Construction failed or was interrupted: finish whatever part of the file was opened."""
        with held():
            if self._ready:  # set up: the usual close, footer and all
                self.close()
                return
            if self.rec is not None:
                self.rec.disconnect()  # the footer of whatever the sink wrote
            if getattr(self, "_blueprints", None) is not None:
                self._blueprints.close()
            if self._file is not None and not self._file.join(timeout=10.0):
                log.error("recording: %s was not finished in time", self._file.path.name)
            if self._reserve is not None:
                self._reserve.discard()
            self._closed_callback()

    def _closed_callback(self) -> None:
        on_close, self._on_close = self._on_close, None
        if on_close is not None:
            on_close()

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def written(self) -> int:
        """Bytes of the current part on disk so far (0 without a file)."""
        return self._file.written if self._file is not None else 0

    def __enter__(self) -> Telemetry:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


@dataclasses.dataclass(frozen=True)
class _StopRecording:
    """Command: close a recording that cannot go on (a full disk), between two steps."""

    telemetry: Telemetry

    def apply(self, sim: Simulation) -> None:
        self.telemetry._stop()
