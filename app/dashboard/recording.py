"""Start and stop rerun recordings of the running simulation (hopper.telemetry), from any thread."""

from __future__ import annotations

import dataclasses
import logging
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

from hopper.app.recordings import FileLimits, open_recording

from hopper.events import Recording as RecordingEvent
from hopper.sim import Command, Simulation

log = logging.getLogger(__name__)

Viewer = Literal["spawn", "serve", "off"]


def telemetry_module() -> Any:
    """hopper.telemetry, or a clear ValueError if it is not there yet."""
    try:
        from hopper import telemetry
    except ImportError as exc:
        raise ValueError(f"recording needs hopper.telemetry, which is not available ({exc})") from None
    return telemetry


@dataclasses.dataclass(frozen=True)
class AttachRecording:
    """Command: start recording the simulation (on the loop thread, between steps)."""

    recorder: Recorder
    path: Path | None
    viewer: Viewer = "off"
    name: str | None = None

    def apply(self, sim: Simulation) -> None:
        self.recorder.attach(sim, self.path, self.viewer, self.name)


@dataclasses.dataclass(frozen=True)
class DetachRecording:
    """Command: stop the recording and finalise its file (on the loop thread)."""

    recorder: Recorder

    def apply(self, sim: Simulation) -> None:
        self.recorder.detach(sim)


class Recorder:
    """At most one Telemetry listener on the simulation; attached and detached by queued commands.

    Listeners are called as `changed(state, path, message)` with state "recording", "saved" or
    "failed"; every change is also a Recording event in the simulation's log (and recordings).
    "behind" (message: why) says the file fell behind what the recording sends (a slow disk), and
    "recording" again once it has caught up.
    """

    def __init__(self, submit: Callable[[Command], None], sessions_dir: Path, limits: FileLimits | None = None) -> None:
        self._submit = submit
        self.sessions_dir = sessions_dir
        self.limits = limits or FileLimits()
        self._lock = threading.Lock()
        self._telemetry: Any = None
        self._pending = False
        self.path: Path | None = None
        self.viewer_url: str | None = None  # a web viewer's address, with viewer="serve"
        self.listeners: list[Callable[[str, Path | None, str], None]] = []

    @property
    def active(self) -> bool:
        return self._telemetry is not None or self._pending

    def progress(self) -> tuple[Path | None, int, int]:
        """(file being written, its bytes on disk, parts so far); read on the simulation's thread."""
        telemetry = self._telemetry
        if telemetry is None:
            return self.path, 0, 0
        return telemetry.path, telemetry.written, len(telemetry.parts)

    def _changed(self, sim: Simulation, state: str, message: str = "") -> None:
        where = str(self.path) if self.path is not None else None
        sim.emit(RecordingEvent({"recording": "started", "saved": "stopped"}.get(state, "failed"), where, message))
        self._tell(state, message)

    def _tell(self, state: str, message: str) -> None:
        for listener in self.listeners:
            try:
                listener(state, self.path, message)
            except Exception:
                log.exception("recording listener failed")

    def start(self, path: Path | None = None, viewer: Viewer = "off", name: str | None = None) -> Path | None:
        """Queue a recording to `path` (default: a timestamped file in sessions_dir); ValueError if it cannot."""
        telemetry = telemetry_module()
        with self._lock:
            if self.active:
                raise ValueError(f"already recording to {self.path}")
            if path is None and viewer == "off":
                path = Path(telemetry.session_path(self.sessions_dir))
            if path is not None:
                path = Path(telemetry.check_writable(path))
            self._pending, self.path = True, path
        self._submit(AttachRecording(self, path, viewer, name))
        return path

    def attach(self, sim: Simulation, path: Path | None, viewer: Viewer = "off", name: str | None = None) -> None:
        """Start recording now; on the loop thread (AttachRecording) or before the loop starts."""
        try:
            mine: list[Any] = []  # this recording, for callbacks that may come after a newer one started
            recording, url = open_recording(
                sim,
                path,
                viewer,
                self.limits,
                name,
                on_part=lambda finished, started: self._next_part(sim, finished, started),
                on_stop=lambda message: self._stopped(sim, mine, message),
                on_lag=lambda message: self._lagging(mine, message),
            )
        except Exception as exc:
            self._changed(sim, "failed", f"{type(exc).__name__}: {exc}")
            raise  # the simulation logs it as a failed command
        finally:
            self._pending = False
        mine.append(recording)
        self._telemetry = recording
        self.viewer_url = url
        self.path = recording.path
        self._changed(sim, "recording")

    def _next_part(self, sim: Simulation, finished: Path, started: Path) -> None:
        """A rollover (on the loop thread): the finished part is saved, the next one recording."""
        sim.emit(RecordingEvent("stopped", str(finished)))
        self.path = started
        self._changed(sim, "recording")

    def _stopped(self, sim: Simulation, mine: list[Any], message: str) -> None:
        """The recording stopped by itself (a full disk; on the loop thread): say so, keep the path."""
        if not mine or mine[0] is not self._telemetry:
            return
        self._telemetry = None
        self._changed(sim, "failed", message)

    def _lagging(self, mine: list[Any], message: str | None) -> None:
        """The file fell behind (a slow disk) or caught up, from the recording's watchdog thread:
        "behind" or "recording" to the listeners (no event: the recording itself goes on)."""
        if mine and mine[0] is self._telemetry:
            self._tell("behind" if message is not None else "recording", message or "")

    def start_now(self, sim: Simulation, path: Path | None, viewer: Viewer = "off", name: str | None = None) -> None:
        """Attach at once, raising on failure; only while the simulation loop is not running (startup)."""
        telemetry = telemetry_module()
        with self._lock:
            if self.active:
                raise ValueError(f"already recording to {self.path}")
            self.path = Path(telemetry.check_writable(path)) if path is not None else None
        self.attach(sim, self.path, viewer, name)

    def stop(self) -> None:
        """Queue closing the recording: Telemetry.close() runs on the simulation thread, as it asks."""
        self._submit(DetachRecording(self))

    def detach(self, sim: Simulation) -> None:
        """Detach and finalise now; on the loop thread, or while it is not running (shutdown)."""
        telemetry, self._telemetry = self._telemetry, None
        if telemetry is None:
            return
        if telemetry in sim.listeners:
            sim.listeners.remove(telemetry)
        try:
            telemetry.close()  # flushes and writes the footer: a short stall the pacer catches up
        except Exception as exc:
            log.exception("closing the recording failed")
            self._changed(sim, "failed", f"{type(exc).__name__}: {exc}")
            return
        self._changed(sim, "saved")

    def close_now(self, sim: Simulation) -> None:
        """Detach and finalise at once; only while the simulation loop is not running (shutdown)."""
        self.detach(sim)
