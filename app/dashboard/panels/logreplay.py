"""Log replay panel: load a recorded log, fly its hops open loop in the log's world (hopper.logs.replay; the
dashboard's terrain, seed and gravity for a log that names none),
and show the log's robot and the simulated one as two ghosts side by side, in step, with the errors charted.
While the ghosts are watched, the ground under them is the log's world's, in place of the live one.

A load runs on a thread of its own (never the 1 kHz loop's, never viser's): the simulation keeps running,
and a bad path or a log that cannot be replayed is a notification to the one who asked.
"""

from __future__ import annotations

import dataclasses
import html
import logging
import math
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import numpy as np
import viser
from hopper.app.dashboard.feedback import guarded, notify
from hopper.app.dashboard.plots import LogReplayPlots
from hopper.app.dashboard.scene import GhostRobot
from hopper.app.dashboard.terrain_view import LogGround, TerrainView, ground_glbs

from hopper.config import SimConfig
from hopper.errors import HopperError
from hopper.logs import gaps
from hopper.logs.io import read_log
from hopper.logs.replay import (
    HELD,
    REANCHOR_S,
    Errors,
    Trajectory,
    check_replayable,
    contact,
    hops,
    poses,
    replay_hops,
    world_model,
)
from hopper.logs.schema import Log
from hopper.logs.world import World, of_config, resolve

if TYPE_CHECKING:
    from hopper.sim import Simulation

log = logging.getLogger(__name__)

MAX_HOPS = 20  # replayed at most (the first ones): a long log would keep a core busy for minutes
GHOST_FRAME_S = 0.01  # s of log time between the ghosts' poses (100 Hz, as the re-fly's ghost)
LOGGED_GHOST = (255, 176, 59)  # orange, as the charts' "log" lines
SIMULATED_GHOST = (90, 169, 255)  # blue, as the charts' "sim" lines
BESIDE_M = 0.5  # m: the log's ghost stands this far behind the simulated one (y), so that both show


class LogReplayHost(Protocol):
    sim: Simulation  # its config is the world the log is replayed in when the log names none
    terrain: TerrainView  # the live ground, hidden while the log's is shown


@dataclasses.dataclass(frozen=True)
class LogReplay:
    """A log's hops replayed: the parts (hopper.logs.replay.replay_hops), both robots' poses, the charts' series."""

    source: str
    world: str  # where it was replayed, and why there
    found: int  # hops in the log
    shown: int  # hops replayed
    every: float | None  # s: each hop re-anchored on the log's state this often (None: whole)
    servo: bool  # the legs held to the log's angles (hopper.logs.replay.simulate)
    parts: list[tuple[Trajectory, Errors]]  # a replay each hop, or each window of one
    logged: np.ndarray  # qpos rows every `frame_s` of log time
    simulated: np.ndarray  # likewise
    frame_s: float  # s
    logged_on: np.ndarray  # either foot down, per sample
    simulated_on: np.ndarray
    track: np.ndarray  # (frames, 2): the log's torso CoM x, z (m) at each ghost pose, for the camera
    ground: dict[int, bytes]  # the log's world's terrain tiles under the track: index -> GLB
    notes: tuple[str, ...] = ()  # a line for each hop that holds a gap (hopper.logs.gaps.note)

    @property
    def errors(self) -> Errors:
        return Errors.concat([e for _, e in self.parts])


def world_for(recorded: Log, config: SimConfig) -> tuple[World, str]:
    """The log's world (its ground and gravity) with the dashboard's robot; the dashboard's whole world
    for a log that names none (a real robot's). With a line saying which."""
    if recorded.world is not None:
        return resolve(recorded.world, model=config.model)
    # A real robot's delay is not this dashboard's sensing mode's: the default is assumed.
    return dataclasses.replace(of_config(config), delay_ticks=None), "the log names none: this dashboard's"


def replay_log(path: str, config: SimConfig, every: float | None = None, servo: bool = False) -> LogReplay:
    """Read the log at `path` and replay its first MAX_HOPS hops in its world (world_for), whole or
    re-anchored on the log's state every `every` s, the legs held to its angles with `servo`;
    HopperError if it cannot."""
    recorded = read_log(path)
    check_replayable(recorded)  # before the hops: a log without the state says so, not 'no hop'
    world, origin = world_for(recorded, config)
    model, window = world_model(world)
    found = len(hops(recorded))
    parts = replay_hops(
        model, recorded, MAX_HOPS, window=window, delay_ticks=world.command_delay, every=every, servo=servo,
        drive=world.drive,
    )  # fmt: skip
    notes = [gaps.note(recorded, f"hop {i + 1}", hop, every is None) for i, hop in enumerate(hops(recorded)[:MAX_HOPS])]
    skipped = sum(1 for n in notes if n is not None) if every is None else 0  # a whole hop across a gap is left out
    first = parts[0][0]
    # The rows replayed, in order: all from the first liftoff, less what a gap left out (hopper.logs.gaps).
    rows = np.concatenate([np.arange(tr.first, tr.first + len(tr.time)) for tr, _ in parts])
    s = recorded.signals
    simulated = {k: np.concatenate([tr.signals[k] for tr, _ in parts]) for k in first.signals}
    stride = max(1, round(GHOST_FRAME_S / recorded.period))  # log rows a ghost frame
    return LogReplay(
        source=str(path),
        world=f"{world.describe()} ({origin})",
        found=found,
        shown=min(found, MAX_HOPS) - skipped,
        every=every,
        servo=servo,
        parts=parts,
        logged=poses(model, {k: v[rows] for k, v in s.items()}, stride),
        simulated=poses(model, simulated, stride),
        frame_s=stride * recorded.period,
        logged_on=contact(s["foot_L_force"][rows], s["foot_R_force"][rows]),
        simulated_on=contact(simulated["foot_L_force"], simulated["foot_R_force"]),
        track=np.column_stack([s["x"][rows][::stride], s["z"][rows][::stride]]),
        ground=ground_glbs(window.field, float(s["x"][rows].min()), float(s["x"][rows].max())),
        notes=tuple(n for n in notes if n is not None),
    )


def summary_html(done: LogReplay | None) -> str:
    if done is None:
        return (
            "<div class='hd-record'>Replays a log's hops open loop in the log's world (this one's terrain, seed "
            "and gravity if the log names none): "
            "<b style='color:#ffb03b'>orange</b> ghost the log, <b style='color:#5aa9ff'>blue</b> the simulation. "
            "Errors chart on the left.</div>"
        )
    e = done.errors
    timing = e.timing()
    rms_pitch, rms_wheel = math.degrees(e.rms("pitch")), e.rms("wheel_speed")
    shown = done.shown
    of = f"{shown} of {done.found} hops" if shown < done.found else f"{shown} hop(s)"
    of += "" if done.every is None else f" re-anchored every {done.every:g} s"
    of += f", {HELD}" if done.servo else ""
    return (
        f"<div class='hd-record'><b>{html.escape(done.source)}</b>: {of}, {e.time[0]:.2f}–{e.time[-1]:.2f} s · "
        f"pitch RMS {rms_pitch:.3f}° · wheel speed RMS {rms_wheel:.3f} rad/s · {timing} · "
        f"in {html.escape(done.world)}. "
        "<b style='color:#ffb03b'>Orange</b>: the log; <b style='color:#5aa9ff'>blue</b>: simulated."
        + "".join(f"<br>{html.escape(n)}" for n in done.notes)
        + "</div>"
    )


@dataclasses.dataclass
class LogReplayPanel:
    host: LogReplayHost
    path: viser.GuiTextHandle
    load: viser.GuiButtonHandle
    watch: viser.GuiCheckboxHandle
    reanchor: viser.GuiCheckboxHandle
    servo: viser.GuiCheckboxHandle
    stop_button: viser.GuiButtonHandle
    summary: viser.GuiHtmlHandle
    logged_ghost: GhostRobot
    simulated_ghost: GhostRobot
    ground: LogGround
    plots: LogReplayPlots | None = None  # set once the left panel exists
    last: LogReplay | None = None
    finished: int = 0  # loads ended (replayed or refused), for tests to wait on
    grounded: LogReplay | None = None  # the replay whose ground is drawn (the loop thread's)
    _lock: threading.Lock = dataclasses.field(default_factory=threading.Lock, repr=False)

    def request(self, text: str, client: viser.ClientHandle | None) -> threading.Thread | None:
        """Load and replay the log at `text` on a thread of its own; None (and a notice) while one runs."""
        path = str(Path(text.strip()).expanduser()) if text.strip() else ""
        if not path:
            notify(client, "No log", "Type the path of a log (.csv, .npz, .mcap, .rrd) first.", "warning")
            self.finished += 1
            return None
        # A second load while one runs is refused (the button is not greyed: Roles owns each client's greying).
        if not self._lock.acquire(blocking=False):
            notify(client, "Replay running", "A log is being replayed: wait for it to finish.", "warning")
            return None
        worker = threading.Thread(target=self._run, args=(path, client), name="log-replay", daemon=True)
        worker.start()
        return worker

    def _run(self, path: str, client: viser.ClientHandle | None) -> None:
        try:
            every = REANCHOR_S if self.reanchor.value else None
            done = replay_log(path, self.host.sim.config, every, self.servo.value)
            self.show(done)
            notify(client, "Log replayed", f"{path}: {done.shown} hop(s)")
        except HopperError as exc:
            notify(client, "Log not replayed", str(exc), "error")
        except Exception as exc:  # a reader's own failure on a corrupt file: said, never raised into the thread
            log.exception("log replay of %s failed", path)
            notify(client, "Log not replayed", f"{path}: {type(exc).__name__}: {exc}", "error")
        finally:
            self.finished += 1
            self._lock.release()

    def show(self, done: LogReplay) -> None:
        now = time.perf_counter()  # both from the same moment, the same length: they play in step
        self.logged_ghost.play(done.logged, done.frame_s, now)
        self.simulated_ghost.play(done.simulated, done.frame_s, now)
        if self.plots is not None:
            e = done.errors
            self.plots.show(e.time, e.pitch, e.wheel_speed, done.logged_on, done.simulated_on)
        self.summary.content = summary_html(done)
        self.last = done
        self.watch.value = True  # the ghosts play where the log was recorded: show them there

    def watched(self) -> tuple[float, float] | None:
        """Where the camera should look (m: the log's torso x, z now) while the ghosts are watched, else None."""
        done, frame = self.last, self.logged_ghost.shown_frame
        if done is None or not self.watch.value or not self.logged_ghost.playing or frame < 0:
            return None
        return float(done.track[frame, 0]), float(done.track[frame, 1])

    def stop(self) -> None:
        """Hide both ghosts; the camera goes back to the live robot."""
        self.watch.value = False
        self.logged_ghost.hide()
        self.simulated_ghost.hide()

    def update(self, now: float) -> None:
        """Send both ghosts' poses due at wall time `now` (the loop calls it inside server.atomic()), and
        the log's ground in place of the live one while they are watched (the live one back after)."""
        watched = self.last if self.watch.value else None
        if watched is not self.grounded:
            if watched is None:
                self.ground.hide()
            else:
                self.ground.show(watched.ground)
            self.host.terrain.hide(watched is not None)
            self.grounded = watched
        self.logged_ghost.update(now)
        self.simulated_ghost.update(now)


def build_logreplay_panel(gui: viser.GuiApi, scene: viser.SceneApi, host: LogReplayHost) -> LogReplayPanel:
    model = host.sim.model
    logged = GhostRobot(scene, model, name="log_ghost", color=LOGGED_GHOST, offset=(0.0, BESIDE_M, 0.0))
    simulated = GhostRobot(scene, model, name="sim_ghost", color=SIMULATED_GHOST)
    with gui.add_folder("Replay a log"):
        path = gui.add_text("Log path", "", hint="A hopper log on the server: .csv, .npz, .mcap or .rrd")
        load = gui.add_button(
            "Load and replay log",
            icon=viser.Icon.FILE_IMPORT,
            hint="Fly the log's commands open loop from its state at each liftoff, on the log's ground "
            "(this one's if it names none)",
        )
        reanchor = gui.add_checkbox(
            f"Re-anchor every {REANCHOR_S:g} s",
            False,
            hint="Start the simulated robot again from the log's state every "
            f"{REANCHOR_S:g} s: a whole open-loop stance drifts off with any model error",
        )
        servo = gui.add_checkbox(
            "Legs held to the log",
            False,
            hint="A servo holds the legs to the log's joint angles around its torques: a whole hop then "
            "measures the torso and the wheel, not the open-loop stance's chaos",
        )
        watch = gui.add_checkbox(
            "Camera on the ghosts", False, hint="Follow the replayed log's ghosts; untick to follow the live robot"
        )
        stop_button = gui.add_button("Stop log replay", icon=viser.Icon.PLAYER_STOP, color="gray")
        summary = gui.add_html(summary_html(None))
    panel = LogReplayPanel(
        host, path, load, watch, reanchor, servo, stop_button, summary, logged, simulated, LogGround(scene)
    )  # fmt: skip
    stop_button.on_click(guarded(lambda _: panel.stop()))
    load.on_click(guarded(lambda event: panel.request(path.value, event.client)))
    return panel
