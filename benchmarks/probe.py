"""A headless viser client for tests and benchmarks: the browser's handshake and wire format, no DOM.

It connects with the `viser-v<version>` subprotocol, reports a camera (the server only registers a
client after its first camera message), and decodes every frame the server sends: 16-byte header,
zstd-compressed msgpack, then raw binary buffers.
"""

from __future__ import annotations

import collections
import threading
import time
from typing import Any

import msgspec
import viser
import websockets.sync.client as ws_client
import zstandard

TORSO = "/world/robot/torso"  # the scene node whose pose updates count as a frame


class ProbeClient:
    """Receives the full stream on a thread; counts bytes and messages by type."""

    def __init__(self, url: str, *, open_timeout: float = 10.0) -> None:
        ws_url = url.replace("http://", "ws://", 1)
        self._socket = ws_client.connect(
            ws_url,
            subprotocols=[f"viser-v{viser.__version__}"],  # type: ignore[list-item]
            open_timeout=open_timeout,
            max_size=None,
            compression=None,
        )
        self._decompressor = zstandard.ZstdDecompressor()
        self._lock = threading.Lock()
        self.bytes = 0
        self.frames = 0  # websocket messages (windows of viser messages)
        self.counts: collections.Counter[str] = collections.Counter()
        self.pose_frames = 0  # windows that moved the robot
        self.notifications: list[dict[str, Any]] = []
        self.gui: dict[str, dict[str, Any]] = {}  # uuid -> creation message
        self.closed = False
        self._thread = threading.Thread(target=self._receive, name="probe", daemon=True)
        self._thread.start()
        self.send_camera()

    def send(self, message: dict[str, Any]) -> None:
        self._socket.send(msgspec.msgpack.encode(message))

    def send_camera(self) -> None:
        """Report a side-view camera, as a browser does on connect."""
        self.send(
            {
                "type": "ViewerCameraMessage",
                "wxyz": [0.7071, 0.7071, 0.0, 0.0],
                "position": [0.0, -4.0, 1.0],
                "fov": 0.785,
                "near": 0.01,
                "far": 1000.0,
                "image_height": 800,
                "image_width": 1280,
                "look_at": [0.0, 0.0, 1.0],
                "up_direction": [0.0, 0.0, 1.0],
            }
        )

    def set_gui_value(self, label: str, value: Any) -> str:
        """Send a value for the GUI input with this label, as the browser would; returns its uuid."""
        uuid = self.uuid_of(label)
        self.send({"type": "GuiUpdateMessage", "uuid": uuid, "updates": {"value": value}})
        return uuid

    def uuid_of(self, label: str) -> str:
        with self._lock:
            for uuid, message in self.gui.items():
                if message.get("props", {}).get("label") == label:
                    return uuid
        raise KeyError(f"no GUI input labelled {label!r} seen yet")

    def wait_for(self, predicate: Any, timeout: float = 10.0) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self._lock:
                if predicate(self):
                    return True
            time.sleep(0.05)
        return False

    def snapshot(self) -> tuple[int, int, int]:
        """(bytes, frames, pose frames) so far."""
        with self._lock:
            return self.bytes, self.frames, self.pose_frames

    def close(self) -> None:
        self.closed = True
        self._socket.close()
        self._thread.join(timeout=5.0)

    def _receive(self) -> None:
        try:
            for raw in self._socket:
                if isinstance(raw, str):
                    continue
                self._decode(raw)
        except Exception:  # connection closed or server stopped
            pass
        finally:
            self.closed = True

    def _decode(self, raw: bytes) -> None:
        size = int.from_bytes(raw[0:8], "little")
        compressed = int.from_bytes(raw[8:16], "little")
        payload = self._decompressor.decompress(raw[16 : 16 + compressed], max_output_size=size)
        messages = msgspec.msgpack.decode(payload)["messages"]
        with self._lock:
            self.bytes += len(raw)
            self.frames += 1
            moved = False
            for message in messages:
                kind = message.get("type", "?")
                self.counts[kind] += 1
                if kind == "SetPositionMessage" and message.get("name") == TORSO:
                    moved = True
                elif kind == "NotificationShowMessage":
                    self.notifications.append(message.get("props", {}))
                elif "uuid" in message and "props" in message and kind.startswith("Gui"):
                    self.gui[message["uuid"]] = message
            self.pose_frames += moved
