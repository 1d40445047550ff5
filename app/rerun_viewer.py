"""Live rerun viewers for a recording: a native viewer window (spawn) or the web viewer on loopback (serve)."""

from __future__ import annotations

import contextlib
import dataclasses
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Literal
from urllib.parse import quote

import rerun as rr

from hopper.errors import HopperError

ViewerKind = Literal["spawn", "serve", "off"]
VIEWER_WAIT_S = 10.0  # s for a viewer process to start listening
VIEWER_GRACE_S = 1.5  # s a spawned viewer must then stay alive (no display: it exits within ~0.5 s)
STOP_WAIT_S = 5.0  # s the web viewer server gets to exit on SIGTERM before SIGKILL


class ViewerError(HopperError, RuntimeError):
    """A viewer could not be started or reached."""


@dataclasses.dataclass
class Viewer:
    """Where a recording also streams to: pass `sinks` to Telemetry, show `url`, `close()` after it.

    A spawned viewer window outlives the run (the user closes it); a served web viewer's file
    server is this object's process and stops on close(). The gRPC server of `serve` is a sink
    of the recording and stops when the recording closes.
    """

    sinks: tuple[rr.GrpcSink | rr.GrpcServerSink, ...] = ()
    url: str | None = None  # the web viewer's address (serve), on 127.0.0.1
    process: subprocess.Popen[bytes] | None = None  # the web viewer's file server (serve)

    def close(self) -> None:
        """Stop the web viewer's file server, if any; idempotent."""
        process, self.process = self.process, None
        if process is None or process.poll() is not None:
            return
        _signal_group(process, signal.SIGTERM)
        try:
            process.wait(timeout=STOP_WAIT_S)
        except subprocess.TimeoutExpired:
            _signal_group(process, signal.SIGKILL if hasattr(signal, "SIGKILL") else signal.SIGTERM)
            process.wait()


def open_viewer(kind: ViewerKind) -> Viewer:
    """Start a viewer of `kind` ("off": none, no sinks); ViewerError with a one-line reason if it cannot."""
    if kind == "off":
        return Viewer()
    if kind == "spawn":
        return _spawn()
    if kind == "serve":
        return _serve()
    raise ValueError(f"rerun viewer must be 'spawn', 'serve' or 'off', got {kind!r}")


def _spawn() -> Viewer:
    if not has_display():
        raise ViewerError("spawning a rerun viewer needs a display (DISPLAY is not set); use serve for the web viewer")
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
        raise ViewerError(f"the rerun viewer exited with code {process.returncode}: no usable display?")
    return Viewer(sinks=(rr.GrpcSink(f"rerun+http://127.0.0.1:{port}/proxy"),))


def _serve() -> Viewer:
    # rr.serve_web_viewer binds 0.0.0.0, the CLI's web server takes --bind: the gRPC server lives
    # in this process on loopback (a sink of the recording), the CLI only serves the viewer's files.
    server = rr.GrpcServerSink(bind_ip="127.0.0.1", port=_free_port())
    web_port = _free_port()
    process = subprocess.Popen(
        [_rerun_executable(), "--serve-web", "--bind", "127.0.0.1", "--web-viewer-port", str(web_port), server.uri],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # its own process group: a wrapper script's child dies with it
    )
    url = f"http://127.0.0.1:{web_port}/?url={quote(server.uri, safe='')}"
    viewer = Viewer(sinks=(server,), url=url, process=process)
    try:
        _wait_for_port(web_port, process, "the rerun web viewer server")
    except BaseException:
        viewer.close()
        raise
    return viewer


def has_display() -> bool:
    """Whether a native window can open: macOS and Windows always, elsewhere X11 or Wayland."""
    return sys.platform in ("darwin", "win32") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _rerun_executable() -> str:
    """The rerun CLI shipped with rerun-sdk (the SDK's own version), else one on PATH."""
    import rerun_cli

    bundled = Path(rerun_cli.__file__).parent / ("rerun.exe" if sys.platform == "win32" else "rerun")
    found = str(bundled) if bundled.exists() else shutil.which("rerun")
    if found is None:
        raise ViewerError("the rerun CLI is missing (it comes with the rerun-sdk package)")
    return found


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _wait_for_port(port: int, process: subprocess.Popen[bytes], what: str) -> None:
    """Return once `process` listens on 127.0.0.1:`port`; else ViewerError (a process still running is stopped)."""
    deadline = time.monotonic() + VIEWER_WAIT_S
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise ViewerError(f"{what} exited with code {process.returncode} before listening on port {port}")
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.05)
    _signal_group(process, signal.SIGTERM)
    process.wait()
    raise ViewerError(f"{what} did not listen on 127.0.0.1:{port} within {VIEWER_WAIT_S:g} s")


def _signal_group(process: subprocess.Popen[bytes], signum: int) -> None:
    """Signal the process group we started it in (it is its leader), or just the process."""
    if hasattr(os, "killpg"):
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signum)
    else:
        process.send_signal(signum)
