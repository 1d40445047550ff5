"""Rerun telemetry: 1 kHz signals, phases, events, per-hop metrics and 3D poses, to a .rrd and/or a viewer.

Usage from a CLI (Ctrl-C and SIGTERM both leave a finalised file that `rerun rrd verify` accepts):

    path = check_writable(args.record)          # before the simulation starts
    exit_on_sigterm()                           # SIGTERM -> SystemExit, so `with` blocks unwind
    with Telemetry(sim, path=path, viewer="off") as telemetry:
        sim.run(hops)

Layout of a recording. Timelines: `sim_time` (duration; the simulation time, kept monotonic across
resets) and `hop` (sequence; hops completed in this recording, so it keeps counting after a reset).

- `signals`: one row per control tick, one struct component `signals` with the float32 fields of
  SIGNALS. One struct instead of one entity per channel because every entity row costs a row id, a
  time and an offset (~14 B after compression) plus ~1 kB per chunk: 14 separate channels would
  take ~14 MB per simulated minute, the struct ~4.5 MB. The blueprint plots the fields through
  component mappings (selector `.pitch_deg` etc.).
- `limits/wheel_torque`: +-WHEEL_TORQUE_LIMIT as reference lines, two rows per batch.
- `phase`: StateChange on every phase change. `events`: TextLog per simulation event.
- `hops/<metric>`: Scalars per HopMetrics field at each touchdown (and at a fall in flight), on
  both timelines.
- `world/terrain`, `world/robot/<body>`: static meshes; `Transform3D` body poses every
  POSE_EVERY_TICKS; `world/trail`: the torso path, one strip per batch.

Row timing: a row describes the state at the start of its tick, exactly what MuJoCo's forward pass
of that tick saw: sensors (pitch, rate, wheel speed, foot forces), actuator forces (the torques
applied this tick) and body poses are read from MjData after mj_step (they are not advanced by the
integrator), and joint angles from qpos read one tick earlier (qpos is advanced). Telemetry reads
MjData itself rather than `sim.physics`, which the simulation no longer refreshes every tick.
"""

from __future__ import annotations

import atexit
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
from hopper.meshes import body_meshes, body_poses, terrain_mesh
from hopper.model import LEG_JOINTS

if TYPE_CHECKING:
    from hopper.sim import Event, Simulation

log = logging.getLogger(__name__)

APPLICATION_ID = "hopper"
TIME = "sim_time"
HOP = "hop"
BATCH_TICKS = 500  # ticks per send: 0.5 s of simulation, ~2 us of sending per tick amortised
POSE_EVERY_TICKS = 20  # 50 Hz body poses
RAD_S_TO_RPM = 60.0 / (2.0 * math.pi)
SIGNALS = (
    "pitch_deg",
    "pitch_rate_deg_s",
    "wheel_rpm",
    "wheel_torque_nm",
    *(f"{j}_deg" for j in LEG_JOINTS),
    *(f"{j}_torque_nm" for j in LEG_JOINTS),
    "foot_L_n",
    "foot_R_n",
)
SIGNALS_COMPONENT = "signals"
EVENT_LEVELS = {"fall": "ERROR", "error": "ERROR", "diverged": "WARN", "disturbance": "WARN"}
VIEWER_WAIT_S = 10.0  # s to wait for a viewer process to listen


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
    try:  # really open it: permission bits lie for root, read-only mounts and ACLs
        with open(p, "ab"):
            pass
    except OSError as exc:
        raise ValueError(f"cannot write recording {str(p)!r}: {exc.strerror or exc}") from None
    if not existed:
        p.unlink(missing_ok=True)
    return p


def session_path(folder: str | Path, prefix: str = "hopper") -> Path:
    """A new timestamped path `folder/prefix-YYYYmmdd-HHMMSS.rrd` (folder created, never an existing file)."""
    directory = Path(folder).expanduser()
    directory.mkdir(parents=True, exist_ok=True)
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    path = directory / f"{prefix}-{stamp}.rrd"
    n = 2
    while path.exists():
        path = directory / f"{prefix}-{stamp}-{n}.rrd"
        n += 1
    return path


# -- signals -------------------------------------------------------------------------------------
def exit_on_sigterm() -> None:
    """Make SIGTERM raise SystemExit(143) in the main thread, so `with`/`finally` close recordings.

    Python's default SIGTERM action kills the process without unwinding; Ctrl-C (SIGINT) already
    raises KeyboardInterrupt. Call from the main thread, before the simulation starts.
    """

    def handler(signum: int, frame: Any) -> None:
        raise SystemExit(128 + signum)

    signal.signal(signal.SIGTERM, handler)


@contextlib.contextmanager
def _deferred_signals() -> Iterator[None]:
    """Hold SIGINT and SIGTERM while a batch is sent or the file finalised, then re-deliver them.

    An interrupt in the middle of a send would lose or duplicate part of a batch. Only the main
    thread can install handlers; elsewhere (and under a foreign handler) this does nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    saved = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        saved[sig] = signal.signal(sig, lambda signum, frame: pending.append(signum))
    try:
        yield
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)
        for sig in pending[:1]:
            signal.raise_signal(sig)


# -- viewers -------------------------------------------------------------------------------------
def _rerun_executable() -> str:
    """The rerun CLI shipped with rerun-sdk (same version as the SDK), else one on PATH."""
    import rerun_cli

    bundled = Path(rerun_cli.__file__).parent / ("rerun.exe" if sys.platform == "win32" else "rerun")
    found = str(bundled) if bundled.exists() else shutil.which("rerun")
    if found is None:
        raise TelemetryError("the rerun CLI is not installed (it comes with the rerun-sdk package)")
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
    process.terminate()
    raise TelemetryError(f"{what} did not listen on 127.0.0.1:{port} within {VIEWER_WAIT_S:g} s")


def _has_display() -> bool:
    return sys.platform in ("darwin", "win32") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


# -- arrow columns -------------------------------------------------------------------------------
class _Column:
    """A ready-made component column for rr.send_columns (the archetype helpers cost ~100 us each)."""

    def __init__(self, descriptor: rr.ComponentDescriptor, values: pa.Array, lengths: int = 1) -> None:
        self.descriptor = descriptor
        offsets = np.arange(0, len(values) + 1, lengths, dtype=np.int32)
        self.array = pa.ListArray.from_arrays(offsets, values)

    def component_descriptor(self) -> rr.ComponentDescriptor:
        return self.descriptor

    def as_arrow_array(self) -> pa.Array:
        return self.array


def _vectors(values: np.ndarray) -> pa.Array:
    """(n, k) floats as Arrow fixed-size lists of float32, rerun's Vec3D/Quaternion layout."""
    n, k = values.shape
    flat = pa.array(np.ascontiguousarray(values, dtype=np.float32).ravel())
    return pa.FixedSizeListArray.from_arrays(flat, type=pa.list_(pa.field("item", pa.float32(), False), k))


def _durations(ns: np.ndarray) -> rr.TimeColumn:
    return rr.TimeColumn(TIME, duration=ns.astype("timedelta64[ns]"))


_TRANSLATION = rr.Transform3D.descriptor_translation()
_QUATERNION = rr.Transform3D.descriptor_quaternion()
_STRIPS = rr.LineStrips3D.descriptor_strips()
_SCALARS = rr.Scalars.descriptor_scalars()
_SIGNALS = rr.ComponentDescriptor(SIGNALS_COMPONENT)


# -- blueprint -----------------------------------------------------------------------------------
def _signal_lines(*fields: tuple[str, str, tuple[int, int, int]]) -> list[Any]:
    """One line visualizer per (struct field, legend name, colour) of the `signals` entity."""
    return [
        rr.SeriesLines(names=name, colors=[color], widths=1.5).visualizer(
            mappings=[
                VisualizerComponentMapping(
                    target=str(_SCALARS.component),
                    source_kind=ComponentSourceKind.SourceComponent,
                    source_component=SIGNALS_COMPONENT,
                    selector=f".{field}",
                )
            ]
        )
        for field, name, color in fields
    ]


def _signal_view(name: str, *fields: tuple[str, str, tuple[int, int, int]], extra: str | None = None) -> rrb.View:
    contents = ["/signals", extra] if extra else ["/signals"]
    return rrb.TimeSeriesView(
        name=name, origin="/", contents=contents, overrides={"/signals": _signal_lines(*fields)}, plot_legend=True
    )


BLUE, ORANGE, GREEN, RED, PURPLE = (31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189)


def default_blueprint() -> rrb.Blueprint:
    """3D view and hop table on the left; pitch, wheel speed, torque and phases on the right."""
    legs = [(f"{j}_deg", j, c) for j, c in zip(LEG_JOINTS, (BLUE, ORANGE, GREEN, RED), strict=True)]
    leg_torques = [(f"{j}_torque_nm", j, c) for j, c in zip(LEG_JOINTS, (BLUE, ORANGE, GREEN, RED), strict=True)]
    world = rrb.Spatial3DView(
        name="robot",
        origin="/world",
        # A side view from -y that follows the torso; the trail shows all history up to the cursor.
        eye_controls=rrb.EyeControls3D(
            position=(0.0, -4.0, 1.2),
            look_target=(0.0, 0.0, 0.6),
            eye_up=(0, 0, 1),
            tracking_entity="/world/robot/torso",
        ),
        time_ranges=rrb.VisibleTimeRange(
            TIME, start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.cursor_relative()
        ),
    )
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                world,
                rrb.Tabs(
                    rrb.DataframeView(
                        name="hop metrics", origin="/hops", query=rrb.archetypes.DataframeQuery(timeline=HOP)
                    ),
                    rrb.TextLogView(name="events", origin="/events"),
                ),
                row_shares=[3, 2],
            ),
            rrb.Vertical(
                _signal_view("pitch (deg)", ("pitch_deg", "pitch", BLUE)),
                _signal_view("wheel speed (rpm)", ("wheel_rpm", "wheel", PURPLE)),
                _signal_view("wheel torque (N m)", ("wheel_torque_nm", "torque", ORANGE), extra="/limits/wheel_torque"),
                rrb.Tabs(
                    _signal_view("pitch rate (deg/s)", ("pitch_rate_deg_s", "pitch rate", GREEN)),
                    _signal_view("leg angles (deg)", *legs),
                    _signal_view("leg torques (N m)", *leg_torques),
                    _signal_view("foot forces (N)", ("foot_L_n", "left", BLUE), ("foot_R_n", "right", RED)),
                ),
                rrb.StateTimelineView(name="phase", origin="/phase"),
                row_shares=[3, 3, 3, 3, 1],
            ),
            rrb.TextLogView(name="event log", origin="/events"),
            column_shares=[5, 5, 2],
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
    """Records one Simulation to rerun; attaches itself to `sim.listeners` until `close()`.

    tick() only appends three lists per tick (~1 us); every BATCH_TICKS the batch is converted
    with numpy and sent with rr.send_columns. Call close() (or use `with`) from the thread that
    steps the simulation, or while it is not stepping (e.g. through `sim.submit`).
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
        self.viewer_url: str | None = None  # web viewer address with viewer="serve"
        self._batch = batch_ticks
        self._lock = threading.Lock()
        self._closed = False
        self._web: subprocess.Popen[bytes] | None = None

        model, data = sim.model, sim.data
        self._data = data
        self._sensordata, self._force, self._qpos = data.sensordata, data.actuator_force, data.qpos
        self._dt_ns = round(model.opt.timestep * 1e9)
        self._meshes = body_meshes(model)
        self._layout(sim)
        self._sens_rows: list[list[float]] = []
        self._force_rows: list[list[float]] = []
        self._qpos_rows: list[list[float]] = []
        self._poses: list[tuple[int, np.ndarray, np.ndarray]] = []  # (row, xpos (n, 3), xquat wxyz (n, 4))
        self._carry_qpos = self._qpos.tolist()  # state at the next row's time (see module docstring)
        self._offset_ns = 0  # sim_time minus data.time, grows at each reset
        self._next_ns = self._data_ns()  # sim_time of the next row
        self._last_torso: np.ndarray | None = None
        self._hops = 0
        self._phase_key: object = None
        self._phase_probe = self._make_phase_probe(sim)

        self.rec = rr.RecordingStream(APPLICATION_ID, send_properties=True)
        self.rec.set_log_tick_enabled(False)  # only our two timelines
        self.rec.set_log_time_enabled(False)
        try:
            rr.set_sinks(*self._sinks(viewer), default_blueprint=default_blueprint(), recording=self.rec)
        except BaseException:
            self._stop_web()
            raise
        self.rec.send_recording_name(recording_name or f"hopper {sim.config.terrain} seed {sim.config.seed}")
        self._log_static(sim)
        self._set_time(self._next_ns)
        self._log_limits(np.array([self._next_ns]))
        self._check_phase()
        sim.listeners.append(self)
        _open.add(self)

    # -- setup -----------------------------------------------------------------------------
    def _layout(self, sim: Simulation) -> None:
        """Column indices into MjData's arrays, looked up by name so model reordering is harmless."""
        m = sim.model
        s = {name: int(m.sensor(name).adr[0]) for name in ("imu_pitch", "imu_gyro", "wheel_speed", "foot_L", "foot_R")}
        self._i_pitch, self._i_rate, self._i_wheel = s["imu_pitch"], s["imu_gyro"] + 1, s["wheel_speed"]
        self._i_feet = [s["foot_L"], s["foot_R"]]
        self._i_wheel_force = int(m.actuator("wheel").id)
        self._wheel_gear = float(m.actuator("wheel").gear[0])
        self._i_leg_force = [int(m.actuator(j).id) for j in LEG_JOINTS]
        self._i_leg_qpos = [int(m.joint(j).qposadr[0]) for j in LEG_JOINTS]
        self._i_torso = next(i for i, mesh in enumerate(self._meshes) if mesh.name == "torso")

    def _sinks(self, viewer: str) -> list[Any]:
        sinks: list[Any] = [rr.FileSink(str(self.path))] if self.path is not None else []
        exe = _rerun_executable() if viewer != "off" else ""
        if viewer == "spawn":
            if not _has_display():
                raise TelemetryError("viewer='spawn' needs a display (DISPLAY is not set); use viewer='serve'")
            port = _free_port()
            process = subprocess.Popen(
                [exe, "--bind", "127.0.0.1", "--port", str(port), "--expect-data-soon"],
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                start_new_session=True,  # the viewer outlives the run, and Ctrl-C here
            )
            _wait_for_port(port, process, "the rerun viewer")
            sinks.append(rr.GrpcSink(f"rerun+http://127.0.0.1:{port}/proxy"))
        elif viewer == "serve":
            # rr.serve_web_viewer binds 0.0.0.0; the CLI's web server takes --bind. The gRPC server
            # lives in this process (bound to loopback); the CLI only serves the viewer's assets.
            server = rr.GrpcServerSink(bind_ip="127.0.0.1", port=_free_port())
            sinks.append(server)
            web_port = _free_port()
            self._web = subprocess.Popen(
                [exe, "--serve-web", "--bind", "127.0.0.1", "--web-viewer-port", str(web_port), server.uri],
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
            _wait_for_port(web_port, self._web, "the rerun web viewer server")
            self.viewer_url = f"http://127.0.0.1:{web_port}/?url={quote(server.uri, safe='')}"
        return sinks

    def _log_static(self, sim: Simulation) -> None:
        rec = self.rec
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        terrain = terrain_mesh(sim.heights, sim.config.craters)
        rec.log("world/terrain", _mesh3d(terrain.vertices, terrain.faces, terrain.visual.vertex_colors), static=True)
        for mesh in self._meshes:
            rec.log(f"world/robot/{mesh.name}", _mesh3d(mesh.vertices, mesh.faces, mesh.colors), static=True)
        rec.log(
            "limits/wheel_torque",
            rr.SeriesLines(names=["+limit", "-limit"], colors=[RED, RED], widths=1.0),
            static=True,
        )
        c = sim.config
        rec.send_property(
            "config",
            rr.AnyValues(
                terrain=c.terrain,
                seed=c.seed,
                gravity=c.gravity,
                kp=c.gains.kp,
                ki=c.gains.ki,
                kd=c.gains.kd,
                wheel=c.wheel,
                timestep=c.timestep,
            ),
        )

    @staticmethod
    def _make_phase_probe(sim: Simulation) -> Any:
        """A cheap callable whose value changes when the phase does (sim.phase costs ~2 us)."""
        from hopper import controller

        state, slot = getattr(sim.controller, "state", None), getattr(controller, "K_PHASE", None)
        if isinstance(state, np.ndarray) and isinstance(slot, int):
            return lambda: state[slot]  # the kernel's phase slot, ~0.1 us
        return lambda: sim.phase

    # -- Listener --------------------------------------------------------------------------
    def tick(self, sim: Simulation) -> None:
        """Buffer one tick; the hot path: three tolist() and appends."""
        self._sens_rows.append(self._sensordata.tolist())
        self._force_rows.append(self._force.tolist())
        self._qpos_rows.append(self._qpos.tolist())
        if self._phase_probe() != self._phase_key:
            self._check_phase(len(self._sens_rows) - 1)
        n = len(self._sens_rows)
        if n % POSE_EVERY_TICKS == 0:
            xpos, xquat = body_poses(sim.model, self._data, self._meshes)
            self._poses.append((n - 1, xpos, xquat))
            if n >= self._batch:
                self.flush(finalize=False)

    def event(self, sim: Simulation, event: Event) -> None:
        """Log an event as text (and a hop's metrics at touchdown); a reset restarts the rows."""
        if self._closed:
            return
        if event.kind == "reset":
            self.flush(finalize=False)  # rows before the reset keep their times
            self._offset_ns = self._next_ns - self._data_ns()
            self._carry_qpos = self._qpos.tolist()
        t_ns = round(event.time * 1e9) + self._offset_ns
        hop = event.data.get("hop")
        if hop is not None:
            self._hops += 1
        self._set_time(t_ns)
        self.rec.log(
            "events",
            rr.TextLog(_describe(event), level=EVENT_LEVELS.get(event.kind, "INFO")),
            rr.AnyValues(kind=event.kind),
        )
        if hop is not None:
            for name, value in hop.as_dict().items():
                self.rec.log(f"hops/{name}", rr.Scalars(float(value)))
        if event.kind in ("reset", "liftoff", "touchdown", "fall"):
            self._check_phase(row=None, t_ns=t_ns)

    # -- phases ----------------------------------------------------------------------------
    def _check_phase(self, row: int | None = None, t_ns: int | None = None) -> None:
        key = self._phase_probe()
        if key == self._phase_key:
            return
        self._phase_key = key
        if t_ns is None:
            t_ns = self._next_ns + (row or 0) * self._dt_ns
        self._set_time(t_ns)
        self.rec.log("phase", rr.StateChange(state=self.sim.phase.label))

    # -- sending ---------------------------------------------------------------------------
    def flush(self, finalize: bool = True) -> None:
        """Send the buffered ticks now (`finalize`: also wait until the sinks have written them)."""
        with self._lock, _deferred_signals():
            if self._closed:
                return
            self._send_batch()
            if finalize:
                self.rec.flush()

    def _send_batch(self) -> None:
        sens, force, qpos, poses = self._sens_rows, self._force_rows, self._qpos_rows, self._poses
        n = min(len(sens), len(force), len(qpos))  # an interrupt may land between the appends
        if n == 0:
            return
        self._sens_rows, self._force_rows, self._qpos_rows, self._poses = [], [], [], []
        times = self._next_ns + np.arange(n, dtype=np.int64) * self._dt_ns
        self._next_ns += n * self._dt_ns
        s = np.array(sens[:n])
        f = np.array(force[:n])
        q = np.array([self._carry_qpos, *qpos[: n - 1]])
        self._carry_qpos = qpos[n - 1]
        columns = {
            "pitch_deg": np.degrees(s[:, self._i_pitch]),
            "pitch_rate_deg_s": np.degrees(s[:, self._i_rate]),
            "wheel_rpm": s[:, self._i_wheel] * RAD_S_TO_RPM,
            "wheel_torque_nm": f[:, self._i_wheel_force] * self._wheel_gear,
        }
        for j, qi, fi in zip(LEG_JOINTS, self._i_leg_qpos, self._i_leg_force, strict=True):
            columns[f"{j}_deg"] = np.degrees(q[:, qi])
            columns[f"{j}_torque_nm"] = f[:, fi]
        columns["foot_L_n"], columns["foot_R_n"] = s[:, self._i_feet[0]], s[:, self._i_feet[1]]
        struct = pa.StructArray.from_arrays(
            [pa.array(columns[name].astype(np.float32)) for name in SIGNALS], names=list(SIGNALS)
        )
        rr.send_columns("signals", [_durations(times)], [_Column(_SIGNALS, struct)], recording=self.rec)
        self._log_limits(times[[0, -1]])
        poses = [p for p in poses if p[0] < n]
        if poses:
            pose_times = _durations(times[[p[0] for p in poses]])
            xpos = np.stack([p[1] for p in poses])  # (k, bodies, 3)
            xquat = np.stack([p[2] for p in poses])[..., [1, 2, 3, 0]]  # wxyz -> rerun's xyzw
            for b, mesh in enumerate(self._meshes):
                rr.send_columns(
                    f"world/robot/{mesh.name}",
                    [pose_times],
                    [_Column(_TRANSLATION, _vectors(xpos[:, b])), _Column(_QUATERNION, _vectors(xquat[:, b]))],
                    recording=self.rec,
                )
            torso = xpos[:, self._i_torso]
            trail = torso if self._last_torso is None else np.vstack([self._last_torso, torso])
            self._last_torso = torso[-1]
            strip = pa.ListArray.from_arrays(pa.array([0, len(trail)], pa.int32()), _vectors(trail))
            rr.send_columns(
                "world/trail", [_durations(times[[poses[-1][0]]])], [_Column(_STRIPS, strip)], recording=self.rec
            )
        expected = self._data_ns() + self._offset_ns
        if expected != self._next_ns and not self._closed:
            # Steps happened without tick() (or time jumped): re-anchor rather than drift.
            log.warning("telemetry lost %d ticks; re-synchronising sim_time", (expected - self._next_ns) // self._dt_ns)
            self._next_ns = expected

    def _log_limits(self, times: np.ndarray) -> None:
        limits = np.tile([WHEEL_TORQUE_LIMIT, -WHEEL_TORQUE_LIMIT], len(times))
        rr.send_columns(
            "limits/wheel_torque",
            [_durations(times)],
            [_Column(_SCALARS, pa.array(limits), lengths=2)],
            recording=self.rec,
        )

    def _set_time(self, t_ns: int) -> None:
        self.rec.set_time(TIME, duration=np.timedelta64(t_ns, "ns"))
        self.rec.set_time(HOP, sequence=self._hops)

    def _data_ns(self) -> int:
        return round(self._data.time * 1e9)

    # -- closing ---------------------------------------------------------------------------
    def close(self) -> None:
        """Send what is buffered, finalise the file (footer) and stop viewers; idempotent."""
        with self._lock, _deferred_signals():
            if self._closed:
                return
            with contextlib.suppress(ValueError):
                self.sim.listeners.remove(self)
            try:
                self._closed = True
                self._send_batch()
                self.rec.flush()
            finally:
                self.rec.disconnect()  # writes the .rrd footer and stops the gRPC server
                self._stop_web()
                _open.discard(self)

    def _stop_web(self) -> None:
        if self._web is not None and self._web.poll() is None:
            self._web.terminate()
            try:
                self._web.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self._web.kill()
                self._web.wait()
        self._web = None

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


def _describe(event: Event) -> str:
    """One line for the event log, e.g. 'touchdown: hop 3, distance 0.95 m, peak pitch 4.2 deg'."""
    data = event.data
    if event.kind in ("touchdown", "fall") and data.get("hop") is not None:
        h = data["hop"]
        head = f"{event.kind}: hop {h.index}" + ("" if h.completed else " (fell)")
        return (
            f"{head}, distance {h.distance_m:.3f} m, apex {h.apex_height_m:.3f} m, flight {h.flight_time_s:.3f} s, "
            f"peak pitch {h.peak_pitch_deg:.2f} deg, landing {h.landing_pitch_deg:.2f} deg, "
            f"saturation {h.saturation_time_s:.3f} s, peak wheel {h.peak_wheel_rpm:.0f} rpm"
        )
    parts = [f"{k}={_fmt(v)}" for k, v in data.items() if k != "hop"]
    return f"{event.kind}: {', '.join(parts)}" if parts else event.kind


def _fmt(value: object) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)
