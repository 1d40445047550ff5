"""The controller API over loopback TCP (hopper.laws.remote): lock-step flights, faults, the README's peer."""

from __future__ import annotations

import ast
import math
import socket
import struct
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from net import free_port, port_is_free

from hopper.config import SimConfig
from hopper.controllers import ControllerError, ControllerFault, Observation, with_controller
from hopper.controllers.law import PROBE_CALLS, WARM_UP_CALLS
from hopper.events import ControllerFailed
from hopper.laws import remote
from hopper.laws.pid import PaperPID
from hopper.laws.remote import HOSTS_ENV, PEER_EXAMPLE, Peer, RemoteController, check_host
from hopper.sim import Simulation

pytestmark = pytest.mark.integration

HOPS = 7


class PythonPID(PaperPID):
    """The paper's PID through the API (not the kernel's compiled copy)."""

    compiled = None


class NaNAfter(PythonPID):
    """The PID until its 1000th call, then NaN (a peer's bug)."""

    calls = 0

    def __call__(self, obs: Observation) -> float:
        self.calls += 1
        return math.nan if self.calls > 1000 else super().__call__(obs)


class AlwaysNaN(PythonPID):
    def __call__(self, obs: Observation) -> float:
        return math.nan


class Trace:
    """A listener keeping qpos and the wheel command of every tick."""

    def __init__(self) -> None:
        self.rows: list[np.ndarray] = []

    def tick(self, sim: Simulation) -> None:
        self.rows.append(np.concatenate([sim.data.qpos, sim.data.ctrl]))

    def event(self, sim: Simulation, event: object) -> None:
        pass


def fly(spec: str, hops: int = HOPS, *listeners: object) -> tuple[Simulation, np.ndarray]:
    sim = Simulation(with_controller(SimConfig(), spec))
    trace = Trace()
    sim.listeners.extend([trace, *listeners])
    sim.run(hops)
    return sim, np.array(trace.rows)


@pytest.fixture(scope="module")
def in_process() -> tuple[Simulation, np.ndarray]:
    return fly(f"{__name__}:PythonPID")


@pytest.fixture
def readme_peer(tmp_path: Path) -> Iterator[tuple[subprocess.Popen, str]]:
    """PEER_EXAMPLE run as a program of its own on a port the OS chooses; (process, spec)."""
    file = tmp_path / "peer.py"
    file.write_text(PEER_EXAMPLE)
    proc = subprocess.Popen([sys.executable, str(file), "0"], stdout=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()  # blocks until it listens (or ends)
        assert line.startswith("listening on tcp://127.0.0.1:"), f"the peer said {line!r}"
        yield proc, line.split()[-1]
    finally:
        proc.kill()
        proc.wait()
        proc.stdout.close()


def same_flight(a: tuple[Simulation, np.ndarray], b: tuple[Simulation, np.ndarray]) -> None:
    (sim_a, trace_a), (sim_b, trace_b) = a, b
    assert len(sim_b.hops) == HOPS and not sim_b.fallen
    assert trace_a.shape == trace_b.shape and np.array_equal(trace_a, trace_b), "the trajectories differ"
    assert sim_a.hops == sim_b.hops
    assert [e.time for e in sim_a.events] == [e.time for e in sim_b.events]


def report(label: str, sim: Simulation) -> remote.RoundTrip:
    rt = sim.law.controller.round_trip()
    print(f"\n{label}: {HOPS} hops lock-step, {rt.describe()}")
    assert rt.calls == sim.law.calls + WARM_UP_CALLS + PROBE_CALLS  # the flight's calls and the pre-run check's
    return rt


# -- lock-step flights ------------------------------------------------------------------------------
def test_a_peer_thread_flies_seven_hops_bit_identical_to_the_in_process_pid(in_process) -> None:
    with Peer(PythonPID) as peer:
        flown = fly(peer.spec)
        rt = report("Peer thread", flown[0])
        flown[0].law.controller.close()
    same_flight(in_process, flown)
    assert not any(isinstance(e.payload, ControllerFailed) for e in flown[0].events)
    assert rt.p50_us < 1000.0  # lock-step at 1 kHz needs less than a tick


def test_the_readme_peer_flies_seven_hops_bit_identical_to_the_in_process_pid(in_process, readme_peer) -> None:
    _, spec = readme_peer
    flown = fly(spec)
    report("README peer (its own process)", flown[0])
    same_flight(in_process, flown)


def test_the_readme_peer_imports_the_stdlib_only_and_fits_a_readme() -> None:
    tree = ast.parse(PEER_EXAMPLE)
    imported = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    imported |= {n.module.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    assert imported and imported <= sys.stdlib_module_names
    assert len(PEER_EXAMPLE.splitlines()) <= 45


def test_a_restore_resets_the_remote_controller_and_refly_is_identical() -> None:
    with Peer(PythonPID) as peer:
        sim = Simulation(with_controller(SimConfig(), peer.spec))
        sim.run(2)  # ends at a touchdown: in stance, the controller is reset at the next liftoff
        snap = sim.snapshot(with_hops=False)
        first = list(sim.run(4)[2:])
        sim.restore(snap)
        del sim.hops[2:]
        assert sim.run(4)[2:] == first
        sim.law.controller.close()


# -- faults ----------------------------------------------------------------------------------------
def test_nothing_listening_is_an_error_at_construction() -> None:
    spec = f"tcp://127.0.0.1:{free_port()}"
    with pytest.raises(ControllerError, match=f"nothing listens on {spec}"):
        RemoteController(spec)
    with pytest.raises(ControllerError, match=f"nothing listens on {spec}"):
        Simulation(with_controller(SimConfig(), spec))


def test_a_peer_that_dies_mid_run_fails_over_to_the_pid(readme_peer) -> None:
    proc, spec = readme_peer

    class Killer(Trace):
        def tick(self, sim: Simulation) -> None:
            if sim.law.compiled is None and sim.law.calls == 1500:  # in the second flight
                proc.kill()
                proc.wait()

    sim, _ = fly(spec, HOPS, Killer())
    failed = [e.payload for e in sim.events if isinstance(e.payload, ControllerFailed)]
    assert len(failed) == 1 and failed[0].spec == spec
    assert spec in failed[0].cause and ("closed the connection" in failed[0].cause or "reset" in failed[0].cause)
    assert sim.law.compiled == "pid" and sim.controller_fault == failed[0].cause
    assert len(sim.hops) == HOPS and not sim.fallen  # the run went on with the PID


def test_a_peer_answering_nan_faults_mid_run_and_at_the_pre_run_check() -> None:
    with Peer(NaNAfter) as peer:
        sim, _ = fly(peer.spec, 2)
    failed = [e.payload for e in sim.events if isinstance(e.payload, ControllerFailed)]
    assert len(failed) == 1 and "nan" in failed[0].cause
    assert len(sim.hops) == 2 and sim.law.compiled == "pid"
    with Peer(AlwaysNaN) as peer, pytest.raises(ControllerError, match="nan"):
        Simulation(with_controller(SimConfig(), peer.spec))


class RawPeer:
    """A listening socket that answers the hello as told, then never answers a frame."""

    def __init__(self, hello: bytes | None) -> None:
        self.server = socket.create_server(("127.0.0.1", 0))
        self.spec = f"tcp://127.0.0.1:{self.server.getsockname()[1]}"
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._serve, args=(hello,), daemon=True)
        self.thread.start()

    def _serve(self, hello: bytes | None) -> None:
        conn, _ = self.server.accept()
        with conn:
            conn.recv(4096)
            if hello is not None:
                conn.sendall(hello)
            self.done.wait()

    def close(self) -> None:
        self.done.set()
        self.thread.join(timeout=10.0)
        self.server.close()


@pytest.mark.parametrize(
    "hello, error",
    [
        (None, r"no hello: tcp://127\.0\.0\.1:\d+ did not answer within 0\.2 s"),
        (struct.pack("<4sI", b"HOPR", 2), "answered the hello with b'HOPR' version 2, not b'HOPR' version 1"),
    ],
)
def test_a_bad_hello_is_an_error_at_construction(hello: bytes | None, error: str) -> None:
    peer = RawPeer(hello)
    try:
        with pytest.raises(ControllerError, match=error):
            RemoteController(peer.spec + "?timeout=0.2")
    finally:
        peer.close()


def test_a_silent_peer_faults_after_the_timeout_naming_the_address() -> None:
    peer = RawPeer(struct.pack("<4sI", b"HOPR", 1))
    try:
        controller = RemoteController(peer.spec + "?timeout=0.2")
        obs = Observation(0.01, 0.0, 0.0, 0.0, 0.0, 1.0, 1.625, 0.001, (1.0, 1.0), (-10.0, 10.0), 1e-3, 500.0)
        with pytest.raises(ControllerFault, match=f"^{peer.spec} did not answer within 0.2 s$"):
            controller(obs)
        with pytest.raises(ControllerFault, match="closed"):
            controller(obs)  # a late answer is never read as the next one's
    finally:
        peer.close()


def test_only_loopback_hosts_unless_the_environment_allows_them(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(HOSTS_ENV, raising=False)
    for host in ("127.0.0.1", "127.4.5.6", "::1", "localhost"):
        check_host(host)
    with pytest.raises(ControllerError, match=f"192.0.2.1 .* is not a loopback address .*{HOSTS_ENV}=192.0.2.1"):
        RemoteController("tcp://192.0.2.1:5757")  # refused before any packet leaves
    with pytest.raises(ControllerError, match="not a loopback address"):
        Simulation(with_controller(SimConfig(), "tcp://[2001:db8::1]:5757"))
    monkeypatch.setenv(HOSTS_ENV, "flight-computer.local, 192.0.2.1")
    check_host("192.0.2.1")  # allowed (not connected to: traffic stays on loopback)
    with pytest.raises(ControllerError, match="not a loopback address"):
        check_host("192.0.2.2")


@pytest.mark.parametrize(
    "spec, error",
    [
        ("tcp://127.0.0.1", "tcp://HOST:PORT"),
        ("tcp://127.0.0.1:99999", "out of range"),
        ("tcp://127.0.0.1:5757?delay=3", "unknown parameter delay"),
        ("tcp://127.0.0.1:5757?timeout=0", r"timeout must be in \(0, 60\] s"),
    ],
)
def test_a_malformed_spec_says_what_is_allowed(spec: str, error: str) -> None:
    with pytest.raises(ControllerError, match=error):
        RemoteController(spec)


# -- the protocol and the reference peer -------------------------------------------------------------
def test_the_frame_carries_every_observation_field_exactly() -> None:
    obs = Observation(*(math.pi * (i + 1) for i in range(8)), (1.5, 2.5), (-3.5, 4.5), 1.0 / 3.0, 5e-324)
    values = remote.FRAME.unpack(remote.FRAME.pack(remote.CALL, *remote.flatten(obs)))[1:]
    assert remote.unflatten(dict(zip(remote.FIELDS, values, strict=True))) == obs
    documented = remote.__doc__.split("Version 1 sends 14: ")[1].split(". A peer")[0].split()
    assert tuple(documented) == remote.FIELDS and remote.FRAME.size == 4 + 8 * 14


def test_the_peer_stops_and_frees_its_port() -> None:
    peer = Peer(PythonPID).start()
    port = peer.server_address[1]
    controller = RemoteController(peer.spec)
    controller.close()  # the client closes first: the wait after closing stays on its side
    peer.stop()
    assert port_is_free(port)
    live = Peer(PythonPID).start()
    controller = RemoteController(live.spec)
    live.stop()  # with a connection open: it ends too
    with pytest.raises(ControllerFault, match="closed the connection|reset"):
        controller.reset(Observation(*([0.0] * 8), (1.0, 1.0), (-1.0, 1.0), 1.0, 1.0))
