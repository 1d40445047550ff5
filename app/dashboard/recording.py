"""Start and stop rerun recordings of the running simulation (hopper.telemetry), from any thread."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

from hopper.sim import Simulation

log = logging.getLogger(__name__)

Viewer = Literal["spawn", "serve", "off"]


def telemetry_module() -> Any:
    """hopper.telemetry, or a clear ValueError if it is not there yet."""
    try:
        from hopper import telemetry
    except ImportError as exc:
        raise ValueError(f"recording needs hopper.telemetry, which is not available ({exc})") from None
    return telemetry


class Recorder:
    """At most one Telemetry listener on the simulation; attached and detached by queued commands.

    `changed(state, path, message)` is called with state "recording", "saved" or "failed".
    """

    def __init__(self, submit: Callable[[Callable[[Simulation], None]], None], sessions_dir: Path) -> None:
        self._submit = submit
        self.sessions_dir = sessions_dir
        self._lock = threading.Lock()
        self._telemetry: Any = None
        self._pending = False
        self.path: Path | None = None
        self.viewer_url: str | None = None  # a web viewer's address, with viewer="serve"
        self.listeners: list[Callable[[str, Path | None, str], None]] = []

    @property
    def active(self) -> bool:
        return self._telemetry is not None or self._pending

    def _changed(self, state: str, message: str = "") -> None:
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

        def attach(sim: Simulation) -> None:
            try:
                self._attach(sim, telemetry, path, viewer, name)
            except Exception as exc:
                self._changed("failed", f"{type(exc).__name__}: {exc}")
                raise  # the simulation logs it and emits an "error" event
            finally:
                self._pending = False
            self._changed("recording")

        self._submit(attach)
        return path

    def _attach(self, sim: Simulation, telemetry: Any, path: Path | None, viewer: Viewer, name: str | None) -> None:
        recording = telemetry.Telemetry(sim, path=path, viewer=viewer, recording_name=name)
        if recording not in sim.listeners:  # Telemetry attaches itself; older versions did not
            sim.listeners.append(recording)
        self._telemetry = recording
        self.viewer_url = getattr(recording, "viewer_url", None)

    def start_now(self, sim: Simulation, path: Path | None, viewer: Viewer = "off", name: str | None = None) -> None:
        """Attach at once, raising on failure; only while the simulation loop is not running (startup)."""
        telemetry = telemetry_module()
        with self._lock:
            if self.active:
                raise ValueError(f"already recording to {self.path}")
            self.path = Path(telemetry.check_writable(path)) if path is not None else None
        self._attach(sim, telemetry, self.path, viewer, name)
        self._changed("recording")

    def stop(self) -> None:
        """Queue closing the recording: Telemetry.close() runs on the simulation thread, as it asks."""

        def detach(sim: Simulation) -> None:
            telemetry, self._telemetry = self._telemetry, None
            if telemetry is None:
                return
            if telemetry in sim.listeners:
                sim.listeners.remove(telemetry)
            self._close(telemetry)  # flushes and writes the footer: a short stall the pacer catches up

        self._submit(detach)

    def _close(self, telemetry: Any) -> None:
        try:
            telemetry.close()
        except Exception as exc:
            log.exception("closing the recording failed")
            self._changed("failed", f"{type(exc).__name__}: {exc}")
            return
        self._changed("saved")

    def close_now(self, sim: Simulation) -> None:
        """Detach and finalize at once; only while the simulation loop is not running (shutdown)."""
        telemetry, self._telemetry = self._telemetry, None
        if telemetry is None:
            return
        if telemetry in sim.listeners:
            sim.listeners.remove(telemetry)
        self._close(telemetry)
