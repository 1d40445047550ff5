"""A headless client of a running dashboard: the browser's handshake and wire format, no DOM.

What the tests and benchmarks/ watch a session with, and what measures a stream's bytes per client
(bench_dashboard) without a browser.

It connects with the `viser-v<version>` subprotocol, reports a camera (the server only registers a
client after its first camera message), and decodes every frame the server sends: 16-byte header,
zstd-compressed msgpack, then raw binary buffers. It also splits the bytes it receives into charts,
poses and other (see `Traffic`), and counts scene updates and chart refreshes.
"""

from __future__ import annotations

import collections
import dataclasses
import importlib.metadata
import threading
import time
from typing import Any

import msgspec
import numpy as np
import websockets.sync.client as ws_client
import zstandard
from hopper.app.dashboard.chart_feed import apply_push, decode_push
from hopper.app.dashboard.scene import AMBIENT

ROBOT = "/world/robot"  # scene nodes under this prefix are the robot: a frame that moves one is a scene update
TERRAIN = "/world/terrain"  # the terrain's tiles: sent as the simulation's window reaches them (terrain_view)
TRAIL = "/world/trail"  # the torso's trail: line segments, counted as "other" with their creation messages
POSE_MESSAGES = frozenset(
    {"SetPositionMessage", "SetOrientationMessage", "SetBonePositionMessage", "SetBoneOrientationMessage"}
)
POSE_PROPS = frozenset({"batched_positions", "batched_wxyzs"})  # batched nodes' transforms (SceneNodeUpdateMessage)
CATEGORIES = ("charts", "poses", "terrain", "other")


def is_pose(message: dict[str, Any]) -> bool:
    """A message that only moves scene nodes (not the trail's, which come with its re-sent segments)."""
    kind, name = message.get("type"), str(message.get("name", ""))
    if name.startswith(TRAIL):
        return False
    if kind in POSE_MESSAGES:
        return True
    return kind == "SceneNodeUpdateMessage" and bool(message["updates"]) and set(message["updates"]) <= POSE_PROPS


def _binary_indices(value: Any, out: list[int]) -> list[int]:
    """Indices of the binary buffers a decoded message refers to (viser's tagged placeholders)."""
    if isinstance(value, dict):
        if "__binary_index" in value and "dtype" in value:
            out.append(value["__binary_index"])
        else:
            for v in value.values():
                _binary_indices(v, out)
    elif isinstance(value, list):
        for v in value:
            _binary_indices(v, out)
    return out


@dataclasses.dataclass
class Traffic:
    """What one client received: bytes on the wire by category, scene updates and chart refreshes.

    Bytes are the websocket payloads' sizes. A frame's binary buffers go to the message that holds
    them; its header and compressed msgpack are shared between the categories present in proportion
    to what each category's messages compress to alone (zstd level 1, as the server uses).
    """

    bytes: dict[str, float] = dataclasses.field(default_factory=lambda: dict.fromkeys(CATEGORIES, 0.0))
    messages: dict[str, int] = dataclasses.field(default_factory=lambda: dict.fromkeys(CATEGORIES, 0))
    scene_updates: int = 0  # frames that moved the robot
    chart_refreshes: dict[str, int] = dataclasses.field(default_factory=dict)  # uPlot uuid -> data updates or pushes

    def copy(self) -> Traffic:
        return Traffic(dict(self.bytes), dict(self.messages), self.scene_updates, dict(self.chart_refreshes))

    def minus(self, earlier: Traffic) -> Traffic:
        """The traffic since `earlier` (a copy taken before)."""
        return Traffic(
            {k: v - earlier.bytes[k] for k, v in self.bytes.items()},
            {k: v - earlier.messages[k] for k, v in self.messages.items()},
            self.scene_updates - earlier.scene_updates,
            {k: v - earlier.chart_refreshes.get(k, 0) for k, v in self.chart_refreshes.items()},
        )


class ProbeClient:
    """Receives the full stream on a thread; counts bytes and messages by type."""

    def __init__(self, url: str, *, open_timeout: float = 10.0) -> None:
        ws_url = url.replace("http://", "ws://", 1)
        self._socket = ws_client.connect(
            ws_url,
            subprotocols=[f"viser-v{importlib.metadata.version('viser')}"],  # type: ignore[list-item]
            open_timeout=open_timeout,
            max_size=None,
            compression=None,
        )
        self._decompressor = zstandard.ZstdDecompressor()
        self._compressor = zstandard.ZstdCompressor(level=1)
        self._lock = threading.RLock()  # re-entered: wait_for predicates may call the locking readers
        self.bytes = 0
        self.frames = 0  # websocket messages (windows of viser messages)
        self.counts: collections.Counter[str] = collections.Counter()
        self.pose_frames = 0  # windows that moved the robot
        self.traffic = Traffic()
        self.uplots: set[str] = set()  # uuids of the uPlot charts
        self.last_pose_frame: list[dict[str, Any]] = []  # the pose messages of the latest frame that moved the robot
        self.chart_data: dict[str, list[Any]] = {}  # uPlot uuid -> its latest data, decoded (binary as raw bytes)
        # uPlot uuid -> the window the page keeps from the live charts' pushes (chart_feed): one list per
        # column, or a constant's value
        self.chart_windows: dict[str, list[Any]] = {}
        self.gui_log: list[tuple[str, dict[str, Any]]] = []  # every GUI update (not charts): (uuid, updates)
        self.scripts: list[str] = []  # the sources of the RunJavascriptMessages received, in order
        self.notifications: list[dict[str, Any]] = []
        # The scene's lighting as last sent: {"environment": an environment map is on, "lights": ...,
        # "shadows": ..., "ambient": ...} (viser's EnvironmentMapMessage, EnableLightsMessage, and the
        # visibility of the ambient light the simple lighting adds)
        self.lighting: dict[str, bool] = {}
        self.gui: dict[str, dict[str, Any]] = {}  # uuid -> creation message
        self.gui_updates: dict[str, dict[str, Any]] = {}  # uuid -> latest value of each property updated (not charts)
        self.scene_counts: collections.Counter[tuple[str, str]] = collections.Counter()  # (type, node name) -> messages
        self.scene_points: dict[str, np.ndarray] = {}  # node name -> its latest `points` (float32)
        self.scene_visible: dict[str, bool] = {}  # node name -> its latest visibility message's
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

    def set_gui_value(self, label: str, value: Any, timeout: float = 30.0) -> str:
        """Send a value for the GUI input with this label, as the browser would; returns its uuid.

        Waits up to `timeout` s for the input to arrive: the page comes in several frames, and a
        busy server may not have sent the later panels when the first ones are seen.
        """
        uuid = self.input_uuid(label, timeout)
        self.send({"type": "GuiUpdateMessage", "uuid": uuid, "updates": {"value": value}})
        return uuid

    def input_uuid(self, label: str, timeout: float = 30.0) -> str:
        """The uuid of the GUI input with this label, once it has arrived (up to `timeout` s)."""
        if not self.wait_for(lambda p: p._find(label) is not None, timeout):
            raise KeyError(f"no GUI input labelled {label!r} seen in {timeout:g} s")
        return self.uuid_of(label)

    def uuid_of(self, label: str) -> str:
        with self._lock:
            uuid = self._find(label)
        if uuid is None:
            raise KeyError(f"no GUI input labelled {label!r} seen yet")
        return uuid

    def _find(self, label: str) -> str | None:
        """The uuid of the input labelled `label` (call with the lock held)."""
        for uuid, message in self.gui.items():
            if message.get("props", {}).get("label") == label:
                return uuid
        return None

    def wait_for(self, predicate: Any, timeout: float = 60.0) -> bool:
        """Poll `predicate(self)` until it is truthy or `timeout` s pass; True if it became truthy.

        `timeout` bounds a failure only (it was 10 s: under a busy loop per core beside two test
        workers, five pose frames took longer than that to arrive)."""
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

    def traffic_snapshot(self) -> Traffic:
        """A copy of the traffic so far (subtract two with `Traffic.minus`)."""
        with self._lock:
            return self.traffic.copy()

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
        envelope = msgspec.msgpack.decode(payload)
        messages, lengths = envelope["messages"], envelope.get("binaryBufferLengths", [])
        with self._lock:
            self.bytes += len(raw)
            self.frames += 1
            moved = False
            poses = []
            for message in messages:
                kind = message.get("type", "?")
                self.counts[kind] += 1
                if is_pose(message):
                    poses.append(message)
                    moved = moved or str(message.get("name", "")).startswith(ROBOT)
                elif kind == "NotificationShowMessage":
                    self.notifications.append(message.get("props", {}))
                elif kind == "GuiUplotMessage":
                    self.uplots.add(message["uuid"])
                elif kind == "GuiUpdateMessage" and message["uuid"] in self.uplots and "data" in message["updates"]:
                    uuid, refreshes = message["uuid"], self.traffic.chart_refreshes
                    refreshes[uuid] = refreshes.get(uuid, 0) + 1
                    self.chart_data[uuid] = self._resolve(message["updates"]["data"], raw, compressed, lengths)
                elif kind == "RunJavascriptMessage":
                    self._script(message["source"])
                elif kind == "EnvironmentMapMessage":
                    self.lighting["environment"] = message.get("hdri_data") is not None
                elif kind == "EnableLightsMessage":
                    self.lighting["lights"], self.lighting["shadows"] = message["enabled"], message["cast_shadow"]
                elif kind == "AmbientLightMessage":
                    self.lighting["ambient"] = True  # until a visibility message says otherwise
                elif kind == "SetSceneNodeVisibilityMessage" and message["name"] == AMBIENT:
                    self.lighting["ambient"] = message["visible"]
                elif kind == "GuiUpdateMessage":
                    self.gui_updates.setdefault(message["uuid"], {}).update(message["updates"])
                    self.gui_log.append((message["uuid"], message["updates"]))
                if "uuid" in message and "props" in message and kind.startswith("Gui"):
                    self.gui[message["uuid"]] = message
                if "name" in message:
                    self._scene(kind, message, raw, compressed, lengths)
            self.pose_frames += moved
            if moved:
                self.last_pose_frame = poses
                self.traffic.scene_updates += 1
            self._account(raw, compressed, messages, lengths)

    def _scene(self, kind: str, message: dict[str, Any], raw: bytes, compressed: int, lengths: list[int]) -> None:
        """Count a scene node's message; keep its points (line segments, arrows) as the page would draw them."""
        name = str(message["name"])
        self.scene_counts[kind, name] += 1
        if kind == "SetSceneNodeVisibilityMessage":
            self.scene_visible[name] = bool(message["visible"])
        elif kind == "RemoveSceneNodeMessage":  # the page draws it no more
            self.scene_points.pop(name, None)
            self.scene_visible.pop(name, None)
        points = {**message.get("props", {}), **message.get("updates", {})}.get("points")
        if isinstance(points, dict):
            dtype, data = self._resolve(points, raw, compressed, lengths)
            self.scene_points[name] = np.frombuffer(data, dtype=dtype).reshape(-1, 2, 3)

    def shown_value(self, label: str) -> Any:
        """The value the page shows in the GUI input labelled `label`: as created, then as last updated."""
        with self._lock:
            uuid = self.uuid_of(label)
            return {**self.gui[uuid], **self.gui_updates.get(uuid, {})}.get("value")

    def shown_html(self, container: str) -> str:
        """The HTML elements of a container as the page shows them: the visible ones, by order, their content."""
        with self._lock:
            parts = []
            for uuid, message in self.gui.items():
                if message.get("type") != "GuiHtmlMessage" or message.get("container_uuid") != container:
                    continue
                props = {**message["props"], **self.gui_updates.get(uuid, {})}
                if props.get("visible", True):
                    parts.append((props["order"], props["content"]))
        return "".join(content for _, content in sorted(parts))

    def _script(self, source: str) -> None:
        """A script the page would run: a live charts' push is applied to the probe's copy of its windows."""
        self.scripts.append(source)
        update = decode_push(source)
        if update is not None:
            apply_push(self.chart_windows, update)
            for uuid in update:
                self.traffic.chart_refreshes[uuid] = self.traffic.chart_refreshes.get(uuid, 0) + 1

    def _category(self, message: dict[str, Any]) -> str:
        if message.get("type") == "GuiUpdateMessage" and message.get("uuid") in self.uplots:
            return "charts"
        if message.get("type") == "RunJavascriptMessage" and decode_push(message["source"]) is not None:
            return "charts"
        if str(message.get("name", "")).startswith(TERRAIN):
            return "terrain"
        return "poses" if is_pose(message) else "other"

    def _account(self, raw: bytes, compressed: int, messages: list[dict[str, Any]], lengths: list[int]) -> None:
        """Split this frame's bytes between the categories (see `Traffic`)."""
        groups: dict[str, list[dict[str, Any]]] = collections.defaultdict(list)
        binary: dict[str, int] = collections.Counter()
        for message in messages:
            category = self._category(message)
            groups[category].append(message)
            binary[category] += sum(lengths[i] for i in _binary_indices(message, []))
            self.traffic.messages[category] += 1
        shared = len(raw) - sum(binary.values())  # header, compressed msgpack, alignment padding
        if len(groups) == 1:
            weights = {next(iter(groups)): 1.0}
        else:
            weights = {c: len(self._compressor.compress(msgspec.msgpack.encode(g))) for c, g in groups.items()}
        total = sum(weights.values())
        for category, weight in weights.items():
            self.traffic.bytes[category] += binary[category] + shared * weight / total

    @staticmethod
    def _resolve(value: Any, raw: bytes, compressed: int, lengths: list[int]) -> Any:
        """Replace binary placeholders by (dtype, bytes), as the browser makes typed arrays of them."""
        offsets, offset = [], 16 + compressed
        for length in lengths:
            offset += (8 - offset % 8) % 8
            offsets.append(offset)
            offset += length

        def walk(v: Any) -> Any:
            if isinstance(v, dict) and "__binary_index" in v:
                i = v["__binary_index"]
                return (v["dtype"], raw[offsets[i] : offsets[i] + lengths[i]])
            if isinstance(v, list):
                return [walk(x) for x in v]
            return v

        return walk(value)
