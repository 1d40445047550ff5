"""Rerun telemetry of a Simulation: 1 kHz signals, phases, events, per-hop metrics and 3D poses.

A CLI records so that Ctrl-C and SIGTERM still leave a file `rerun rrd verify` accepts:

    path = check_writable(args.rrd)  # before the simulation starts
    exit_on_sigterm()  # SIGTERM -> SystemExit, so the `with` block unwinds
    with Telemetry(sim, path=path) as telemetry:
        sim.run(hops)
"""

from __future__ import annotations

import atexit
import bisect
import contextlib
import datetime
import logging
import math
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
import weakref
from collections.abc import Iterator
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any, Literal
from urllib.parse import quote

import numpy as np
import pyarrow as pa
import rerun as rr
import rerun.blueprint as rrb
from rerun.blueprint.encodings import ComponentSourceKind, VisualizerComponentMapping

from hopper.config import WHEEL_TORQUE_LIMIT
from hopper.control import Phase
from hopper.events import EventKind
from hopper.layout import LEG_JOINTS
from hopper.meshes import body_meshes, terrain_mesh

if TYPE_CHECKING:
    from hopper.sim import Event, Simulation

log = logging.getLogger(__name__)

APPLICATION_ID = "hopper"
TIME = "sim_time"
HOP = "hop"
# A batch goes out when it holds BATCH_TICKS ticks or FLUSH_WALL_S after the last one, whichever
# comes first: faster than real time the ticks decide (a send costs ~1 ms whatever its size, each
# chunk ~1 kB of schema), at real time the clock does (a live viewer lags by at most a second).
BATCH_TICKS = 4000
FLUSH_WALL_S = 1.0
LIMIT_EVERY_BATCHES = 5  # the torque limit lines only need a point now and then
POSE_EVERY_TICKS = 20  # 50 Hz body poses
RAD_S_TO_RPM = 60.0 / (2.0 * math.pi)
SIGNALS_F32 = ("pitch_deg", "pitch_rate_deg_s", "wheel_rpm", "wheel_torque_nm")
SIGNALS_F16 = (*(f"{j}_deg" for j in LEG_JOINTS), *(f"{j}_torque_nm" for j in LEG_JOINTS), "foot_L_n", "foot_R_n")
SIGNALS = SIGNALS_F32 + SIGNALS_F16
EVENT_LEVELS = {
    EventKind.FALL: "ERROR",
    EventKind.COMMAND_FAILED: "ERROR",
    EventKind.DIVERGED: "WARN",
    EventKind.DISTURBANCE: "WARN",
}
SETTING_EVENTS = (EventKind.GAINS, EventKind.WHEEL, EventKind.GRAVITY, EventKind.TERRAIN)
VIEWER_WAIT_S = 10.0  # s for a viewer process to start listening
VIEWER_GRACE_S = 1.5  # s a spawned viewer must then stay alive (no display: it exits within ~0.5 s)
BLUE, ORANGE, GREEN, RED, PURPLE = (31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189)


class TelemetryError(RuntimeError):
    """A viewer could not be started or reached."""


# -- paths ---------------------------------------------------------------------------------------
def check_writable(path: str | Path) -> Path:
    """The absolute .rrd path, or ValueError with a one-line reason why it cannot be written."""
    p = Path(path).expanduser().absolute()
    if p.suffix != ".rrd":
        raise ValueError(f"recording path {str(path)!r} must end in .rrd")
    if p.is_dir():
        raise ValueError(f"recording path {str(p)!r} is a directory")
    if not p.parent.is_dir():
        raise ValueError(f"cannot write recording {str(p)!r}: directory {str(p.parent)!r} does not exist")
    existed = p.exists()
    try:  # really open it: permission bits say little for root, read-only mounts or ACLs
        with open(p, "ab"):
            pass
    except OSError as exc:
        raise ValueError(f"cannot write recording {str(p)!r}: {exc.strerror or exc}") from None
    if not existed:
        p.unlink(missing_ok=True)
    return p


def session_path(folder: str | Path, prefix: str = "hopper") -> Path:
    """A new path `folder/prefix-YYYYmmdd-HHMMSS.rrd` (folder created; never an existing file)."""
    directory = Path(folder).expanduser()
    directory.mkdir(parents=True, exist_ok=True)
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    path, n = directory / f"{prefix}-{stamp}.rrd", 2
    while path.exists():
        path, n = directory / f"{prefix}-{stamp}-{n}.rrd", n + 1
    return path


# -- signals -------------------------------------------------------------------------------------
def exit_on_sigterm() -> None:
    """Make SIGTERM raise SystemExit(143) in the main thread, so `with`/`finally` close recordings.

    Python's default SIGTERM action kills the process without unwinding; Ctrl-C (SIGINT) already
    raises KeyboardInterrupt. Call from the main thread before the simulation starts.
    """

    def handler(signum: int, frame: object) -> None:
        raise SystemExit(128 + signum)

    signal.signal(signal.SIGTERM, handler)


@contextlib.contextmanager
def _deferred_signals() -> Iterator[None]:
    """Hold SIGINT and SIGTERM while a batch is sent or the file finalised, then deliver them.

    An interrupt in the middle of a send would lose or duplicate part of a batch. Only the main
    thread can install handlers; in other threads this does nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    saved = {
        sig: signal.signal(sig, lambda signum, _: pending.append(signum)) for sig in (signal.SIGINT, signal.SIGTERM)
    }
    try:
        yield
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)
        if pending:
            signal.raise_signal(pending[0])


# -- viewers -------------------------------------------------------------------------------------
def _rerun_executable() -> str:
    """The rerun CLI shipped with rerun-sdk (the SDK's own version), else one on PATH."""
    import rerun_cli

    bundled = Path(rerun_cli.__file__).parent / ("rerun.exe" if sys.platform == "win32" else "rerun")
    found = str(bundled) if bundled.exists() else shutil.which("rerun")
    if found is None:
        raise TelemetryError("the rerun CLI is missing (it comes with the rerun-sdk package)")
    return found


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _wait_for_port(port: int, process: subprocess.Popen[bytes], what: str) -> None:
    deadline = time.monotonic() + VIEWER_WAIT_S
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise TelemetryError(f"{what} exited with code {process.returncode} before listening on port {port}")
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.05)
    _signal_group(process, signal.SIGTERM)
    process.wait()
    raise TelemetryError(f"{what} did not listen on 127.0.0.1:{port} within {VIEWER_WAIT_S:g} s")


def _signal_group(process: subprocess.Popen[bytes], signum: int) -> None:
    """Signal the process group we started it in (it is its leader), or just the process."""
    if hasattr(os, "killpg"):
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signum)
    else:
        process.send_signal(signum)


def _has_display() -> bool:
    return sys.platform in ("darwin", "win32") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


# -- arrow columns -------------------------------------------------------------------------------
class _Column:
    """A ready-made component column for rr.send_columns: one `per_row` slice of `values` a row.

    The archetypes' .columns() helpers convert element by element in Python, ~100x slower.
    """

    def __init__(self, descriptor: rr.ComponentDescriptor | str, values: pa.Array, per_row: int = 1) -> None:
        self.descriptor = rr.ComponentDescriptor(descriptor) if isinstance(descriptor, str) else descriptor
        self.array = pa.ListArray.from_arrays(np.arange(0, len(values) + 1, per_row, dtype=np.int32), values)

    def component_descriptor(self) -> rr.ComponentDescriptor:
        return self.descriptor

    def as_arrow_array(self) -> pa.Array:
        return self.array


def _vectors(values: np.ndarray) -> pa.Array:
    """(n, k) floats as Arrow fixed-size lists of float32: rerun's Vec3D and Quaternion layout."""
    k = values.shape[-1]
    flat = pa.array(np.ascontiguousarray(values, dtype=np.float32).ravel())
    return pa.FixedSizeListArray.from_arrays(flat, type=pa.list_(pa.field("item", pa.float32(), False), k))


def _times(ns: np.ndarray | list[int], hops: np.ndarray | list[int] | None = None) -> list[rr.TimeColumn]:
    columns = [rr.TimeColumn(TIME, duration=np.asarray(ns, dtype=np.int64).astype("timedelta64[ns]"))]
    if hops is not None:
        columns.append(rr.TimeColumn(HOP, sequence=hops))
    return columns


_TRANSLATION = rr.Transform3D.descriptor_translation()
_QUATERNION = rr.Transform3D.descriptor_quaternion()
_CHILD_FRAME = rr.Transform3D.descriptor_child_frame()
_STRIPS = rr.LineStrips3D.descriptor_strips()
_SCALARS = rr.Scalars.descriptor_scalars()
_TEXT = rr.TextLog.descriptor_text()
_LEVEL = rr.TextLog.descriptor_level()
_STATE = rr.StateChange.descriptor_state()


# -- blueprint -----------------------------------------------------------------------------------
def _lines(*fields: tuple[str, str, tuple[int, int, int]]) -> list[Any]:
    """One line visualizer per (struct field of `signals`, legend name, colour)."""
    return [
        rr.SeriesLines(names=name, colors=[color]).visualizer(
            mappings=[
                VisualizerComponentMapping(
                    target=str(_SCALARS.component),
                    source_kind=ComponentSourceKind.SourceComponent,
                    source_component="signals",
                    selector=f".{field}",
                )
            ]
        )
        for field, name, color in fields
    ]


def _plot(name: str, *fields: tuple[str, str, tuple[int, int, int]], extra: str | None = None) -> rrb.View:
    contents = ["/signals", extra] if extra else ["/signals"]
    return rrb.TimeSeriesView(name=name, origin="/", contents=contents, overrides={"/signals": _lines(*fields)})


def default_blueprint() -> rrb.Blueprint:
    """Robot and hop table on the left; pitch, wheel speed and torque, more plots, phases, events."""
    colors = (BLUE, ORANGE, GREEN, RED)
    robot = rrb.Spatial3DView(
        name="robot",
        origin="/world",
        # From the -y side, following the torso; the trail shows everything up to the time cursor.
        eye_controls=rrb.EyeControls3D(
            position=(0.0, -3.5, 1.2),
            look_target=(0.0, 0.0, 0.7),
            eye_up=(0, 0, 1),
            tracking_entity="/world/robot/torso",
        ),
        time_ranges=rrb.VisibleTimeRange(
            TIME, start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.cursor_relative()
        ),
    )
    hops = rrb.DataframeView(name="hop metrics", origin="/hops", query=rrb.archetypes.DataframeQuery(timeline=HOP))
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(robot, hops, row_shares=[3, 2]),
            rrb.Vertical(
                _plot("pitch (deg)", ("pitch_deg", "pitch", BLUE)),
                _plot("wheel speed (rpm)", ("wheel_rpm", "wheel", PURPLE)),
                _plot("wheel torque (N m)", ("wheel_torque_nm", "torque", ORANGE), extra="/limits/wheel_torque"),
                rrb.Tabs(
                    _plot("pitch rate (deg/s)", ("pitch_rate_deg_s", "pitch rate", GREEN)),
                    _plot("leg angles (deg)", *[(f"{j}_deg", j, c) for j, c in zip(LEG_JOINTS, colors, strict=True)]),
                    _plot(
                        "leg torques (N m)",
                        *[(f"{j}_torque_nm", j, c) for j, c in zip(LEG_JOINTS, colors, strict=True)],
                    ),
                    _plot("foot forces (N)", ("foot_L_n", "left", BLUE), ("foot_R_n", "right", RED)),
                ),
                rrb.StateTimelineView(name="phase", origin="/phase"),
                row_shares=[3, 3, 3, 3, 2],
            ),
            rrb.TextLogView(name="events", origin="/events"),
            column_shares=[5, 5, 3],
        ),
        collapse_panels=True,
    )


# -- the listener --------------------------------------------------------------------------------
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
    - `limits/wheel_torque`: +-WHEEL_TORQUE_LIMIT reference lines.
    - `phase`: StateChange at each change, exact to the tick. `events`: TextLog and a `kind`.
    - `hops`: a row per touchdown (or fall in flight), a float64 component per HopMetrics field.
    - `world/terrain`, `world/robot/<body>`: static meshes, bodies in named frames posed by
      `world/tf` (Transform3D rows with `child_frame`) at 50 Hz; `world/trail`: the torso path.

    A row is the state at the start of its tick, as that tick's forward pass saw it: sensors,
    applied actuator forces and body poses come from MjData after mj_step (the integrator leaves
    them), joint angles from the qpos of one tick earlier (it advances qpos). MjData is read
    directly: the simulation no longer refreshes `sim.physics` every tick.

    tick() appends four byte views to a bytearray (~0.5 us); every `batch_ticks` ticks (or
    FLUSH_WALL_S) the batch is read back with numpy and sent with rr.send_columns. Call
    close() (or use `with`) from the thread that steps the simulation, or while it is not stepping
    (e.g. through `sim.submit`).
    """

    def __init__(
        self,
        sim: Simulation,
        *,
        path: str | Path | None = None,
        viewer: Literal["spawn", "serve", "off"] = "off",
        recording_name: str | None = None,
        batch_ticks: int = BATCH_TICKS,
    ) -> None:
        if viewer not in ("spawn", "serve", "off"):
            raise ValueError(f"viewer must be 'spawn', 'serve' or 'off', got {viewer!r}")
        if path is None and viewer == "off":
            raise ValueError("nothing to record to: give a path, or viewer='spawn' or 'serve'")
        if batch_ticks < POSE_EVERY_TICKS or batch_ticks % POSE_EVERY_TICKS:
            raise ValueError(f"batch_ticks must be a positive multiple of {POSE_EVERY_TICKS}, got {batch_ticks}")
        self.sim = sim
        self.path = check_writable(path) if path is not None else None
        self.viewer_url: str | None = None  # the web viewer's address with viewer="serve"
        self._batch = batch_ticks
        self._lock = threading.Lock()
        self._closed = False
        self._web: subprocess.Popen[bytes] | None = None
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
        self._flush_due = time.monotonic() + FLUSH_WALL_S
        self._frames: dict[int, pa.Array] = {}  # child_frame columns by pose count
        self._hops = 0
        # The kernel's phase slot, appended to every row: phases exact to the tick at no cost.
        self._phase_view = memoryview(sim.controller.field("phase")).cast("B")  # int64
        self._phase = int(sim.phase)

        self.rec = rr.RecordingStream(APPLICATION_ID)
        self.rec.set_log_tick_enabled(False)  # only our two timelines
        self.rec.set_log_time_enabled(False)
        try:
            rr.set_sinks(*self._sinks(viewer), default_blueprint=default_blueprint(), recording=self.rec)
        except BaseException:
            self._stop_web()
            raise
        self.rec.send_recording_name(recording_name or f"hopper {sim.config.terrain} seed {sim.config.seed}")
        self._log_static(sim)
        self._phases.append((self._next_ns, 0, sim.phase.label))
        sim.listeners.append(self)
        _open.add(self)

    # -- setup -----------------------------------------------------------------------------
    def _layout(self, sim: Simulation) -> None:
        """Columns of each signal in a buffered row, from the simulation's model layout."""
        m, lay = sim.model, sim.layout
        self._nsens, self._nu, self._nq = m.nsensordata, m.nu, m.nq
        # Each signal as (column of [sensordata | actuator_force | qpos], scale from SI).
        sources = {
            "pitch_deg": (lay.s_pitch, math.degrees(1.0)),
            "pitch_rate_deg_s": (lay.s_gyro_pitch, math.degrees(1.0)),
            "wheel_rpm": (lay.s_wheel_speed, RAD_S_TO_RPM),
            "wheel_torque_nm": (self._nsens + lay.a_wheel, lay.wheel_gear),
            "foot_L_n": (lay.s_foot_l, 1.0),
            "foot_R_n": (lay.s_foot_r, 1.0),
        }
        for j, qi, fi in zip(LEG_JOINTS, lay.q_legs, lay.a_legs, strict=True):
            sources[f"{j}_deg"] = (self._nsens + self._nu + qi, math.degrees(1.0))
            sources[f"{j}_torque_nm"] = (self._nsens + fi, 1.0)
        self._signal_source = np.array([sources[name][0] for name in SIGNALS])
        self._signal_scale = np.array([sources[name][1] for name in SIGNALS])
        self._body_ids = [mesh.body_id for mesh in self._meshes]
        self._torso = self._body_ids[[mesh.name for mesh in self._meshes].index("torso")]
        self._nbody = m.nbody

    def _sinks(self, viewer: str) -> list[Any]:
        sinks: list[Any] = [rr.FileSink(str(self.path))] if self.path is not None else []
        if viewer == "spawn":
            if not _has_display():
                raise TelemetryError("viewer='spawn' needs a display (DISPLAY is not set); use viewer='serve'")
            port = _free_port()
            process = subprocess.Popen(
                [_rerun_executable(), "--bind", "127.0.0.1", "--port", str(port), "--expect-data-soon"],
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                start_new_session=True,  # the window outlives the run and ignores our Ctrl-C
            )
            _wait_for_port(port, process, "the rerun viewer")
            time.sleep(VIEWER_GRACE_S)  # it listens before opening its window, and exits if it cannot
            if process.poll() is not None:
                raise TelemetryError(f"the rerun viewer exited with code {process.returncode}: no usable display?")
            sinks.append(rr.GrpcSink(f"rerun+http://127.0.0.1:{port}/proxy"))
        elif viewer == "serve":
            # rr.serve_web_viewer binds 0.0.0.0, the CLI's web server takes --bind: the gRPC server
            # lives in this process on loopback, the CLI only serves the viewer's files.
            server = rr.GrpcServerSink(bind_ip="127.0.0.1", port=_free_port())
            sinks.append(server)
            web_port = _free_port()
            self._web = subprocess.Popen(
                [
                    _rerun_executable(),
                    "--serve-web",
                    "--bind",
                    "127.0.0.1",
                    "--web-viewer-port",
                    str(web_port),
                    server.uri,
                ],
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                start_new_session=True,  # its own process group: a wrapper script's child dies with it
            )
            _wait_for_port(web_port, self._web, "the rerun web viewer server")
            self.viewer_url = f"http://127.0.0.1:{web_port}/?url={quote(server.uri, safe='')}"
        return sinks

    def _log_static(self, sim: Simulation) -> None:
        rec = self.rec
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        self._log_terrain(sim)
        for mesh in self._meshes:  # each body mesh lives in its own frame, posed by world/tf
            # rerun draws mesh vertex alpha opaque, and the torso box would hide the wheel inside
            # it: draw the torso as a transparent box with its edges instead.
            shape = _torso_box(sim.model) if mesh.name == "torso" else _mesh3d(mesh.vertices, mesh.faces, mesh.colors)
            rec.log(f"world/robot/{mesh.name}", shape, rr.CoordinateFrame(mesh.name), static=True)
        rec.log("limits/wheel_torque", rr.SeriesLines(names=["+limit", "-limit"], colors=[RED, RED]), static=True)
        self._send_config(sim)
        self._send_limits([self._next_ns])

    def _send_config(self, sim: Simulation) -> None:
        """The live settings (sim.config) as the recording's `config` property; re-sent at each change."""
        c, g = sim.config, sim.config.gains
        self.rec.send_property(
            "config",
            rr.AnyValues(
                terrain=c.terrain,
                seed=c.seed,
                gravity=c.gravity,
                wheel=c.wheel,
                timestep=c.timestep,
                kp=g.kp,
                ki=g.ki,
                kd=g.kd,
            ),
        )

    def _log_terrain(self, sim: Simulation) -> None:
        """Static, so a terrain change mid-recording shows its new terrain for the whole replay (the
        3D view's time range would otherwise draw every terrain at once); the event log has the change."""
        mesh = terrain_mesh(sim.heights, sim.config.craters)
        self.rec.log("world/terrain", _mesh3d(mesh.vertices, mesh.faces, mesh.visual.vertex_colors), static=True)

    # -- Listener --------------------------------------------------------------------------
    def tick(self, sim: Simulation) -> None:
        """Buffer one tick. The hot path: four byte-view appends and a counter."""
        b = self._ticks
        b += self._sensor_view
        b += self._force_view
        b += self._qpos_view
        b += self._phase_view
        n = self._n = self._n + 1
        if n % POSE_EVERY_TICKS == 0:
            self._pose_rows.append(n - 1)
            p = self._poses
            p += self._xpos_view
            p += self._xquat_view
            if n >= self._batch or time.monotonic() >= self._flush_due:
                self._flush(wait=False)

    def event(self, sim: Simulation, event: Event) -> None:
        """Buffer an event's text (and a finished hop's metrics); a reset sends the ticks before it."""
        if self._closed:
            return
        if event.kind == EventKind.TERRAIN:
            self._log_terrain(sim)
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
            self._hop_rows.append((t_ns, self._hops, hop.as_dict()))
        text = f"{event.kind}: {event.describe()}"
        self._events.append((t_ns, self._hops, str(event.kind), EVENT_LEVELS.get(event.kind, "INFO"), text))

    # -- sending ---------------------------------------------------------------------------
    def flush(self, wait: bool = True) -> None:
        """Send everything buffered now; `wait` until the sinks have written it."""
        self._flush(wait)

    def _flush(self, wait: bool, check_clock: bool = True) -> None:
        with self._lock, _deferred_signals():
            if self._closed:
                return
            self._send(check_clock)
            if wait:
                self._wait_for_sinks()

    def _send(self, check_clock: bool) -> None:
        self._flush_due = time.monotonic() + FLUSH_WALL_S
        # Take the buffers before sending (an exception mid-send must not make the next flush send
        # them twice) and copy them out: a numpy view would pin a bytearray that tick() may still
        # append to if close() runs on another thread.
        ticks, rows, poses = bytes(self._ticks), self._pose_rows, bytes(self._poses)
        count, events, phases, hop_rows = self._n, self._events, self._phases, self._hop_rows
        self._ticks, self._poses, self._n, self._pose_rows = bytearray(), bytearray(), 0, []
        self._events, self._phases, self._hop_rows = [], [], []
        width = self._nsens + self._nu + self._nq + 1
        ticks, poses = np.frombuffer(ticks, dtype=np.float64), np.frombuffer(poses, dtype=np.float64)
        n = min(count, len(ticks) // width)  # an interrupt may cut a tick's appends short
        k = min(len(rows), len(poses) // (7 * self._nbody))
        if n:
            times = self._next_ns + np.arange(n, dtype=np.int64) * self._dt_ns
            self._next_ns += n * self._dt_ns
            table = ticks[: n * width].reshape(n, width)
            self._send_signals(times, table[:, :-1])
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
                _Column(_TEXT, pa.array(texts)),
                _Column(_LEVEL, pa.array(levels)),
                _Column("kind", pa.array(kinds)),
            ]
            rr.send_columns("events", _times(t, h), columns, recording=self.rec)
        if phases:
            t, h, labels = zip(*phases, strict=True)
            rr.send_columns("phase", _times(t, h), [_Column(_STATE, pa.array(labels))], recording=self.rec)
        if hop_rows:
            t, h, metrics = zip(*hop_rows, strict=True)
            columns = [
                _Column(
                    rr.ComponentDescriptor(name, archetype="hopper.HopMetrics"),
                    pa.array([float(m[name]) for m in metrics]),
                )
                for name in metrics[0]
            ]
            rr.send_columns("hops", _times(t, h), columns, recording=self.rec)
        expected = self._data_ns() + self._offset_ns
        if check_clock and n and expected != self._next_ns:
            # Steps without tick() (or a time jump): re-anchor rather than drift, and say so once.
            if not self._warned:
                log.warning(
                    "telemetry missed %d ticks; re-anchoring sim_time", (expected - self._next_ns) // self._dt_ns
                )
                self._warned = True
            self._next_ns = expected

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

    def _send_signals(self, times: np.ndarray, rows: np.ndarray) -> None:
        """rows: (n, nsensordata + nu + nq) as buffered by tick()."""
        s, f = rows[:, : self._nsens], rows[:, self._nsens : self._nsens + self._nu]
        after = rows[:, self._nsens + self._nu :]  # qpos after each step: the next row's state
        q = np.vstack([self._carry_qpos, after[:-1]])
        self._carry_qpos = after[-1].copy()
        values = np.hstack([s, f, q])[:, self._signal_source] * self._signal_scale  # (n, len(SIGNALS)), SI -> units
        n32 = len(SIGNALS_F32)
        rows32 = np.ascontiguousarray(values[:, :n32].T, dtype=np.float32)  # one contiguous row per field
        rows16 = np.ascontiguousarray(values[:, n32:].T, dtype=np.float16)
        struct = pa.StructArray.from_arrays([pa.array(r) for r in (*rows32, *rows16)], names=list(SIGNALS))
        rr.send_columns("signals", _times(times), [_Column("signals", struct)], recording=self.rec)

    def _send_poses(self, times: np.ndarray, rows: np.ndarray) -> None:
        """rows: (k, 7 nbody), every body's xpos then every body's xquat, as buffered by tick()."""
        ids, k = self._body_ids, len(rows)
        p = rows[:, : 3 * self._nbody].reshape(k, self._nbody, 3)
        q = rows[:, 3 * self._nbody :].reshape(k, self._nbody, 4)[:, ids][..., [1, 2, 3, 0]]  # wxyz -> xyzw
        nb = len(ids)
        frames = self._frames.get(k) or self._frames.setdefault(k, pa.array([m.name for m in self._meshes] * k))
        rr.send_columns(  # one row per body and sample: one chunk for all bodies
            "world/tf",
            _times(np.repeat(times, nb)),
            [
                _Column(_TRANSLATION, _vectors(p[:, ids].reshape(-1, 3))),
                _Column(_QUATERNION, _vectors(q.reshape(-1, 4))),
                _Column(_CHILD_FRAME, frames),
            ],
            recording=self.rec,
        )
        torso = p[:, self._torso]
        trail = torso if self._last_torso is None else np.vstack([self._last_torso, torso])
        self._last_torso = torso[-1].tolist()
        points = _vectors(trail)
        strip = pa.ListArray.from_arrays(
            pa.array([0, len(trail)], pa.int32()), points, type=pa.list_(pa.field("item", points.type, False))
        )
        rr.send_columns("world/trail", _times(times[-1:]), [_Column(_STRIPS, strip)], recording=self.rec)

    def _send_limits(self, times: np.ndarray | list[int]) -> None:
        limits = pa.array(np.tile([WHEEL_TORQUE_LIMIT, -WHEEL_TORQUE_LIMIT], len(times)))
        rr.send_columns("limits/wheel_torque", _times(times), [_Column(_SCALARS, limits, 2)], recording=self.rec)

    def _wait_for_sinks(self) -> None:
        """rec.flush(), but a viewer that went away (its window closed) must not fail the file."""
        try:
            self.rec.flush()
        except RuntimeError as exc:
            log.warning("rerun: a sink failed (%s); the file is still written", exc)

    def _data_ns(self) -> int:
        return round(self._data.time * 1e9)

    # -- closing ---------------------------------------------------------------------------
    def close(self) -> None:
        """Send what is buffered, finalise the file (its footer) and stop viewers; idempotent."""
        with self._lock, _deferred_signals():
            if self._closed:
                return
            with contextlib.suppress(ValueError):
                self.sim.listeners.remove(self)
            self._closed = True
            try:
                self._send(check_clock=False)  # an interrupt may have cut a step short of its tick()
                self._send_limits([max(self._start_ns, self._next_ns - self._dt_ns)])
                self._wait_for_sinks()
            finally:
                self.rec.disconnect()  # writes the .rrd footer, stops the gRPC server
                self._stop_web()
                _open.discard(self)

    def _stop_web(self) -> None:
        web, self._web = self._web, None
        if web is None or web.poll() is not None:
            return
        _signal_group(web, signal.SIGTERM)
        try:
            web.wait(timeout=5)
        except subprocess.TimeoutExpired:
            _signal_group(web, signal.SIGKILL if hasattr(signal, "SIGKILL") else signal.SIGTERM)
            web.wait()

    @property
    def closed(self) -> bool:
        return self._closed

    def __enter__(self) -> Telemetry:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


def _mesh3d(vertices: Any, faces: Any, colors: Any) -> rr.Mesh3D:
    return rr.Mesh3D(
        vertex_positions=np.asarray(vertices, dtype=np.float32),
        triangle_indices=np.asarray(faces, dtype=np.uint32),
        vertex_colors=np.asarray(colors, dtype=np.uint8),
    )


def _torso_box(model: Any) -> rr.Boxes3D:
    geom = model.geom("torso")
    rgba = np.clip(np.asarray(geom.rgba) * 255, 0, 255).astype(np.uint8)
    return rr.Boxes3D(
        half_sizes=[geom.size],
        centers=[geom.pos],
        colors=[rgba],
        fill_mode=rr.components.FillMode.TransparentFillMajorWireframe,
    )
