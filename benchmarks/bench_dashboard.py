"""Dashboard load: real-time factor, scene updates and bandwidth with 0, 1 and 4 connected clients.

Run: python -m benchmarks.bench_dashboard [--seconds 10] [--speed 1]

The server runs in this process at the asked speed; the clients run in a child process (browsers
are separate processes too) and speak viser's real protocol: subprotocol handshake, a camera
report, then they receive and decode the full stream (zstd + msgpack + binary buffers) as a
browser would, without rendering it. Everything is measured in this one run.
"""

from __future__ import annotations

import argparse
import json
import socket
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # run from a checkout without installing


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def probe_main(url: str, clients: int, settle: float, seconds: float) -> None:
    """Child process: connect `clients`, wait out the initial scene, measure, print JSON."""
    from benchmarks.probe import ProbeClient

    probes = [ProbeClient(url) for _ in range(clients)]
    for p in probes:
        if not p.wait_for(lambda c: c.pose_frames > 0, timeout=30):
            raise SystemExit("a client never received a pose")
    time.sleep(settle)
    initial = [p.snapshot() for p in probes]
    print(json.dumps({"event": "measuring"}), flush=True)
    start = time.perf_counter()
    time.sleep(seconds)
    wall = time.perf_counter() - start
    final = [p.snapshot() for p in probes]
    stats = [
        {
            "initial_bytes": b0,
            "bytes_per_s": (b1 - b0) / wall,
            "frames_per_s": (f1 - f0) / wall,
            "pose_updates_per_s": (q1 - q0) / wall,
        }
        for (b0, f0, q0), (b1, f1, q1) in zip(initial, final, strict=True)
    ]
    print(json.dumps({"event": "done", "clients": stats}), flush=True)
    for p in probes:
        p.close()


def measure(dashboard, clients: int, settle: float, seconds: float) -> dict:
    """Real-time factor over the measuring window, with `clients` connected from a child process."""
    child = None
    if clients:
        child = subprocess.Popen(
            [sys.executable, "-m", "benchmarks.bench_dashboard", "--probe", dashboard.url,
             "--clients", str(clients), "--seconds", str(seconds), "--settle", str(settle)],
            stdout=subprocess.PIPE, text=True, cwd=ROOT,
        )  # fmt: skip
        line = child.stdout.readline()
        if '"measuring"' not in line:
            raise SystemExit(f"probe failed to start: {line!r}")
    else:
        time.sleep(settle)
    pacer = dashboard.pacer
    steps0, frames0, t0 = pacer._steps, dashboard.frames, time.perf_counter()
    time.sleep(seconds)
    steps1, frames1, t1 = pacer._steps, dashboard.frames, time.perf_counter()
    result = {
        "clients": clients,
        "rtf": (steps1 - steps0) * pacer.timestep / (t1 - t0) / pacer.speed,
        "server_frames_per_s": (frames1 - frames0) / (t1 - t0),
        "per_client": [],
    }
    if child is not None:
        out, _ = child.communicate(timeout=seconds + 60)
        result["per_client"] = json.loads(out.strip().splitlines()[-1])["clients"]
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="measuring window per case (s)")
    parser.add_argument("--settle", type=float, default=3.0, help="wait after connecting, before measuring (s)")
    parser.add_argument("--speed", type=float, default=1.0, help="simulation speed (x real time)")
    parser.add_argument("--probe", help=argparse.SUPPRESS)
    parser.add_argument("--clients", type=int, default=0, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.probe:
        probe_main(args.probe, args.clients, args.settle, args.seconds)
        return

    from hopper.app.dashboard.config import DashboardConfig
    from hopper.app.dashboard.server import Dashboard

    dashboard = Dashboard(DashboardConfig(port=free_port(), speed=args.speed), verbose=False).start()
    try:
        results = [measure(dashboard, n, args.settle, args.seconds) for n in (0, 1, 4)]
    finally:
        dashboard.stop()

    print(f"\nhopper-dashboard load, {args.seconds:g} s windows at {args.speed:g}x real time (target RTF >= 0.98)")
    print("RTF = simulated s per wall s, divided by the asked speed")
    print(f"{'clients':>7}  {'RTF':>6}  {'server frames/s':>15}  {'updates/s/client':>16}  {'kB/s/client':>11}  "
          f"{'initial scene kB':>16}")  # fmt: skip
    for r in results:
        per = r["per_client"]
        if per:
            updates = sum(c["pose_updates_per_s"] for c in per) / len(per)
            kbps = sum(c["bytes_per_s"] for c in per) / len(per) / 1e3
            initial = sum(c["initial_bytes"] for c in per) / len(per) / 1e3
            cells = f"{updates:16.1f}  {kbps:11.1f}  {initial:16.0f}"
        else:
            cells = f"{'-':>16}  {'-':>11}  {'-':>16}"
        print(f"{r['clients']:7d}  {r['rtf']:6.3f}  {r['server_frames_per_s']:15.1f}  {cells}")
    base = results[0]["rtf"]
    print("RTF ratio vs 0 clients: " + ", ".join(f"{r['clients']} clients {r['rtf'] / base:.3f}" for r in results[1:]))


if __name__ == "__main__":
    main()
