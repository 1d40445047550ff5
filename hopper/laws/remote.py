"""A flight wheel law in another process: the controller API over loopback TCP, lock-step at 1 kHz.

The simulation is the client: `--controller tcp://127.0.0.1:PORT` connects to a program that listens
(a flight computer's code, a controller in another language, `Peer` below). That way round because
the controller is the long-lived party and the simulation the one started, re-flown and switched
many times: a spec names where the controller is, as a URL does; a run that finds no one there stops
before it starts ("nothing listens on ..."); each connection is one controller instance, so sweep
workers may share one peer (Peer serves connections in parallel, PEER_EXAMPLE in turn). Only
loopback hosts (127.0.0.0/8, ::1) are accepted unless the environment variable HOPPER_REMOTE_HOSTS
lists the host (comma-separated, `*` for any): set by whoever starts the process, not by whoever
types a spec (a dashboard client may).

Protocol, version 1 (all integers and floats little-endian, no padding; the simulation sends first):
- hello, simulation -> peer: b"HOPR", uint32 version (1), uint32 n, then n bytes of ASCII: the frame's
  field names separated by spaces (FIELDS: the Observation's fields with momentum_headroom and
  torque_bounds flattened to *_plus/*_minus and torque_low/torque_high). Units are the Observation's.
  Version 1 sends 14: pitch rate wheel_speed time time_since_liftoff time_to_touchdown gravity dt
  momentum_headroom_plus momentum_headroom_minus torque_low torque_high wheel_inertia
  wheel_speed_limit. A peer reads them by name from the hello: later fields may be appended.
- hello reply, peer -> simulation: b"HOPR", uint32 the version the peer speaks (it must be 1).
- frame, simulation -> peer: uint32 type (1 = call, 2 = reset at liftoff), then one float64 per field
  in the hello's order: 4 + 8 n bytes.
- reply, peer -> simulation: one float64. For a call, the wheel torque command in N m (the API's sign
  convention); for a reset, any value (ignored: the answer keeps the exchange lock-step).
- the simulation closes the connection when it is done with the controller; the peer sees end of file.
A peer that does not answer within the timeout (`?timeout=S`, default 1 s) or closes the connection
makes a ControllerFault naming the address (the simulation flies on with the built-in PID).

Not done: simulating the round trip as the command delay. On loopback it is tens of us, far under
one 1 ms tick, and the kernel's delay line counts whole ticks: it would round to zero, or to one tick
that overstates it, and make a run depend on the machine it ran on. The lock-step simulation waits
for the answer, so the round trip costs wall time, never simulated time; for a real bus's latency
use realistic sensing's motor_delay_ticks. PEER_EXAMPLE is a complete peer with the stdlib alone.
"""

from __future__ import annotations

import collections
import contextlib
import ipaddress
import logging
import math
import os
import socket
import socketserver
import struct
import threading
import time
import urllib.parse
from collections.abc import Mapping
from typing import NamedTuple, NoReturn

import numpy as np

from hopper import interrupts
from hopper.controllers.api import ControllerError, Observation
from hopper.controllers.law import ControllerFault
from hopper.controllers.loading import declared_params

log = logging.getLogger(__name__)

MAGIC = b"HOPR"
VERSION = 1
CALL, RESET = 1, 2
HOSTS_ENV = "HOPPER_REMOTE_HOSTS"  # non-loopback hosts allowed, comma-separated; "*" for any
DEFAULT_TIMEOUT_S = 1.0  # s a peer may take to answer one frame (or to accept the connection)
MAX_TIMEOUT_S = 60.0
ROUND_TRIP_WINDOW = 65536  # call round trips kept for the percentiles (about a minute of flight at 1 kHz)

_PAIRS = {
    "momentum_headroom": ("momentum_headroom_plus", "momentum_headroom_minus"),
    "torque_bounds": ("torque_low", "torque_high"),
}
FIELDS: tuple[str, ...] = tuple(n for f in Observation._fields for n in _PAIRS.get(f, (f,)))
HELLO = struct.Struct("<4sII")  # magic, version, length of the field names
HELLO_REPLY = struct.Struct("<4sI")  # magic, version
REPLY = struct.Struct("<d")  # N m


def frame_struct(n_fields: int) -> struct.Struct:
    """A frame: uint32 type, then n_fields float64."""
    return struct.Struct(f"<I{n_fields}d")


FRAME = frame_struct(len(FIELDS))


def flatten(obs: Observation) -> tuple[float, ...]:
    """The Observation's values in FIELDS' order (14 floats)."""
    h, b = obs.momentum_headroom, obs.torque_bounds
    return (*obs[:8], h[0], h[1], b[0], b[1], *obs[10:])


def unflatten(values: dict[str, float]) -> Observation:
    """The Observation a frame's values (by field name) describe."""
    return Observation(
        **{f: tuple(values[n] for n in _PAIRS[f]) if f in _PAIRS else values[f] for f in Observation._fields}
    )


class RoundTrip(NamedTuple):
    """Wall time from sending a call frame to having its reply, over the last ROUND_TRIP_WINDOW calls."""

    calls: int  # call frames answered since the connection opened
    p50_us: float  # us, median (nan before the first call)
    p99_us: float  # us

    def describe(self) -> str:
        return f"round trip p50 {self.p50_us:.1f} us, p99 {self.p99_us:.1f} us over {self.calls} calls"


def parse(spec: str) -> tuple[str, int, float]:
    """(host, port, timeout s) of `tcp://HOST:PORT[?timeout=S]`, or ControllerError."""
    parts = urllib.parse.urlsplit(spec)
    try:
        host, port = parts.hostname, parts.port
    except ValueError as exc:
        raise ControllerError(f"{spec}: {exc}") from None
    if parts.scheme != "tcp" or not host or port is None or parts.path not in ("", "/"):
        raise ControllerError(f"{spec}: a remote controller is tcp://HOST:PORT[?timeout=S], e.g. tcp://127.0.0.1:5757")
    query = urllib.parse.parse_qs(parts.query, keep_blank_values=True)
    unknown = sorted(set(query) - {"timeout"})
    if unknown:
        raise ControllerError(f"{spec}: unknown parameter {', '.join(unknown)} (allowed: timeout=S, seconds)")
    timeout = DEFAULT_TIMEOUT_S
    if "timeout" in query:
        try:
            timeout = float(query["timeout"][-1])
        except ValueError:
            timeout = math.nan
        if not 0.0 < timeout <= MAX_TIMEOUT_S:
            raise ControllerError(f"{spec}: timeout must be in (0, {MAX_TIMEOUT_S:g}] s, got {query['timeout'][-1]!r}")
    return host, port, timeout


def check_host(host: str) -> None:
    """ControllerError unless every address of `host` is loopback or HOSTS_ENV allows the host."""
    allowed = {h.strip() for h in os.environ.get(HOSTS_ENV, "").split(",") if h.strip()}
    if host in allowed or "*" in allowed:
        return
    try:
        addresses = {info[4][0] for info in socket.getaddrinfo(host, None, proto=socket.IPPROTO_TCP)}
    except socket.gaierror as exc:
        raise ControllerError(f"unknown host {host}: {exc.strerror}") from None
    outside = sorted(a for a in addresses if not ipaddress.ip_address(a.split("%")[0]).is_loopback)
    if outside:
        raise ControllerError(
            f"{host} ({', '.join(outside)}) is not a loopback address (127.0.0.0/8, ::1); "
            f"to allow it, start the process with {HOSTS_ENV}={host}"
        )


class RemoteController:
    """The controller behind `tcp://HOST:PORT`: each call sends the Observation, waits for the torque."""

    stateless_copy = True  # its state is in the peer: a snapshot resets it at the next liftoff instead
    _sock: socket.socket | None = None  # None: not connected yet, or closed

    def __init__(self, spec: str) -> None:
        host, port, self.timeout = parse(spec)
        check_host(host)
        self.address = f"tcp://{f'[{host}]' if ':' in host else host}:{port}"
        self._reply = bytearray(REPLY.size)
        self._times: collections.deque[int] = collections.deque(maxlen=ROUND_TRIP_WINDOW)  # ns
        self.calls = 0
        try:
            sock = socket.create_connection((host, port), timeout=self.timeout)
        except ConnectionRefusedError:
            raise ControllerError(f"nothing listens on {self.address}") from None
        except OSError as exc:
            raise ControllerError(f"cannot connect to {self.address}: {exc.strerror or exc}") from None
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._sock = sock
        names = " ".join(FIELDS).encode("ascii")
        try:
            sock.sendall(HELLO.pack(MAGIC, VERSION, len(names)) + names)
            magic, version = HELLO_REPLY.unpack(self._receive(HELLO_REPLY.size))
        except ControllerFault as fault:
            self.close()
            raise ControllerError(f"no hello: {fault}") from None
        if magic != MAGIC or version != VERSION:
            self.close()
            raise ControllerError(
                f"{self.address} answered the hello with {magic!r} version {version}, not {MAGIC!r} version {VERSION}"
            )

    def __call__(self, obs: Observation) -> float:
        start = time.perf_counter_ns()
        torque = self._exchange(CALL, obs)
        self._times.append(time.perf_counter_ns() - start)
        self.calls += 1
        return torque

    def reset(self, obs: Observation) -> None:
        self._exchange(RESET, obs)

    def round_trip(self) -> RoundTrip:
        """p50 and p99 of the call round trips (us), for a CLI or the dashboard to show."""
        if not self._times:
            return RoundTrip(self.calls, math.nan, math.nan)
        p50, p99 = np.percentile(np.fromiter(self._times, np.int64, len(self._times)), (50, 99)) / 1e3
        return RoundTrip(self.calls, float(p50), float(p99))

    def close(self) -> None:
        """End the connection (the peer sees end of file); later calls fault."""
        sock, self._sock = self._sock, None
        if sock is not None:
            sock.close()

    def __del__(self) -> None:
        self.close()

    def _exchange(self, kind: int, obs: Observation) -> float:
        if self._sock is None:
            raise ControllerFault(f"{self.address}: the connection is closed")
        try:
            self._sock.sendall(FRAME.pack(kind, *flatten(obs)))
        except OSError as exc:
            self._fail(f"{self.address}: sending failed: {exc.strerror or type(exc).__name__}")
        return REPLY.unpack(self._receive(REPLY.size))[0]

    def _receive(self, size: int) -> bytearray:
        buffer = self._reply if size == REPLY.size else bytearray(size)
        view, got = memoryview(buffer), 0
        while got < size:
            try:
                n = self._sock.recv_into(view[got:])
            except TimeoutError:
                self._fail(f"{self.address} did not answer within {self.timeout:g} s")
            except OSError as exc:
                self._fail(f"{self.address}: {exc.strerror or type(exc).__name__}")
            if n == 0:
                self._fail(f"{self.address} closed the connection")
            got += n
        return buffer

    def _fail(self, message: str) -> NoReturn:
        self.close()  # a late answer must not be read as the next frame's
        raise ControllerFault(message)


class Peer(socketserver.ThreadingTCPServer):
    """The protocol's reference peer: serves a controller class of the API to simulations that
    connect, a fresh instance per connection with its declared params at their defaults, then
    `params`. Listening once constructed; `start()` accepts in a thread, `stop()` closes every
    connection and frees the port."""

    daemon_threads = True
    block_on_close = True

    def __init__(
        self, controller: type, host: str = "127.0.0.1", port: int = 0, params: Mapping[str, float] | None = None
    ) -> None:
        self.controller, self.params = controller, dict(params or {})
        declared = {p.name: p for p in declared_params(controller)}
        unknown = sorted(set(self.params) - set(declared))
        if unknown:
            raise ControllerError(f"{controller.__name__} has no parameter {', '.join(unknown)}")
        self._values = {n: p.check(self.params.get(n, p.default), controller.__name__) for n, p in declared.items()}
        self._open: set[socket.socket] = set()
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self.address_family = socket.AF_INET6 if ":" in host else socket.AF_INET
        super().__init__((host, port), _Connection)

    @property
    def spec(self) -> str:
        host, port = self.server_address[:2]
        return f"tcp://{host}:{port}"

    def start(self) -> Peer:
        self._thread = threading.Thread(target=self.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self.shutdown()  # returns when serve_forever has
        with self._lock:
            for sock in self._open:
                with contextlib.suppress(OSError):
                    sock.shutdown(socket.SHUT_RDWR)
        self.server_close()  # joins the connections' threads

    def instance(self) -> object:
        """A new controller for one connection."""
        controller = self.controller()
        for name, value in self._values.items():
            setattr(controller, name, value)
        return controller

    def __enter__(self) -> Peer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


class _Connection(socketserver.BaseRequestHandler):
    server: Peer

    def handle(self) -> None:
        sock: socket.socket = self.request
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        with self.server._lock:
            self.server._open.add(sock)
        file = sock.makefile("rb")
        try:
            magic, version, size = HELLO.unpack(file.read(HELLO.size))
            fields = file.read(size).decode("ascii").split()
            sock.sendall(HELLO_REPLY.pack(MAGIC, VERSION))
            if magic != MAGIC or version != VERSION or set(fields) != set(FIELDS):
                return
            frame, controller = frame_struct(len(fields)), self.server.instance()
            reset = getattr(controller, "reset", None)
            while len(data := file.read(frame.size)) == frame.size:
                kind, *values = frame.unpack(data)
                obs = unflatten(dict(zip(fields, values, strict=True)))
                if kind == CALL:
                    sock.sendall(REPLY.pack(float(controller(obs))))
                elif kind == RESET:
                    if reset is not None:
                        reset(obs)
                    sock.sendall(REPLY.pack(0.0))
                else:
                    return
        except (struct.error, OSError):
            pass  # the simulation went away, or sent garbage: end this connection
        except Exception:
            log.exception("%s raised; closing the connection", self.server.controller.__name__)
        finally:
            with self.server._lock:
                self.server._open.discard(sock)
            file.close()


def serve(controller: type, host: str = "127.0.0.1", port: int = 0, params: Mapping[str, float] | None = None) -> None:
    """Serve `controller` (an API class) on host:port until interrupted (port 0: the OS chooses; logged)."""
    with Peer(controller, host, port, params) as peer:
        log.info("serving %s on %s", controller.__name__, peer.spec)
        interrupts.join(peer._thread)  # a stop signal ends it


PEER_EXAMPLE = """\
# The paper's PID in its own process, over hopper's TCP protocol (version 1), with the stdlib alone.
# Run `python peer.py 5757`, then `hopper-sim run --controller tcp://127.0.0.1:5757`.
import socket
import struct
import sys

KP, KI, KD = 450.0, 50.0, 30.0  # N m/rad, N m/(rad s), N m s/rad: hopper's default gains
CALL, RESET = 1, 2


def read(conn, size):
    data = conn.recv(size, socket.MSG_WAITALL)  # all `size` bytes, or fewer at end of file
    if len(data) < size:
        raise EOFError
    return data


def fly(conn):
    magic, version, size = struct.unpack("<4sII", read(conn, 12))  # hello: b"HOPR", 1, len(names)
    fields = read(conn, size).decode("ascii").split()  # the frame's float64 fields, in order
    conn.sendall(struct.pack("<4sI", b"HOPR", 1))  # I speak version 1
    frame, integral = struct.Struct("<I%dd" % len(fields)), 0.0  # uint32 type, one float64 a field
    while True:
        kind, *values = frame.unpack(read(conn, frame.size))
        obs = dict(zip(fields, values))  # SI units: rad, rad/s, s, N m ...
        if kind == RESET:  # at liftoff
            integral, torque = 0.0, 0.0
        else:
            torque = KP * obs["pitch"] + KD * obs["rate"] + KI * integral  # N m
            if obs["torque_low"] <= torque <= obs["torque_high"]:  # no windup while saturated
                integral += obs["pitch"] * obs["dt"]
        conn.sendall(struct.pack("<d", torque))  # every frame gets one float64


server = socket.create_server(("127.0.0.1", int(sys.argv[1])))
print("listening on tcp://%s:%d" % server.getsockname(), flush=True)
while True:
    conn, _ = server.accept()
    conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    try:
        fly(conn)
    except (EOFError, ConnectionError):
        conn.close()  # the simulation is done with this controller
"""
